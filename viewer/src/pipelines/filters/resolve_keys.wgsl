// The resolve's pixels from the 64-bit keys, read as their two words (index low, depth high),
// so that no pass unpacks them into planes first; complemented where the step says so (a
// peeled layer's).
@group(0) @binding(2) var<storage, read> keys: array<vec2<u32>>;

// The pixel's depth and point index.
fn pixel_key(i: u32) -> vec2<u32> {
    let k = keys[i].yx;
    return select(k, ~k, step.complemented != 0u);
}
