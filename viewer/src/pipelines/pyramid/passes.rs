//! The passes of paper 003 (Bouchiba, Deschaud, Goulette 2018), run on the depth and colour
//! planes the projection and resolve passes leave: a min-depth point pyramid, the pyramidal
//! hidden-point removal, pull-push filling of depth and colour, a normal per level of the
//! filled depth pyramid, and deferred headlight shading.

use crate::ViewerError;
use crate::gpu::GpuContext;
use crate::gpu::async_readback::AsyncReadback;
use crate::gpu::readback::read_buffer;
use crate::gpu::timing::Timer;
use crate::pipelines::LIGHTING_WGSL;
use crate::pipelines::ScreenBuffer;
use crate::pipelines::edl::EDL_WGSL;
use crate::pipelines::projection::pixel_groups;
use crate::pipelines::shader::ShaderSource;
use super::hpr::HprShape;
use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

/// The paper's HPR neighbourhood size, in multiples of s0 (its section 3.1.2).
pub const HPR_SCALE_S0: f32 = 10.0;
/// Mean sector occlusion below which a pixel is a hole (the paper's 0.1 for all datasets).
pub const HPR_THRESHOLD: f32 = 0.1;
/// The pyramid level whose min depth decides each pixel's HPR neighbourhood (the paper's 4th).
pub const COARSE_LEVEL: u32 = 4;
/// Radius of the surface the normals are estimated over, in multiples of s0, where the depth
/// noise does not call for more (pyramid_noise.wgsl). The paper leaves it open. Measured with
/// the quality harness (960x720), noise-aware: 4·s0 gives 22.2 dB / SSIM 0.82 on the real
/// bunny scans and 22.6 dB / 0.78 on the clean sampled bunny, 8·s0 21.8 / 0.82 and 21.1 / 0.75
/// (a larger radius rounds off edges; without the noise estimate it was the only defence
/// against noisy normals).
pub const NORMAL_SCALE_S0: f32 = 4.0;
/// Pyramid levels at most (`MAX_LEVELS` in pyramid.wgsl).
pub const MAX_LEVELS: usize = 16;

const COMMON_WGSL: &str = include_str!("pyramid.wgsl");
const NOISE_WGSL: &str = include_str!("pyramid_noise.wgsl");
const HPR_WGSL: &str = include_str!("pyramid_hpr.wgsl");

/// Everything the pyramid passes need to know of the frame beyond `FrameUniforms`.
#[derive(Debug, Clone, Copy)]
pub struct PyramidFrame {
    /// The metric scale of the point sampling, in dataset units.
    pub s0: f32,
    pub fov_y: f32,
    pub far: f32,
    pub focal_px: f32,
    /// `light` of pyramid.wgsl's uniforms: a world light's view-space direction, and w = 1 for
    /// Blinn-Phong with the lit share.
    pub light: [f32; 4],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct PyramidUniforms {
    pixel_scale: [f32; 2],
    pixel_bias: [f32; 2],
    far: f32,
    hpr_scale: f32,
    normal_scale: f32,
    threshold: f32,
    levels: u32,
    coarse_level: u32,
    s0: f32,
    /// Copied on the GPU from the noise estimate (`PyramidTargets::noise`) each frame.
    noise_scale: f32,
    light: [f32; 4],
    table: [[u32; 4]; MAX_LEVELS],
}

impl PyramidUniforms {
    fn new(t: &PyramidTargets, frame: &PyramidFrame) -> PyramidUniforms {
        let top = t.levels.len() as u32 - 1;
        let tan_y = (frame.fov_y * 0.5).tan();
        let tan_x = tan_y * t.width as f32 / t.height.max(1) as f32;
        let mut params = PyramidUniforms {
            pixel_scale: [2.0 * tan_x / t.width as f32, -2.0 * tan_y / t.height as f32],
            pixel_bias: [-tan_x, tan_y],
            far: frame.far,
            hpr_scale: HPR_SCALE_S0 * frame.s0 * frame.focal_px,
            normal_scale: NORMAL_SCALE_S0 * frame.s0 * frame.focal_px,
            threshold: HPR_THRESHOLD,
            levels: t.levels.len() as u32,
            coarse_level: COARSE_LEVEL.min(top),
            s0: frame.s0,
            noise_scale: 0.0,
            light: frame.light,
            table: [[0; 4]; MAX_LEVELS],
        };
        for (slot, l) in params.table.iter_mut().zip(&t.levels) {
            *slot = [l[0], l[1], l[2], 0];
        }
        params
    }
}

/// Bins of the depth-noise histogram (`NOISE_BINS` in pyramid_noise.wgsl); the noise scale
/// and the deviation follow them in the same buffer.
pub const NOISE_BINS: u64 = 80;
const NOISE_BYTES: u64 = (NOISE_BINS + 2) * 4;
/// Where the noise estimate leaves σ: after the bins and the noise scale.
const NOISE_SIGMA_AT: u64 = (NOISE_BINS + 1) * 4;

/// Per level of a `width` x `height` pyramid: offset into the pyramid buffers, width, height.
fn level_table(width: u32, height: u32) -> Vec<[u32; 3]> {
    let mut levels = Vec::new();
    let (mut w, mut h, mut offset) = (width.max(1), height.max(1), 0u32);
    loop {
        levels.push([offset, w, h]);
        offset += w * h;
        if (w == 1 && h == 1) || levels.len() == MAX_LEVELS {
            break;
        }
        w = w.div_ceil(2);
        h = h.div_ceil(2);
    }
    levels
}

/// The compiled passes, shared by every viewport size.
pub struct PyramidPasses {
    frame_layout: wgpu::BindGroupLayout,
    data_layout: wgpu::BindGroupLayout,
    /// The noise passes read few buffers; their own layout keeps every layout within eight
    /// storage buffers (the least adapters allow).
    noise_layout: wgpu::BindGroupLayout,
    noise_histogram: wgpu::ComputePipeline,
    noise_estimate: wgpu::ComputePipeline,
    base: wgpu::ComputePipeline,
    down: wgpu::ComputePipeline,
    hpr: wgpu::ComputePipeline,
    hpr_shape: HprShape,
    pull: wgpu::ComputePipeline,
    push: wgpu::ComputePipeline,
    normals: wgpu::ComputePipeline,
    shade: wgpu::ComputePipeline,
}

/// The pyramids for one viewport size.
pub struct PyramidTargets {
    pub width: u32,
    pub height: u32,
    /// Per level: offset into the pyramid buffers, width, height.
    levels: Vec<[u32; 3]>,
    pts: wgpu::Buffer,
    fill: wgpu::Buffer,
    /// Level 0 holds the filled colour each pixel is shaded with.
    pub fill_colour: wgpu::Buffer,
    normals: wgpu::Buffer,
    labels: wgpu::Buffer,
    /// The depth-noise histogram and the estimate drawn from it.
    noise: wgpu::Buffer,
    /// Per pixel (depth bits or EMPTY, octahedral normal), for readback.
    pub surface: wgpu::Buffer,
    params: wgpu::Buffer,
    level_uniforms: Vec<wgpu::Buffer>,
}

/// The pixel buffers of the screen that the pyramid reads and writes.
pub struct PyramidInputs<'a> {
    pub frame_uniforms: &'a wgpu::Buffer,
    pub depths: &'a wgpu::Buffer,
    pub colours: &'a wgpu::Buffer,
    pub output: &'a wgpu::Texture,
}

fn uniform_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

impl PyramidTargets {
    /// The depth noise of the last frame's visible points, as a deviation in dataset units
    /// (0 where too few neighbouring points were visible to tell). Waits for the GPU.
    pub fn read_depth_noise(&self, ctx: &GpuContext) -> Result<f32, ViewerError> {
        let bytes = read_buffer(ctx, &self.noise, NOISE_BYTES)?;
        bytes
            .get(NOISE_SIGMA_AT as usize..)
            .and_then(depth_noise_from)
            .ok_or_else(|| ViewerError::Gpu("the depth-noise readback came back short".into()))
    }

    /// Records a copy of this frame's depth noise into `readback`, if it is free, for the
    /// window, which must not wait for it; `depth_noise_from` reads what arrives.
    pub fn record_depth_noise(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        readback: &mut AsyncReadback,
    ) {
        readback.record(encoder, &self.noise, NOISE_SIGMA_AT, 4);
    }
}

/// The depth noise in the first four bytes of a readback of the noise estimate's σ.
pub fn depth_noise_from(bytes: &[u8]) -> Option<f32> {
    let word = <[u8; 4]>::try_from(bytes.get(..4)?).ok()?;
    Some(f32::from_le_bytes(word))
}

/// Every module the pyramid compiles, as it composes them.
pub fn shaders() -> Vec<ShaderSource> {
    let pass = |label, part| ShaderSource::new(label, &[COMMON_WGSL, part]);
    vec![
        ShaderSource::new("noise histogram", &[COMMON_WGSL, NOISE_WGSL]).with_entry("histogram"),
        ShaderSource::new("noise estimate", &[COMMON_WGSL, NOISE_WGSL]).with_entry("estimate"),
        pass("pyramid base", include_str!("pyramid_base.wgsl")),
        pass("pyramid down", include_str!("pyramid_down.wgsl")),
        ShaderSource::new(
            HprShape::Pixel.module(),
            &[COMMON_WGSL, HPR_WGSL, include_str!("pyramid_hpr_pixel.wgsl")],
        ),
        ShaderSource::new(
            HprShape::Block.module(),
            &[COMMON_WGSL, HPR_WGSL, include_str!("pyramid_hpr_block.wgsl")],
        ),
        pass("pull", include_str!("pyramid_pull.wgsl")),
        pass("push", include_str!("pyramid_push.wgsl")),
        pass("normals", include_str!("pyramid_normals.wgsl")),
        ShaderSource::new(
            "pyramid shade",
            &[
                COMMON_WGSL,
                LIGHTING_WGSL,
                EDL_WGSL,
                include_str!("pyramid_shade.wgsl"),
            ],
        ),
    ]
}

impl PyramidPasses {
    pub fn new(device: &wgpu::Device, hpr_shape: HprShape) -> Result<PyramidPasses, ViewerError> {
        let frame_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("pyramid frame"),
            entries: &[uniform_entry(0), uniform_entry(1), uniform_entry(2)],
        });
        let mut data_entries = vec![storage_entry(0, true), storage_entry(1, true)];
        data_entries.extend((2..8).map(|b| storage_entry(b, false)));
        data_entries.push(wgpu::BindGroupLayoutEntry {
            binding: 8,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::StorageTexture {
                access: wgpu::StorageTextureAccess::WriteOnly,
                format: wgpu::TextureFormat::Rgba8Unorm,
                view_dimension: wgpu::TextureViewDimension::D2,
            },
            count: None,
        });
        let data_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("pyramid data"),
            entries: &data_entries,
        });
        let noise_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("pyramid noise"),
            entries: &[
                storage_entry(0, true),
                storage_entry(6, false),
                storage_entry(9, false),
            ],
        });
        let pipeline_layout = |groups: &[Option<&wgpu::BindGroupLayout>]| {
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("pyramid"),
                bind_group_layouts: groups,
                immediate_size: 0,
            })
        };
        let layout = pipeline_layout(&[Some(&frame_layout), Some(&data_layout)]);
        let noise_pipeline_layout = pipeline_layout(&[Some(&frame_layout), Some(&noise_layout)]);
        let compile = |label: &str, layout: &wgpu::PipelineLayout| {
            shaders()
                .into_iter()
                .find(|s| s.label == label)
                .map(|s| s.compute(device, Some(layout)))
                .ok_or_else(|| ViewerError::Gpu(format!("no pyramid shader named {label}")))
        };
        let make = |label: &str| compile(label, &layout);
        Ok(PyramidPasses {
            noise_histogram: compile("noise histogram", &noise_pipeline_layout)?,
            noise_estimate: compile("noise estimate", &noise_pipeline_layout)?,
            noise_layout,
            base: make("pyramid base")?,
            down: make("pyramid down")?,
            hpr: make(hpr_shape.module())?,
            hpr_shape,
            pull: make("pull")?,
            push: make("push")?,
            normals: make("normals")?,
            shade: make("pyramid shade")?,
            frame_layout,
            data_layout,
        })
    }

    /// The buffers `targets` creates for a `width` x `height` screen.
    pub fn screen_buffers(width: u32, height: u32) -> Vec<ScreenBuffer> {
        let cells = level_table(width, height)
            .last()
            .map_or(0, |l| l[0] as u64 + l[1] as u64 * l[2] as u64);
        let pixels = width as u64 * height as u64;
        let b = |label, bytes| ScreenBuffer { label, bytes };
        vec![
            b("point pyramid", cells * 8),
            b("pull-push pyramid", cells * 8),
            b("pull-push colours", cells * 4),
            b("normal pyramid", cells * 4),
            b("HPR labels", pixels * 4),
            b("surface", pixels * 8),
        ]
    }

    pub fn targets(&self, device: &wgpu::Device, width: u32, height: u32) -> PyramidTargets {
        let levels = level_table(width, height);
        let offset = levels.last().map_or(0, |l| l[0] + l[1] * l[2]);
        let cells = offset as u64;
        let pixels = width as u64 * height as u64;
        let buffer = |label: &str, bytes: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes.max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let uniform = |label: &str, bytes: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        // Each level's index never changes: written once here, not every frame.
        let level_uniforms = (0..levels.len() as u32)
            .map(|i| {
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("pyramid level"),
                    contents: bytemuck::cast_slice(&[i, 0, 0, 0]),
                    usage: wgpu::BufferUsages::UNIFORM,
                })
            })
            .collect();
        PyramidTargets {
            width,
            height,
            pts: buffer("point pyramid", cells * 8),
            fill: buffer("pull-push pyramid", cells * 8),
            fill_colour: buffer("pull-push colours", cells * 4),
            normals: buffer("normal pyramid", cells * 4),
            labels: buffer("hpr labels", pixels * 4),
            noise: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("depth noise"),
                size: NOISE_BYTES,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            surface: buffer("surface", pixels * 8),
            params: uniform(
                "pyramid uniforms",
                std::mem::size_of::<PyramidUniforms>() as u64,
            ),
            level_uniforms,
            levels,
        }
    }

    /// Encodes the pyramid passes after projection and resolve; they write the output image.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        t: &PyramidTargets,
        inputs: &PyramidInputs,
        frame: &PyramidFrame,
        timer: &mut Timer,
    ) {
        let params = PyramidUniforms::new(t, frame);
        queue.write_buffer(&t.params, 0, bytemuck::bytes_of(&params));
        let frame_groups: Vec<wgpu::BindGroup> = t
            .level_uniforms
            .iter()
            .map(|u| {
                device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("pyramid frame"),
                    layout: &self.frame_layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: inputs.frame_uniforms.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: t.params.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: u.as_entire_binding(),
                        },
                    ],
                })
            })
            .collect();
        let view = inputs.output.create_view(&Default::default());
        let buffers = [
            inputs.depths,
            inputs.colours,
            &t.pts,
            &t.fill,
            &t.fill_colour,
            &t.normals,
            &t.labels,
            &t.surface,
        ];
        let mut entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        entries.push(wgpu::BindGroupEntry {
            binding: 8,
            resource: wgpu::BindingResource::TextureView(&view),
        });
        let data = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("pyramid data"),
            layout: &self.data_layout,
            entries: &entries,
        });
        let noise_data = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("pyramid noise"),
            layout: &self.noise_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: inputs.depths.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 6,
                    resource: t.labels.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 9,
                    resource: t.noise.as_entire_binding(),
                },
            ],
        });
        let level_groups = |l: usize| {
            let [_, w, h] = t.levels[l];
            pixel_groups(w, h)
        };
        // Each dispatch: the level it works on, and its workgroups.
        let run = |encoder: &mut wgpu::CommandEncoder,
                   timer: &mut Timer,
                   name: &str,
                   pipe: &wgpu::ComputePipeline,
                   group: &wgpu::BindGroup,
                   steps: &mut dyn Iterator<Item = (usize, (u32, u32))>| {
            let timestamp_writes = timer.pass(encoder, name);
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(name),
                timestamp_writes,
            });
            pass.set_pipeline(pipe);
            pass.set_bind_group(1, group, &[]);
            for (l, (x, y)) in steps {
                pass.set_bind_group(0, &frame_groups[l], &[]);
                pass.dispatch_workgroups(x, y, 1);
            }
        };
        let levels = t.levels.len();
        // Level 0 is the full screen.
        let at = |l: usize| (l, level_groups(l));
        let (e, tm) = (encoder, timer);
        run(
            e,
            tm,
            "pyramid",
            &self.base,
            &data,
            &mut [at(0)].into_iter(),
        );
        run(
            e,
            tm,
            "pyramid",
            &self.down,
            &data,
            &mut (1..levels).map(at),
        );
        // A workgroup is 8x8 invocations, each labelling a pixel or a block.
        let [_, w0, h0] = t.levels[0];
        let group_side = 8 * self.hpr_shape.side();
        let hpr_groups = (0, (w0.div_ceil(group_side), h0.div_ceil(group_side)));
        run(
            e,
            tm,
            "hpr",
            &self.hpr,
            &data,
            &mut [hpr_groups].into_iter(),
        );
        // The noise estimate reaches the shading's uniforms by a copy on the GPU: the frame
        // never waits for it.
        e.clear_buffer(&t.noise, 0, None);
        let histogram = &self.noise_histogram;
        run(
            e,
            tm,
            "noise",
            histogram,
            &noise_data,
            &mut [at(0)].into_iter(),
        );
        let estimate = &self.noise_estimate;
        run(
            e,
            tm,
            "noise",
            estimate,
            &noise_data,
            &mut [(0, (1, 1))].into_iter(),
        );
        let noise_field = std::mem::offset_of!(PyramidUniforms, noise_scale) as u64;
        e.copy_buffer_to_buffer(&t.noise, NOISE_BINS * 4, &t.params, noise_field, 4);
        run(e, tm, "pull", &self.pull, &data, &mut (1..levels).map(at));
        run(
            e,
            tm,
            "push",
            &self.push,
            &data,
            &mut (0..levels).rev().map(at),
        );
        run(
            e,
            tm,
            "normals",
            &self.normals,
            &data,
            &mut (0..levels).map(at),
        );
        run(
            e,
            tm,
            "pyramid shade",
            &self.shade,
            &data,
            &mut [at(0)].into_iter(),
        );
    }
}

#[cfg(test)]
#[path = "hpr_tests.rs"]
mod hpr_tests;

/// `PyramidUniforms`' size and field offsets, for the check against pyramid.wgsl.
#[cfg(test)]
pub(crate) fn uniforms_layout() -> (u32, Vec<(String, u32)>) {
    macro_rules! fields {
        ($($f:ident),*) => {
            vec![$((stringify!($f).to_string(), std::mem::offset_of!(PyramidUniforms, $f) as u32)),*]
        };
    }
    (
        std::mem::size_of::<PyramidUniforms>() as u32,
        fields!(
            pixel_scale,
            pixel_bias,
            far,
            hpr_scale,
            normal_scale,
            threshold,
            levels,
            coarse_level,
            s0,
            noise_scale,
            light,
            table
        ),
    )
}
