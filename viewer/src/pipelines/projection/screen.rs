//! The per-pixel planes and the output image of one viewport size, and the check of a size
//! against the adapter's limits before anything is created.

use crate::pipelines::ScreenBuffer;

/// The per-pixel buffers and the output image for one viewport size.
pub struct Screen {
    pub width: u32,
    pub height: u32,
    /// The 64-bit (depth, index) per pixel, on the int64 path.
    pub keys: Option<wgpu::Buffer>,
    /// Linear depth bits per pixel (`EMPTY` where no point landed), after resolve.
    pub depths: wgpu::Buffer,
    pub indices: wgpu::Buffer,
    /// RGBA8 colour per pixel, after resolve.
    pub colours: wgpu::Buffer,
    pub output: wgpu::Texture,
    /// `FrameUniforms`.
    pub uniforms: wgpu::Buffer,
    /// The previous frame's depth plane, for pipelines that declare `previous_frame`.
    pub previous_depths: Option<wgpu::Buffer>,
}

/// The output image's format.
pub const OUTPUT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

impl Screen {
    /// The planes a `width` x `height` screen takes, for the limits check.
    pub fn buffers(int64: bool, width: u32, height: u32) -> Vec<ScreenBuffer> {
        let pixels = width as u64 * height as u64;
        let mut b = vec![
            ScreenBuffer {
                label: "depth plane",
                bytes: pixels * 4,
            },
            ScreenBuffer {
                label: "index plane",
                bytes: pixels * 4,
            },
            ScreenBuffer {
                label: "colour plane",
                bytes: pixels * 4,
            },
        ];
        if int64 {
            b.push(ScreenBuffer {
                label: "64-bit key plane",
                bytes: pixels * 8,
            });
        }
        b
    }

    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        int64: bool,
        width: u32,
        height: u32,
        previous: bool,
    ) -> Screen {
        let pixels = width as u64 * height as u64;
        let buffer = |label: &str, bytes: u64| plane_buffer(device, label, bytes);
        Screen {
            width,
            height,
            keys: int64.then(|| buffer("keys", pixels * 8)),
            depths: buffer("depths", pixels * 4),
            indices: buffer("indices", pixels * 4),
            colours: buffer("colours", pixels * 4),
            output: image_texture(
                device,
                "output",
                (width, height),
                wgpu::TextureUsages::STORAGE_BINDING,
            ),
            uniforms: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("frame uniforms"),
                size: std::mem::size_of::<super::FrameUniforms>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            previous_depths: previous.then(|| {
                // Nothing drawn before the first frame: every pixel empty, not at depth 0.
                let b = buffer("previous depths", pixels * 4);
                queue.write_buffer(&b, 0, &vec![0xff; (pixels * 4) as usize]);
                b
            }),
        }
    }

    /// Keeps this frame's depth plane for the next frame (pipelines with `previous_frame`):
    /// `reconstructed`, where the pipeline made one of this screen's size, else the projection's.
    pub fn keep_depths(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        reconstructed: Option<&wgpu::Buffer>,
    ) {
        if let Some(prev) = &self.previous_depths {
            let source = reconstructed
                .filter(|b| b.size() == self.depths.size())
                .unwrap_or(&self.depths);
            encoder.copy_buffer_to_buffer(source, 0, prev, 0, self.depths.size());
        }
    }
}

/// An image of the output's format, `width` x `height`, that the window can show and a
/// readback or copy can take from, with `usage` besides.
pub fn image_texture(
    device: &wgpu::Device,
    label: &str,
    (width, height): (u32, u32),
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: OUTPUT_FORMAT,
        usage: usage | wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    })
}

/// A per-pixel buffer that passes read and write and that can be cleared and read back.
pub fn plane_buffer(device: &wgpu::Device, label: &str, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(16),
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// A screen size the adapter cannot hold.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScreenLimitError {
    pub width: u32,
    pub height: u32,
    pub what: String,
}

impl std::fmt::Display for ScreenLimitError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "an image of {}x{} {}",
            self.width, self.height, self.what
        )
    }
}

/// Checks that a `width` x `height` screen with `buffers` fits the adapter's `limits`.
pub fn check_screen(
    limits: &wgpu::Limits,
    width: u32,
    height: u32,
    buffers: &[ScreenBuffer],
) -> Result<(), ScreenLimitError> {
    let fail = |what: String| ScreenLimitError {
        width,
        height,
        what,
    };
    let side = limits.max_texture_dimension_2d;
    if width == 0 || height == 0 || width > side || height > side {
        return Err(fail(format!(
            "exceeds the adapter's largest image side of {side} pixels"
        )));
    }
    let cap = limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size);
    if let Some(b) = buffers
        .iter()
        .max_by_key(|b| b.bytes)
        .filter(|b| b.bytes > cap)
    {
        return Err(fail(format!(
            "needs a {} of {} MiB, more than the {} MiB the adapter binds",
            b.label,
            b.bytes.div_ceil(1 << 20),
            cap >> 20
        )));
    }
    Ok(())
}

/// The largest size with the aspect of `width` x `height` (at most that) that `fits`.
pub fn largest_fitting(width: u32, height: u32, fits: impl Fn(u32, u32) -> bool) -> (u32, u32) {
    if fits(width, height) {
        return (width, height);
    }
    // Bisect on the scale: fitting only shrinks as the size grows.
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..40 {
        let mid = (lo + hi) / 2.0;
        let (w, h) = scaled(width, height, mid);
        if fits(w, h) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    scaled(width, height, lo)
}

fn scaled(width: u32, height: u32, s: f64) -> (u32, u32) {
    (
        ((width as f64 * s).floor() as u32).max(1),
        ((height as f64 * s).floor() as u32).max(1),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits(binding: u64) -> wgpu::Limits {
        wgpu::Limits {
            max_storage_buffer_binding_size: binding,
            max_buffer_size: 1 << 40,
            max_texture_dimension_2d: 16384,
            ..wgpu::Limits::default()
        }
    }

    #[test]
    fn a_plane_over_the_binding_limit_is_named_with_both_sizes() {
        let l = limits(128 << 20);
        let b = Screen::buffers(true, 8192, 8192);
        let e = check_screen(&l, 8192, 8192, &b).expect_err("too large");
        let text = e.to_string();
        assert!(text.contains("8192x8192"), "{text}");
        assert!(text.contains("64-bit key plane of 512 MiB"), "{text}");
        assert!(text.contains("128 MiB"), "{text}");
        assert!(check_screen(&l, 4096, 4096, &Screen::buffers(true, 4096, 4096)).is_ok());
        let side = check_screen(&l, 16385, 16, &[]).expect_err("too wide");
        assert!(side.to_string().contains("16384"), "{side}");
    }

    #[test]
    fn the_previous_frame_keeps_the_depth_plane_only_where_asked() {
        use crate::gpu::readback::read_buffer;
        use crate::gpu::{GpuContext, ProjectionPath};
        let ctx = GpuContext::new(ProjectionPath::Auto).expect("GPU adapter");
        let plain = Screen::new(&ctx.device, &ctx.queue, false, 7, 5, false);
        assert!(plain.previous_depths.is_none());
        let screen = Screen::new(&ctx.device, &ctx.queue, false, 7, 5, true);
        let prev = screen.previous_depths.as_ref().expect("kept");
        let empty = read_buffer(&ctx, prev, 35 * 4).expect("readback");
        assert!(empty.iter().all(|b| *b == 0xff), "a fresh plane is empty");
        let depths: Vec<u32> = (0..35u32).map(|i| i * 3 + 1).collect();
        ctx.queue
            .write_buffer(&screen.depths, 0, bytemuck::cast_slice(&depths));
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        screen.keep_depths(&mut encoder, None);
        ctx.queue.submit([encoder.finish()]);
        let kept = read_buffer(&ctx, prev, 35 * 4).expect("readback");
        assert_eq!(bytemuck::cast_slice::<u8, u32>(&kept), depths.as_slice());
    }

    #[test]
    fn the_largest_fitting_size_keeps_the_aspect_and_fits() {
        let l = limits(128 << 20);
        let fits = |w, h| check_screen(&l, w, h, &Screen::buffers(true, w, h)).is_ok();
        let (w, h) = largest_fitting(8000, 4000, fits);
        assert!(fits(w, h));
        assert!(!fits(w + 2, h + 1), "{w}x{h} is not the largest");
        assert!((w as f64 / h as f64 - 2.0).abs() < 0.01, "{w}x{h}");
        assert_eq!(largest_fitting(640, 480, fits), (640, 480));
    }
}
