// The 32-bit blend sums (uniforms.wgsl): seven atomics a fragment.
@group(0) @binding(5) var<storage, read_write> sums: array<atomic<u32>>;

// Adds a fragment's colour and its normal mapped to [0, 1] (both clamped there) to pixel's sums.
fn add_sums(pixel: u32, colour: vec3<f32>, normal01: vec3<f32>) {
    let i = pixel * SUM_WORDS;
    let c = vec3<u32>(colour * f32(255u * FRAGMENT_WEIGHT) + 0.5);
    let n = vec3<u32>(normal01 * f32(1023u * FRAGMENT_WEIGHT) + 0.5);
    atomicAdd(&sums[i], FRAGMENT_WEIGHT);
    atomicAdd(&sums[i + 1u], c.x);
    atomicAdd(&sums[i + 2u], c.y);
    atomicAdd(&sums[i + 3u], c.z);
    atomicAdd(&sums[i + 4u], n.x);
    atomicAdd(&sums[i + 5u], n.y);
    atomicAdd(&sums[i + 6u], n.z);
}
