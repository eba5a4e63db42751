//! The triangulation's per-screen buffers and what is read back from them: its counters, the
//! reconstructed surface and its unlit colour.

use crate::ViewerError;
use crate::gpu::GpuContext;
use crate::gpu::async_readback::AsyncReadback;
use crate::gpu::readback::read_buffer;
use crate::pipelines::ScreenBuffer;
use crate::pipelines::projection::plane_buffer;
use crate::renderer::SurfacePixel;

/// Sectors per point (`SECTORS` in uniforms.wgsl).
pub const SECTORS: u64 = 8;
/// Words per pixel of the 32-bit blend sums (`SUM_WORDS` in uniforms.wgsl).
pub const SUM_WORDS: u64 = 7;
/// Bytes per pixel of the 64-bit blend sums (two words).
pub const SUM64_BYTES: u64 = 16;
/// Counter words (`COUNT_WORDS` in counts.wgsl): culled points, triangles, holes, covered.
pub const COUNT_WORDS: u64 = 4;

/// The per-pixel buffers of one screen size, by label and bytes per pixel.
const PLANES: [(&str, u64); 12] = [
    ("reprojected depth", 4),
    ("triangulation points", 16),
    ("triangulation point normals", 4),
    ("sector distances", 4 * SECTORS),
    ("sector neighbours", 4 * SECTORS),
    ("triangulation normals", 16),
    ("radius feedback", 4),
    ("triangulation sums", 4 * SUM_WORDS),
    ("triangulation front depth", 4),
    ("reconstructed depth", 4),
    ("triangulation surface", 16),
    ("triangulation back sums", 4 * SUM_WORDS),
];

pub struct TriangulateTargets {
    pub width: u32,
    pub height: u32,
    pub uniforms: wgpu::Buffer,
    /// The previous frame's reconstructed depth in this frame (complements; 0 is empty).
    pub reprojected: wgpu::Buffer,
    /// Per pixel: the kept point's position and search radius (w 0: none).
    pub points: wgpu::Buffer,
    /// Per pixel: the kept point's own normal (four snorm8; 0: none), where the normals tell the
    /// sides apart or shade (`stored_normals`).
    pub point_normals: wgpu::Buffer,
    /// Per pixel and sector: the complement of the least distance's bits.
    pub distances: wgpu::Buffer,
    /// Per pixel and sector: the complement of (distance, pixel id) of the nearest, where the
    /// device has 64-bit atomics (the search is then one pass).
    pub keys: Option<wgpu::Buffer>,
    /// Per pixel and sector: the complement of the nearest neighbour's pixel id (the two-pass
    /// search's; 16 bytes where the fans read the 64-bit keys in place).
    pub neighbours: wgpu::Buffer,
    pub normals: wgpu::Buffer,
    /// Per pixel: the largest distance at which a neighbour took the point (f32 bits).
    pub feedback: wgpu::Buffer,
    pub sums: wgpu::Buffer,
    /// The back faces' blend sums, laid out as `sums`, where the normals tell the sides apart.
    pub back_sums: wgpu::Buffer,
    pub front: wgpu::Buffer,
    /// Linear depth bits per pixel (`EMPTY` on background): what the next frame reprojects.
    pub reconstructed: wgpu::Buffer,
    pub surface: wgpu::Buffer,
    pub albedo: wgpu::Buffer,
    pub counts: wgpu::Buffer,
    pub counts_readback: AsyncReadback,
}

/// What one frame counted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Counts {
    pub culled: u32,
    pub triangles: u32,
    pub holes: u32,
    pub covered: u32,
}

impl Counts {
    /// Empty pixels inside the silhouette over those and the covered ones.
    pub fn hole_rate(&self) -> f32 {
        let inside = self.holes as f64 + self.covered as f64;
        if inside == 0.0 {
            0.0
        } else {
            (self.holes as f64 / inside) as f32
        }
    }
}

/// The counters from a readback of at least `COUNT_WORDS` words.
pub fn counts_from(bytes: &[u8]) -> Option<Counts> {
    let word = |k: usize| -> Option<u32> {
        Some(u32::from_le_bytes(
            bytes.get(4 * k..4 * k + 4)?.try_into().ok()?,
        ))
    };
    Some(Counts {
        culled: word(0)?,
        triangles: word(1)?,
        holes: word(2)?,
        covered: word(3)?,
    })
}

impl TriangulateTargets {
    pub fn screen_buffers(width: u32, height: u32) -> Vec<ScreenBuffer> {
        let pixels = width as u64 * height as u64;
        let mut b: Vec<ScreenBuffer> = PLANES
            .iter()
            .map(|&(label, bytes)| ScreenBuffer {
                label,
                bytes: pixels * bytes,
            })
            .collect();
        b.push(ScreenBuffer {
            label: "triangulation albedo",
            bytes: pixels * 4,
        });
        b.push(ScreenBuffer {
            label: "64-bit sector keys",
            bytes: pixels * 8 * SECTORS,
        });
        b
    }

    /// `int64`: the one-pass sector search's keys; `sums64`: the 64-bit blend sums.
    pub fn new(
        device: &wgpu::Device,
        width: u32,
        height: u32,
        int64: bool,
        sums64: bool,
    ) -> TriangulateTargets {
        let pixels = width as u64 * height as u64;
        let plane = |k: usize| plane_buffer(device, PLANES[k].0, pixels * PLANES[k].1);
        // The 64-bit sums take two words a pixel where the 32-bit ones take seven.
        let blend_sums = |k: usize| {
            if sums64 {
                plane_buffer(device, PLANES[k].0, pixels * SUM64_BYTES)
            } else {
                plane(k)
            }
        };
        TriangulateTargets {
            width,
            height,
            uniforms: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("triangulation uniforms"),
                size: std::mem::size_of::<super::passes::TriangulateUniforms>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            reprojected: plane(0),
            points: plane(1),
            point_normals: plane(2),
            // The 64-bit search needs no distance plane.
            distances: if int64 {
                plane_buffer(device, PLANES[3].0, 16)
            } else {
                plane(3)
            },
            keys: int64.then(|| plane_buffer(device, "64-bit sector keys", pixels * 8 * SECTORS)),
            // The 64-bit search's keys are read in place of the ids.
            neighbours: if int64 {
                plane_buffer(device, PLANES[4].0, 16)
            } else {
                plane(4)
            },
            normals: plane(5),
            feedback: plane(6),
            sums: blend_sums(7),
            back_sums: blend_sums(11),
            front: plane(8),
            reconstructed: plane(9),
            surface: plane(10),
            albedo: plane_buffer(device, "triangulation albedo", pixels * 4),
            counts: plane_buffer(device, "triangulation counts", COUNT_WORDS * 4),
            counts_readback: AsyncReadback::new(
                device,
                "triangulation counts readback",
                COUNT_WORDS * 4,
            ),
        }
    }

    fn pixels(&self) -> u64 {
        self.width as u64 * self.height as u64
    }

    pub fn read_counts(&self, ctx: &GpuContext) -> Result<Counts, ViewerError> {
        let bytes = read_buffer(ctx, &self.counts, COUNT_WORDS * 4)?;
        counts_from(&bytes)
            .ok_or_else(|| ViewerError::Gpu("the triangulation counts came back short".into()))
    }

    pub fn read_albedo(&self, ctx: &GpuContext) -> Result<Vec<Option<[u8; 3]>>, ViewerError> {
        let bytes = read_buffer(ctx, &self.albedo, self.pixels() * 4)?;
        Ok(crate::pipelines::surface::albedo_from(&bytes))
    }

    pub fn read_surface(&self, ctx: &GpuContext) -> Result<Vec<Option<SurfacePixel>>, ViewerError> {
        let bytes = read_buffer(ctx, &self.surface, self.pixels() * 16)?;
        Ok(crate::pipelines::surface::surface_from(&bytes))
    }
}
