// First of two 32-bit passes: the nearest depth per pixel.
@group(0) @binding(1) var<storage, read_write> depths: array<atomic<u32>>;

fn emit(pixel: u32, depth: u32, index: u32) {
    atomicMin(&depths[pixel], depth);
}
