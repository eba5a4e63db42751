// The 64-bit blend sums (uniforms.wgsl): two atomics a fragment where the 32-bit sums take
// seven, which made the raster pass a quarter faster on lavapipe.
@group(0) @binding(5) var<storage, read_write> sums: array<atomic<u64>>;

// Adds a fragment's colour and its normal mapped to [0, 1] (both clamped there) to pixel's
// sums, unless the pixel has kept SUM64_KEPT fragments. A fragment past them has added its
// colour word before it can know, and takes it back: the sums are modulo 2^64, so what the
// kept fragments added comes back exact whatever else was added and taken back meanwhile
// (an overflow in between only makes the count read higher, and a fragment turn away sooner).
fn add_sums(pixel: u32, colour: vec3<f32>, normal01: vec3<f32>) {
    let c = vec3<u32>(colour * SUM64_COLOUR_SCALE + 0.5);
    let colour_word = u64(c.x) | (u64(c.y) << SUM64_COLOUR_BITS) | (u64(c.z) << (2u * SUM64_COLOUR_BITS))
        | (1lu << SUM64_COUNT_SHIFT);
    let before = atomicAdd(&sums[2u * pixel], colour_word);
    if (before >> SUM64_COUNT_SHIFT) >= u64(SUM64_KEPT) {
        atomicSub(&sums[2u * pixel], colour_word);
        return;
    }
    let n = vec3<u32>(normal01 * SUM64_NORMAL_SCALE + 0.5);
    atomicAdd(&sums[2u * pixel + 1u], u64(n.x) | (u64(n.y) << SUM64_NORMAL_BITS) | (u64(n.z) << (2u * SUM64_NORMAL_BITS)));
}
