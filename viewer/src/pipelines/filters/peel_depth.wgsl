// Depth peeling (sections 4 and 5), first of two passes: the nearest depth per pixel among the
// points farther than `layer_reach` (d~) behind the previous layer's filled depth there. Planes hold complements
// (atomicMax), so that a cleared plane (0) is empty.
@group(0) @binding(2) var<storage, read_write> peel_depths: array<atomic<u32>>;
@group(0) @binding(3) var<storage, read> reference: array<Texel>;

fn emit(pixel: u32, depth: u32, index: u32) {
    let previous = reference[pixel].x;
    // Behind background nothing is left to peel: every point there was in an earlier layer.
    if previous == 0u || bitcast<f32>(depth) <= bitcast<f32>(previous) + layer_reach(index) {
        return;
    }
    atomicMax(&peel_depths[pixel], ~depth);
}
