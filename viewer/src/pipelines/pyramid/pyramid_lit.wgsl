// The shadows' lit share into the colour plane, once per arena: each pixel whose nearest point
// lives in this arena takes that point's share of the light (its lit count times 1 / the
// samples summed) as its colour's alpha, which the pull-push then carries like colour.
@group(0) @binding(0) var<uniform> frame: Frame;
// x: 1 / the light samples summed in each point's lit count.
@group(0) @binding(1) var<uniform> lit_scale: vec4<f32>;
@group(0) @binding(2) var<storage, read> depths: array<u32>;
@group(0) @binding(3) var<storage, read> indices: array<u32>;
@group(0) @binding(4) var<storage, read_write> colours: array<u32>;
@group(1) @binding(0) var<storage, read> ranges: array<Range>;
// Per point: the light samples that reached it (shadow.wgsl).
@group(1) @binding(1) var<storage, read> lit: array<f32>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let i = id.y * frame.width + id.x;
    let g = indices[i];
    if depths[i] == EMPTY || (g >> frame.arena_shift) != ranges[0].start {
        return;
    }
    let share = clamp(lit[g & ((1u << frame.arena_shift) - 1u)] * lit_scale.x, 0.0, 1.0);
    colours[i] = (colours[i] & 0x00ffffffu) | (u32(share * 255.0 + 0.5) << 24u);
}
