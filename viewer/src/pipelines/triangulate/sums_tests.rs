//! The blend sums on the GPU, both layouts (raster_sums*.wgsl adding, shade_sums*.wgsl
//! reading): a pixel reads back the mean colour and normal of its fragments, and one with more
//! fragments than the 64-bit sums keep reads back the mean of those it kept, no field having
//! overflowed into the next; the back faces' sums the same, apart from the front faces'.

use super::passes::{
    RASTER_SUMS32_WGSL, RASTER_SUMS64_WGSL, SHADE_SUMS32_WGSL, SHADE_SUMS64_WGSL, UNIFORMS_WGSL,
};
use super::targets::{SUM_WORDS, SUM64_BYTES};
use crate::gpu::readback::read_buffer;
use crate::gpu::{GpuContext, ProjectionPath};
use crate::pipelines::dispatch_tests_support::run_passes;
use crate::pipelines::filters::bind;
use crate::pipelines::shader::ShaderSource;
use wgpu::util::DeviceExt;

const ADD_MAIN: &str = "
@group(0) @binding(0) var<storage, read> colours: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read> normals: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x < arrayLength(&colours) {
        add_sums(u32(colours[id.x].w), colours[id.x].xyz, normals[id.x].xyz, normals[id.x].w != 0.0);
    }
}
";

const READ_MAIN: &str = "
@group(0) @binding(0) var<storage, read_write> blends: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x < arrayLength(&blends) / 4u {
        for (var side = 0u; side < 2u; side++) {
            let b = blend_at(id.x, side == 1u);
            blends[4u * id.x + 2u * side] = vec4<f32>(f32(b.fragments), b.colour);
            blends[4u * id.x + 2u * side + 1u] = vec4<f32>(b.normal, 0.0);
        }
    }
}
";

struct Layout {
    add: &'static str,
    read: &'static str,
    bytes_per_pixel: u64,
}

const SUMS32: Layout = Layout {
    add: RASTER_SUMS32_WGSL,
    read: SHADE_SUMS32_WGSL,
    bytes_per_pixel: 4 * SUM_WORDS,
};

const SUMS64: Layout = Layout {
    add: RASTER_SUMS64_WGSL,
    read: SHADE_SUMS64_WGSL,
    bytes_per_pixel: SUM64_BYTES,
};

/// A pixel's blend read back: fragments, colour, normal (mapped to [0, 1]).
type Blend = (u32, [f32; 3], [f32; 3]);

/// Adds `fragments` (pixel, colour, normal mapped to [0, 1]) in one dispatch, to the back
/// faces' sums where `back`, then reads back the blend of `pixels` pixels on that side; the
/// other side's must hold none.
fn blends(
    ctx: &GpuContext,
    layout: &Layout,
    fragments: &[(u32, [f32; 3], [f32; 3])],
    pixels: u64,
    back: bool,
) -> Vec<Blend> {
    let device = &ctx.device;
    let storage = |contents: &[u8], usage: wgpu::BufferUsages| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: None,
            contents,
            usage: wgpu::BufferUsages::STORAGE | usage,
        })
    };
    let colours: Vec<[f32; 4]> = fragments
        .iter()
        .map(|(p, c, _)| [c[0], c[1], c[2], *p as f32])
        .collect();
    let normals: Vec<[f32; 4]> = fragments
        .iter()
        .map(|(_, _, n)| [n[0], n[1], n[2], f32::from(u8::from(back))])
        .collect();
    let colours = storage(bytemuck::cast_slice(&colours), wgpu::BufferUsages::empty());
    let normals = storage(bytemuck::cast_slice(&normals), wgpu::BufferUsages::empty());
    let [sums, back_sums] = [(); 2].map(|_| {
        storage(
            &vec![0u8; (pixels * layout.bytes_per_pixel) as usize],
            wgpu::BufferUsages::empty(),
        )
    });
    let out = storage(
        &vec![0u8; (pixels * 64) as usize],
        wgpu::BufferUsages::COPY_SRC,
    );
    let add = ShaderSource::new("sums test add", &[UNIFORMS_WGSL, layout.add, ADD_MAIN])
        .with_constant("SIDES", 1.0)
        .compute(device, None);
    let read = ShaderSource::new("sums test read", &[UNIFORMS_WGSL, layout.read, READ_MAIN])
        .with_constant("SIDES", 1.0)
        .compute(device, None);
    let add_group = bind(
        device,
        &add,
        0,
        &[
            (0, colours.as_entire_binding()),
            (1, normals.as_entire_binding()),
            (5, sums.as_entire_binding()),
            (9, back_sums.as_entire_binding()),
        ],
    );
    let read_group = bind(
        device,
        &read,
        0,
        &[
            (0, out.as_entire_binding()),
            (2, sums.as_entire_binding()),
            (7, back_sums.as_entire_binding()),
        ],
    );
    run_passes(
        ctx,
        &[
            (&add, &add_group, ((fragments.len() as u32).div_ceil(64), 1)),
            (&read, &read_group, ((pixels as u32).div_ceil(64), 1)),
        ],
    );
    let bytes = read_buffer(ctx, &out, pixels * 64).expect("blends readback");
    let v: &[[[f32; 8]; 2]] = bytemuck::cast_slice(&bytes);
    let (side, other) = (usize::from(back), usize::from(!back));
    assert!(
        v.iter().all(|b| b[other][0] == 0.0),
        "fragments on the other side's sums"
    );
    v.iter()
        .map(|b| {
            let b = b[side];
            (b[0] as u32, [b[1], b[2], b[3]], [b[4], b[5], b[6]])
        })
        .collect()
}

fn close(a: [f32; 3], b: [f32; 3], within: f32) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() <= within)
}

/// Pixel 0: `crowd` white fragments with normals (1, 1, 1), the most every field can take;
/// pixel 1: three fragments of different colours and normals; pixel 2: none. Interleaved, so
/// that pixel 1's fragments arrive while pixel 0's are added.
fn check(ctx: &GpuContext, layout: &Layout, crowd: usize, kept: u32) {
    let few = [
        ([0.2, 0.4, 0.6], [0.0, 0.5, 1.0]),
        ([0.4, 0.0, 1.0], [0.25, 0.5, 0.0]),
        ([0.0, 0.8, 0.2], [1.0, 0.25, 0.5]),
    ];
    let mut fragments = Vec::new();
    for i in 0..crowd {
        fragments.push((0, [1.0; 3], [1.0; 3]));
        if i % 500 == 0 && i / 500 < few.len() {
            let (c, n) = few[i / 500];
            fragments.push((1, c, n));
        }
    }
    for back in [false, true] {
        let got = blends(ctx, layout, &fragments, 3, back);
        check_blends(&got, kept, &few);
    }
}

/// The blends `check` expects: `few` the three fragments of pixel 1.
fn check_blends(got: &[Blend], kept: u32, few: &[([f32; 3], [f32; 3]); 3]) {
    assert_eq!(got[0].0, kept, "fragments kept on the crowded pixel");
    assert!(
        close(got[0].1, [1.0; 3], 1e-6) && close(got[0].2, [1.0; 3], 1e-6),
        "the crowded pixel: {:?}",
        got[0]
    );
    let colour = [0, 1, 2].map(|c| few.iter().map(|f| f.0[c]).sum::<f32>() / 3.0);
    let normal = [0, 1, 2].map(|c| few.iter().map(|f| f.1[c]).sum::<f32>() / 3.0);
    assert_eq!(got[1].0, 3);
    // Each fragment's colour is rounded to 1/255 (the 64-bit sums) or better.
    assert!(
        close(got[1].1, colour, 0.5 / 255.0 + 1e-6) && close(got[1].2, normal, 0.5 / 1023.0 + 1e-6),
        "the mean of three: {:?}, expected {colour:?} and {normal:?}",
        got[1]
    );
    assert_eq!(got[2].0, 0, "a pixel without fragments");
}

#[test]
fn the_32_bit_sums_blend_every_fragment() {
    let ctx = GpuContext::new(ProjectionPath::Int32).expect("GPU adapter");
    check(&ctx, &SUMS32, 2000, 2000);
}

#[test]
fn the_64_bit_sums_keep_512_fragments_a_pixel_and_overflow_nothing() {
    let ctx = GpuContext::new(ProjectionPath::Auto).expect("GPU adapter");
    if !ctx.int64_sums {
        eprintln!("skipped: the adapter has no 64-bit atomic adds");
        return;
    }
    check(&ctx, &SUMS64, 2000, 512);
}
