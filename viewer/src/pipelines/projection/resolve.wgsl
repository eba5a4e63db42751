// Resolve, once per arena: each pixel whose nearest point lives in this arena fetches that
// point's attributes and writes its colour for the current colouring mode.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> depths: array<u32>;
@group(0) @binding(2) var<storage, read> indices: array<u32>;
@group(0) @binding(3) var<storage, read_write> colours: array<u32>;
@group(1) @binding(0) var<storage, read> points: array<vec4<u32>>;
@group(1) @binding(1) var<storage, read> ranges: array<Range>;
@group(1) @binding(2) var<storage, read> attributes: array<u32>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let i = id.y * frame.width + id.x;
    if depths[i] == EMPTY {
        return;
    }
    let g = indices[i];
    if (g >> frame.arena_shift) != ranges[0].start {
        return;
    }
    let local = g & ((1u << frame.arena_shift) - 1u);
    let p = points[local];
    let a = attributes[local];
    let rgb = point_colour(p, a);
    colours[i] = pack4x8unorm(vec4<f32>(rgb, 1.0));
}
