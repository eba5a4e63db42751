// Second 32-bit pass: among the points at the nearest depth, the lowest index, so the result
// equals the 64-bit path's.
@group(0) @binding(1) var<storage, read> depths: array<u32>;
@group(0) @binding(2) var<storage, read_write> indices: array<atomic<u32>>;

fn emit(pixel: u32, depth: u32, index: u32) {
    if depths[pixel] == depth {
        atomicMin(&indices[pixel], index);
    }
}
