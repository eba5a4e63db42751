// The 32-bit blend sums (uniforms.wgsl), normalised.
@group(0) @binding(2) var<storage, read> sums: array<u32>;

fn blend_at(p: u32) -> Blend {
    let i = p * SUM_WORDS;
    var b: Blend;
    b.fragments = sums[i] / FRAGMENT_WEIGHT;
    let w = f32(sums[i]);
    b.colour = vec3<f32>(f32(sums[i + 1u]), f32(sums[i + 2u]), f32(sums[i + 3u])) / (255.0 * w);
    b.normal = vec3<f32>(f32(sums[i + 4u]), f32(sums[i + 5u]), f32(sums[i + 6u])) / (1023.0 * w);
    return b;
}
