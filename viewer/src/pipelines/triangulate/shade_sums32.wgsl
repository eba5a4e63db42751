// The 32-bit blend sums (uniforms.wgsl), normalised.
@group(0) @binding(2) var<storage, read> sums: array<u32>;
// The back faces' own, where SIDES (raster.wgsl).
@group(0) @binding(7) var<storage, read> back_sums: array<u32>;

// Word `i` of the front faces' sums, or of the back faces' where `back`.
fn sum_word(i: u32, back: bool) -> u32 {
    if SIDES && back {
        return back_sums[i];
    }
    return sums[i];
}

fn blend_at(p: u32, back: bool) -> Blend {
    let i = p * SUM_WORDS;
    var b: Blend;
    let weight = sum_word(i, back);
    b.fragments = weight / FRAGMENT_WEIGHT;
    let w = f32(weight);
    b.colour = vec3<f32>(f32(sum_word(i + 1u, back)), f32(sum_word(i + 2u, back)), f32(sum_word(i + 3u, back))) / (255.0 * w);
    b.normal = vec3<f32>(f32(sum_word(i + 4u, back)), f32(sum_word(i + 5u, back)), f32(sum_word(i + 6u, back))) / (1023.0 * w);
    return b;
}
