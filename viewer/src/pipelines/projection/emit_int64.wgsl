// One pass: depth in the high word, point index in the low word; the nearest point wins and
// equal depths go to the lower index.
@group(0) @binding(1) var<storage, read_write> keys: array<atomic<u64>>;

fn emit(pixel: u32, depth: u32, index: u32) {
    atomicMin(&keys[pixel], (u64(depth) << 32u) | u64(index));
}
