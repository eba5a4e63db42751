// Depth peeling, second pass: among the points at the layer's nearest depth, the lowest index
// (as the projection picks), kept as a complement.
@group(0) @binding(2) var<storage, read> peel_depths: array<u32>;
@group(0) @binding(3) var<storage, read_write> peel_indices: array<atomic<u32>>;

fn emit(pixel: u32, depth: u32, index: u32) {
    if peel_depths[pixel] == ~depth {
        atomicMax(&peel_indices[pixel], ~index);
    }
}
