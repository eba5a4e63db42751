// Depth peeling in one pass where the device has 64-bit atomics: the nearest depth (high word)
// and the lowest index at it (low word) among the points farther than `layer_reach` behind the
// previous layer's filled depth, kept as the complement so that a cleared plane (0) is empty.
@group(0) @binding(2) var<storage, read_write> peel_keys: array<atomic<u64>>;
@group(0) @binding(3) var<storage, read> reference: array<Texel>;

fn emit(pixel: u32, depth: u32, index: u32) {
    let previous = reference[pixel].x;
    if previous == 0u || bitcast<f32>(depth) <= bitcast<f32>(previous) + layer_reach(index) {
        return;
    }
    atomicMax(&peel_keys[pixel], ~((u64(depth) << 32u) | u64(index)));
}
