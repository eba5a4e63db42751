// The fused last pass when a frame's points lie in at most four arenas: per pixel, fetch the
// nearest point's attributes from its arena, colour it, shade it with the pipeline's
// `shade_pixel` and write the output image. Replaces unpack, resolve and shade (three
// full-screen passes) with one. `pixel_depth` and `pixel_index` come from the projection
// path's prelude.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(3) var output: texture_storage_2d<rgba8unorm, write>;
@group(1) @binding(0) var<storage, read> points0: array<vec4<u32>>;
@group(1) @binding(1) var<storage, read> attributes0: array<u32>;
@group(1) @binding(2) var<storage, read> points1: array<vec4<u32>>;
@group(1) @binding(3) var<storage, read> attributes1: array<u32>;
@group(1) @binding(4) var<storage, read> points2: array<vec4<u32>>;
@group(1) @binding(5) var<storage, read> attributes2: array<u32>;
@group(1) @binding(6) var<storage, read> points3: array<vec4<u32>>;
@group(1) @binding(7) var<storage, read> attributes3: array<u32>;

fn point_at(slot: u32, i: u32) -> vec4<u32> {
    switch slot {
        case 0u: { return points0[i]; }
        case 1u: { return points1[i]; }
        case 2u: { return points2[i]; }
        default: { return points3[i]; }
    }
}

fn attribute_at(slot: u32, i: u32) -> u32 {
    switch slot {
        case 0u: { return attributes0[i]; }
        case 1u: { return attributes1[i]; }
        case 2u: { return attributes2[i]; }
        default: { return attributes3[i]; }
    }
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let i = id.y * frame.width + id.x;
    let d = pixel_depth(i);
    if d == EMPTY {
        textureStore(output, vec2<i32>(id.xy), unpack4x8unorm(frame.background));
        return;
    }
    let g = pixel_index(i);
    let arena = g >> frame.arena_shift;
    var slot = 0u;
    for (var k = 0u; k < 4u; k++) {
        if frame.arena_slots[k] == arena {
            slot = k;
        }
    }
    let local = g & ((1u << frame.arena_shift) - 1u);
    // Quantized to 8 bits before shading, as the separate resolve stores it, so both paths
    // give the same image.
    let colour = vec4<f32>(point_colour(point_at(slot, local), attribute_at(slot, local)), 1.0);
    let rgb = unpack4x8unorm(pack4x8unorm(colour)).rgb;
    textureStore(output, vec2<i32>(id.xy), vec4<f32>(shade_pixel(id.xy, d, rgb), 1.0));
}
