//! The filters pipeline's per-screen buffers and what is read back from them: the layer
//! counters (layers used, fill iterations used), the first layer's surface and unlit colour.

use super::passes::{COUNTERS, FiltersUniforms, LIST_HEADER, LISTS, MAX_ITERATIONS, MAX_LAYERS};
use crate::ViewerError;
use crate::gpu::GpuContext;
use crate::gpu::async_readback::AsyncReadback;
use crate::gpu::readback::read_buffer;
use crate::pipelines::ScreenBuffer;
use crate::pipelines::projection::plane_buffer;
use crate::renderer::SurfacePixel;

/// Bytes between two steps in the steps buffer: the least uniform offset alignment WebGPU
/// guarantees.
pub const STEP_STRIDE: u64 = 256;
/// Steps one frame encodes at most: per layer the resolve, the shading and its arguments, and
/// per fill iteration of each kind the tile list and the fill.
const STEP_SLOTS: u64 = MAX_LAYERS as u64 * (3 + 4 * MAX_ITERATIONS as u64);

/// Flags of the fill's 16x16 tiles: per kind and iteration, one per tile where it changed
/// (`tile_slot` in uniforms.wgsl), then one per tile where the resolve put a point
/// (`occupied_slot`).
fn tile_flags(width: u32, height: u32) -> u64 {
    (2 * MAX_ITERATIONS as u64 + 1) * tile_count(width, height)
}

/// Bytes of the fill's tile lists: every list (`LISTS`), each its header and a slot per tile.
fn list_bytes(width: u32, height: u32) -> u64 {
    LISTS * (LIST_HEADER + tile_count(width, height)) * 4
}

fn tile_count(width: u32, height: u32) -> u64 {
    width.div_ceil(16) as u64 * height.div_ceil(16) as u64
}

/// Bytes per pixel of a texel (`Texel` in uniforms.wgsl).
const TEXEL_BYTES: u64 = 16;

pub struct FiltersTargets {
    pub width: u32,
    pub height: u32,
    pub uniforms: wgpu::Buffer,
    pub steps: wgpu::Buffer,
    /// A peeled layer's 64-bit keys (complements; 0 is empty), where the device has 64-bit
    /// atomics.
    pub peel_keys: Option<wgpu::Buffer>,
    /// A peeled layer's depth and index planes (complements; 0 is empty).
    pub peel_depths: wgpu::Buffer,
    pub peel_indices: wgpu::Buffer,
    /// Two texel buffers the resolve and the fill iterations ping-pong between.
    pub texels: [wgpu::Buffer; 2],
    /// Premultiplied colour and coverage of the layers blended so far.
    pub accum: wgpu::Buffer,
    pub surface: wgpu::Buffer,
    pub albedo: wgpu::Buffer,
    pub counters: wgpu::Buffer,
    pub counters_readback: AsyncReadback,
    /// Dispatch arguments of a peeled layer's shading.
    pub args: wgpu::Buffer,
    /// Per fill kind, iteration and 16x16 tile: whether the iteration changed the tile; then
    /// per tile whether the layer's resolve put a point in it.
    pub tiles: wgpu::Buffer,
    /// Per fill kind and iteration, the tiles it works on (`list_base` in uniforms.wgsl); each
    /// list's count is its iteration's dispatch arguments.
    pub tile_lists: wgpu::Buffer,
}

impl FiltersTargets {
    pub fn screen_buffers(width: u32, height: u32) -> Vec<ScreenBuffer> {
        let pixels = width as u64 * height as u64;
        vec![
            ScreenBuffer {
                label: "filters peel planes",
                bytes: pixels * 8,
            },
            ScreenBuffer {
                label: "filters peel keys",
                bytes: pixels * 8,
            },
            ScreenBuffer {
                label: "filters texels",
                bytes: pixels * TEXEL_BYTES * 2,
            },
            ScreenBuffer {
                label: "filters blend",
                bytes: pixels * 16,
            },
            ScreenBuffer {
                label: "filters surface",
                bytes: pixels * 16,
            },
            ScreenBuffer {
                label: "filters albedo",
                bytes: pixels * 4,
            },
            ScreenBuffer {
                label: "filters fill tiles",
                bytes: tile_flags(width, height) * 4,
            },
            ScreenBuffer {
                label: "filters fill tile lists",
                bytes: list_bytes(width, height),
            },
        ]
    }

    pub fn new(device: &wgpu::Device, width: u32, height: u32) -> FiltersTargets {
        let pixels = width as u64 * height as u64;
        let storage = |label: &str, bytes: u64| plane_buffer(device, label, bytes);
        FiltersTargets {
            width,
            height,
            uniforms: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("filters uniforms"),
                size: std::mem::size_of::<FiltersUniforms>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            steps: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("filters steps"),
                size: STEP_SLOTS * STEP_STRIDE,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            peel_keys: device
                .features()
                .contains(wgpu::Features::SHADER_INT64_ATOMIC_MIN_MAX)
                .then(|| storage("filters peel keys", pixels * 8)),
            peel_depths: storage("filters peel depths", pixels * 4),
            peel_indices: storage("filters peel indices", pixels * 4),
            texels: [
                storage("filters texels a", pixels * TEXEL_BYTES),
                storage("filters texels b", pixels * TEXEL_BYTES),
            ],
            accum: storage("filters blend", pixels * 16),
            surface: storage("filters surface", pixels * 16),
            albedo: storage("filters albedo", pixels * 4),
            counters: storage("filters counters", COUNTERS * 4),
            counters_readback: AsyncReadback::new(
                device,
                "filters counters readback",
                COUNTERS * 4,
            ),
            args: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("filters dispatch arguments"),
                size: 16,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDIRECT,
                mapped_at_creation: false,
            }),
            tiles: storage("filters fill tiles", tile_flags(width, height) * 4),
            tile_lists: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("filters fill tile lists"),
                size: list_bytes(width, height),
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::INDIRECT
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        }
    }

    /// Words of one fill tile list.
    pub fn list_words(&self) -> u64 {
        LIST_HEADER + tile_count(self.width, self.height)
    }

    pub fn step_slots(&self) -> usize {
        STEP_SLOTS as usize
    }

    fn pixels(&self) -> u64 {
        self.width as u64 * self.height as u64
    }

    pub fn read_counters(&self, ctx: &GpuContext) -> Result<Vec<u8>, ViewerError> {
        read_buffer(ctx, &self.counters, COUNTERS * 4)
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

/// What the counters say: layers that hold a pixel, and per kind of fill (background,
/// occluded) the most iterations that changed something in one layer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LayerCounts {
    pub layers_used: u32,
    pub background_iterations: u32,
    pub occluded_iterations: u32,
}

pub fn counts_from(bytes: &[u8]) -> Option<LayerCounts> {
    let words: Vec<u32> = bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    if (words.len() as u64) < COUNTERS {
        return None;
    }
    let (flags, changed) = words.split_at(MAX_LAYERS as usize);
    let layers_used = flags.iter().filter(|&&f| f != 0).count() as u32;
    // Runs of MAX_ITERATIONS flags, per layer: background, then occluded.
    let longest = |kind: usize| {
        changed
            .chunks_exact(MAX_ITERATIONS as usize)
            .skip(kind)
            .step_by(2)
            .map(|run| {
                run.iter()
                    .rposition(|&c| c != 0)
                    .map_or(0, |k| k as u32 + 1)
            })
            .max()
            .unwrap_or(0)
    };
    Some(LayerCounts {
        layers_used,
        background_iterations: longest(0),
        occluded_iterations: longest(1),
    })
}
