// The 64-bit blend sums (uniforms.wgsl), normalised; each word read as its low and high
// halves, so that this pass needs no 64-bit integers.
@group(0) @binding(2) var<storage, read> sums: array<vec2<u32>>;
// The back faces' own, where SIDES (raster.wgsl).
@group(0) @binding(7) var<storage, read> back_sums: array<vec2<u32>>;

// Word `i` of the front faces' sums, or of the back faces' where `back`.
fn sum_word(i: u32, back: bool) -> vec2<u32> {
    if SIDES && back {
        return back_sums[i];
    }
    return sums[i];
}

// Bits `offset` to `offset + count` (count below 32) of the 64-bit word w (low, high).
fn field(w: vec2<u32>, offset: u32, count: u32) -> u32 {
    let mask = (1u << count) - 1u;
    if offset >= 32u {
        return (w.y >> (offset - 32u)) & mask;
    }
    if offset + count <= 32u {
        return (w.x >> offset) & mask;
    }
    return ((w.x >> offset) | (w.y << (32u - offset))) & mask;
}

fn blend_at(p: u32, back: bool) -> Blend {
    let c = sum_word(SUM64_WORDS * p, back);
    let n = sum_word(SUM64_WORDS * p + 1u, back);
    var b: Blend;
    b.fragments = c.y >> (SUM64_COUNT_SHIFT - 32u);
    let w = f32(b.fragments);
    let cb = SUM64_COLOUR_BITS;
    b.colour = vec3<f32>(f32(field(c, 0u, cb)), f32(field(c, cb, cb)), f32(field(c, 2u * cb, cb))) / (SUM64_COLOUR_SCALE * w);
    let nb = SUM64_NORMAL_BITS;
    b.normal = vec3<f32>(f32(field(n, 0u, nb)), f32(field(n, nb, nb)), f32(field(n, 2u * nb, nb))) / (SUM64_NORMAL_SCALE * w);
    return b;
}
