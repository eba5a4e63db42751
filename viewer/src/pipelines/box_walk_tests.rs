//! The box walk (box_walk.wgsl) on the GPU: each thread walks one box, adding one to every
//! pixel it visits, so that every pixel of every box is visited once and no other.

use super::BOX_WALK_WGSL;
use super::dispatch_tests_support::run_passes;
use super::filters::bind;
use super::shader::ShaderSource;
use crate::gpu::readback::read_buffer;
use crate::gpu::{GpuContext, ProjectionPath};
use wgpu::util::DeviceExt;

const WIDTH: u32 = 13;
const HEIGHT: u32 = 11;

const WALK_MAIN: &str = "
override WIDTH: u32;
@group(0) @binding(0) var<storage, read> boxes: array<vec4<u32>>;
@group(0) @binding(1) var<storage, read_write> visits: array<atomic<u32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= arrayLength(&boxes) {
        return;
    }
    let b = boxes[id.x];
    let pixels = box_pixels(b);
    var next = b.xy;
    for (var k = 0u; k < pixels; k++) {
        atomicAdd(&visits[next.y * WIDTH + next.x], 1u);
        next = box_next(b, next);
    }
}
";

#[test]
fn a_walk_visits_every_pixel_of_its_box_once() {
    let ctx = GpuContext::new(ProjectionPath::Auto).expect("GPU adapter");
    let device = &ctx.device;
    // Boxes of one pixel, one row, one column, the whole plane, and empty ones (x1 < x0 and
    // y1 < y0, as a box off the screen's edge is clamped).
    let boxes: Vec<[u32; 4]> = vec![
        [3, 4, 3, 4],
        [0, 0, 12, 0],
        [12, 2, 12, 10],
        [0, 0, 12, 10],
        [2, 5, 7, 9],
        [5, 1, 4, 3],
        [1, 6, 3, 5],
        [9, 9, 0, 0],
    ];
    let mut want = vec![0u32; (WIDTH * HEIGHT) as usize];
    for b in &boxes {
        for y in b[1]..=b[3] {
            for x in b[0]..=b[2] {
                want[(y * WIDTH + x) as usize] += 1;
            }
        }
    }
    let boxes_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: None,
        contents: bytemuck::cast_slice(&boxes),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let visits = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: None,
        contents: &vec![0u8; want.len() * 4],
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
    });
    let pipe = ShaderSource::new("box walk test", &[BOX_WALK_WGSL, WALK_MAIN])
        .with_constant("WIDTH", WIDTH as f64)
        .compute(device, None);
    let group = bind(
        device,
        &pipe,
        0,
        &[
            (0, boxes_buffer.as_entire_binding()),
            (1, visits.as_entire_binding()),
        ],
    );
    run_passes(&ctx, &[(&pipe, &group, (1, 1))]);
    let bytes = read_buffer(&ctx, &visits, want.len() as u64 * 4).expect("visits readback");
    let got: &[u32] = bytemuck::cast_slice(&bytes);
    assert_eq!(got, want.as_slice());
}
