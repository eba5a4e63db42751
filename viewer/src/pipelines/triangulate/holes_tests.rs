//! The hole count (holes.wgsl) on the GPU against its definition, on reconstructed planes whose
//! sizes are not multiples of the 16 x 16 tiles: an empty pixel is a hole where covered pixels
//! lie within 16 on its left, its right, above and below it.

use super::passes::shaders;
use super::targets::{COUNT_WORDS, Counts, counts_from};
use crate::gpu::{GpuContext, ProjectionPath};
use crate::pipelines::dispatch_tests_support::run_passes;
use crate::pipelines::filters::bind;
use crate::pipelines::projection::{EMPTY, FrameUniforms, pixel_groups};
use bytemuck::Zeroable;
use wgpu::util::DeviceExt;

const REACH: i64 = 16;

fn expected(covered: &[bool], width: usize, height: usize) -> Counts {
    let at = |x: i64, y: i64| {
        x >= 0
            && y >= 0
            && (x as usize) < width
            && (y as usize) < height
            && covered[y as usize * width + x as usize]
    };
    let reaches = |x: i64, y: i64, dx: i64, dy: i64| (1..=REACH).any(|k| at(x + k * dx, y + k * dy));
    let mut counts = Counts {
        culled: 0,
        triangles: 0,
        holes: 0,
        covered: 0,
    };
    for y in 0..height as i64 {
        for x in 0..width as i64 {
            if at(x, y) {
                counts.covered += 1;
            } else if reaches(x, y, -1, 0)
                && reaches(x, y, 1, 0)
                && reaches(x, y, 0, -1)
                && reaches(x, y, 0, 1)
            {
                counts.holes += 1;
            }
        }
    }
    counts
}

fn gpu_counts(ctx: &GpuContext, covered: &[bool], width: u32, height: u32) -> Counts {
    let device = &ctx.device;
    let source = shaders(false)
        .into_iter()
        .find(|s| s.label == "triangulate holes")
        .expect("the holes module");
    let pipe = source.compute(device, None);
    let mut frame = FrameUniforms::zeroed();
    frame.width = width;
    frame.height = height;
    let uniforms = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: None,
        contents: bytemuck::bytes_of(&frame),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let plane: Vec<u32> = covered
        .iter()
        .map(|&c| if c { 1.5f32.to_bits() } else { EMPTY })
        .collect();
    let reconstructed = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: None,
        contents: bytemuck::cast_slice(&plane),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let counts = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: None,
        contents: &[0u8; COUNT_WORDS as usize * 4],
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
    });
    let group = bind(
        device,
        &pipe,
        0,
        &[
            (0, uniforms.as_entire_binding()),
            (1, reconstructed.as_entire_binding()),
            (2, counts.as_entire_binding()),
        ],
    );
    // The dispatch the frame gives it (passes.rs): one workgroup a 16 x 16 tile.
    run_passes(ctx, &[(&pipe, &group, pixel_groups(width, height))]);
    let bytes =
        crate::gpu::readback::read_buffer(ctx, &counts, COUNT_WORDS * 4).expect("counts readback");
    counts_from(&bytes).expect("four words")
}

#[test]
fn holes_and_covered_pixels_are_counted_as_defined() {
    let ctx = GpuContext::new(ProjectionPath::Auto).expect("GPU adapter");
    // A disc of scattered points with a gap wider than the reach across it, a lone pixel and
    // pixels at every edge of the screen, on sizes off the tile grid.
    for (width, height) in [(70usize, 45usize), (33, 17), (16, 16), (97, 64)] {
        let mut state = 0x2545_f491_u32;
        let mut random = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        };
        let mut covered = vec![false; width * height];
        let (cx, cy, r) = (width as f64 / 2.0, height as f64 / 2.0, width.min(height) as f64 / 2.5);
        for y in 0..height {
            for x in 0..width {
                let (dx, dy) = (x as f64 + 0.5 - cx, y as f64 + 0.5 - cy);
                let inside = dx * dx + dy * dy < r * r && !(x as f64 > cx - 10.0 && (x as f64) < cx + 10.0 && (dy.abs() as usize) < 3);
                covered[y * width + x] = inside && random() % 5 != 0;
            }
        }
        covered[0] = true;
        covered[width - 1] = true;
        covered[(height - 1) * width] = true;
        covered[width * height - 1] = true;
        covered[(height / 3) * width + width / 7] = true;
        let want = expected(&covered, width, height);
        assert!(want.holes > 0 && want.covered > 40, "{want:?} for {width}x{height}");
        let got = gpu_counts(&ctx, &covered, width as u32, height as u32);
        assert_eq!(
            (got.holes, got.covered),
            (want.holes, want.covered),
            "{width}x{height}"
        );
        // Sparse pixels: many empty ones have their nearest covered pixel exactly at the reach
        // or one beyond it, in every direction and at every row of a tile.
        let sparse: Vec<bool> = (0..width * height).map(|_| random() % 23 == 0).collect();
        let want = expected(&sparse, width, height);
        let got = gpu_counts(&ctx, &sparse, width as u32, height as u32);
        assert_eq!(
            (got.holes, got.covered),
            (want.holes, want.covered),
            "sparse, {width}x{height}"
        );
    }
}
