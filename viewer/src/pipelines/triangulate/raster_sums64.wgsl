// The 64-bit blend sums (uniforms.wgsl): two atomics a fragment where the 32-bit sums take
// seven, which made the raster pass a quarter faster on lavapipe.
@group(0) @binding(5) var<storage, read_write> sums: array<atomic<u64>>;
// The back faces' own, where SIDES (raster.wgsl).
@group(0) @binding(9) var<storage, read_write> back_sums: array<atomic<u64>>;

// Word `i` of the front faces' sums, or of the back faces' where `back`.
fn sum_word(i: u32, back: bool) -> u64 {
    if SIDES && back {
        return atomicLoad(&back_sums[i]);
    }
    return atomicLoad(&sums[i]);
}

// Adds `w` to word `i` of the sums `back` chooses; returns what the word held before.
fn add_to_sum(i: u32, back: bool, w: u64) -> u64 {
    if SIDES && back {
        return atomicAdd(&back_sums[i], w);
    }
    return atomicAdd(&sums[i], w);
}

// Takes `w` back from word `i` of the sums `back` chooses.
fn take_from_sum(i: u32, back: bool, w: u64) {
    if SIDES && back {
        atomicSub(&back_sums[i], w);
    } else {
        atomicSub(&sums[i], w);
    }
}

// Adds a fragment's colour and its normal mapped to [0, 1] (both clamped there) to pixel's
// sums (the back faces' where `back`), unless the pixel has kept SUM64_KEPT fragments. A
// fragment that reads the count below that adds its colour word, and finds the count it added
// to in what the add returns: past the kept ones, it takes its add back. Sums are modulo 2^64, so what the kept fragments added
// comes back exact whatever was added and taken back meanwhile; only fragments that read the
// count before it filled are ever taken back, and as long as fewer than 2^13 - 512 of them are
// on one pixel at once the count cannot wrap, so no field overflows.
fn add_sums(pixel: u32, colour: vec3<f32>, normal01: vec3<f32>, back: bool) {
    let i = SUM64_WORDS * pixel;
    if (sum_word(i, back) >> SUM64_COUNT_SHIFT) >= u64(SUM64_KEPT) {
        return;
    }
    // Within the fields whatever the input (a NaN converts to any u32).
    let c = min(vec3<u32>(colour * SUM64_COLOUR_SCALE + 0.5), vec3<u32>(u32(SUM64_COLOUR_SCALE)));
    let colour_word = u64(c.x) | (u64(c.y) << SUM64_COLOUR_BITS) | (u64(c.z) << (2u * SUM64_COLOUR_BITS))
        | (1lu << SUM64_COUNT_SHIFT);
    let before = add_to_sum(i, back, colour_word);
    if (before >> SUM64_COUNT_SHIFT) >= u64(SUM64_KEPT) {
        take_from_sum(i, back, colour_word);
        return;
    }
    let n = min(vec3<u32>(normal01 * SUM64_NORMAL_SCALE + 0.5), vec3<u32>(u32(SUM64_NORMAL_SCALE)));
    let normal_word = u64(n.x) | (u64(n.y) << SUM64_NORMAL_BITS) | (u64(n.z) << (2u * SUM64_NORMAL_BITS));
    add_to_sum(i + 1u, back, normal_word);
}
