// Splits the 64-bit peel keys into the depth and index planes the resolve reads (complements
// both, as the two 32-bit passes leave them).
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(2) var<storage, read> peel_keys: array<vec2<u32>>;
@group(0) @binding(3) var<storage, read_write> peel_depths: array<u32>;
@group(0) @binding(4) var<storage, read_write> peel_indices: array<u32>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let i = id.y * frame.width + id.x;
    let k = peel_keys[i];
    peel_depths[i] = k.y;
    peel_indices[i] = k.x;
}
