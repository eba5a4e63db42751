// The 32-bit blend sums (uniforms.wgsl): seven atomics a fragment.
@group(0) @binding(5) var<storage, read_write> sums: array<atomic<u32>>;
// The back faces' own, where SIDES (raster.wgsl).
@group(0) @binding(9) var<storage, read_write> back_sums: array<atomic<u32>>;

// Adds a fragment's colour and its normal mapped to [0, 1] (both clamped there) to pixel's sums
// (the back faces' where `back`).
fn add_sums(pixel: u32, colour: vec3<f32>, normal01: vec3<f32>, back: bool) {
    let i = pixel * SUM_WORDS;
    let c = vec3<u32>(colour * f32(255u * FRAGMENT_WEIGHT) + 0.5);
    let n = vec3<u32>(normal01 * f32(1023u * FRAGMENT_WEIGHT) + 0.5);
    let words = array<u32, SUM_WORDS>(FRAGMENT_WEIGHT, c.x, c.y, c.z, n.x, n.y, n.z);
    for (var k = 0u; k < SUM_WORDS; k++) {
        if SIDES && back {
            atomicAdd(&back_sums[i + k], words[k]);
        } else {
            atomicAdd(&sums[i + k], words[k]);
        }
    }
}
