//! `sector_of` (uniforms.wgsl) on the GPU against the angles it stands for: every screen
//! offset of a search splat (at most 47 pixels either side) in the sector its angle counter-
//! clockwise from +x falls in, a direction on a boundary in the sector it starts.

use super::passes::UNIFORMS_WGSL;
use crate::gpu::{GpuContext, ProjectionPath};
use crate::pipelines::filters::bind;
use crate::pipelines::shader::ShaderSource;
use crate::pipelines::shader_tests::{SECTOR_DIRECTIONS, kernel_output, run_kernel};
use wgpu::util::DeviceExt;

const KERNEL_WGSL: &str = r#"
@group(0) @binding(0) var<storage, read> offsets: array<vec2<i32>>;
@group(0) @binding(1) var<storage, read_write> sectors: array<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= arrayLength(&offsets) {
        return;
    }
    let o = offsets[id.x];
    sectors[id.x] = sector_of(f32(o.x), f32(o.y));
}
"#;

/// The sector of offset (dx, dy) (y down): off a boundary from the angle, on one by the
/// boundary's own sector.
fn expected(dx: i32, dy: i32) -> u32 {
    let (x, y) = (dx, -dy);
    // The boundaries, 45 degrees apart from +x, counter-clockwise.
    for (k, (bx, by)) in SECTOR_DIRECTIONS.iter().enumerate() {
        // Along boundary k: parallel to it and facing the same way.
        if x * by == y * bx && x * bx + y * by > 0 {
            return k as u32;
        }
    }
    let turn = (y as f64).atan2(x as f64).rem_euclid(std::f64::consts::TAU);
    (turn / std::f64::consts::FRAC_PI_4) as u32
}

#[test]
fn sectors_follow_the_angle_with_each_boundary_in_the_sector_it_starts() {
    let ctx = GpuContext::new(ProjectionPath::Auto).expect("GPU adapter");
    let device = &ctx.device;
    let offsets: Vec<[i32; 2]> = (-47..=47)
        .flat_map(|dy| (-47..=47).map(move |dx| [dx, dy]))
        .filter(|&[dx, dy]| dx != 0 || dy != 0)
        .collect();
    let pipe =
        ShaderSource::new("sector test", &[UNIFORMS_WGSL, KERNEL_WGSL]).compute(device, None);
    let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: None,
        contents: bytemuck::cast_slice(&offsets),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let output = kernel_output(device, (offsets.len() * 4) as u64);
    let group = bind(
        device,
        &pipe,
        0,
        &[
            (0, input.as_entire_binding()),
            (1, output.as_entire_binding()),
        ],
    );
    let bytes = run_kernel(&ctx, &pipe, &[group], offsets.len(), &output);
    let got: &[u32] = bytemuck::cast_slice(&bytes);
    let mut per_sector = [0; 8];
    for (&[dx, dy], &s) in offsets.iter().zip(got) {
        assert_eq!(s, expected(dx, dy), "offset ({dx}, {dy}) (y down)");
        per_sector[s as usize] += 1;
    }
    // A turn of the grid by 90 degrees maps the sectors onto each other: as many in each.
    assert!(
        per_sector.iter().all(|&n| n == per_sector[0]),
        "{per_sector:?}"
    );
}
