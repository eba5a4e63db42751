// The resolve's pixels from the depth and index planes (the 32-bit passes'); complemented
// where the step says so (a peeled layer's).
@group(0) @binding(2) var<storage, read> depths: array<u32>;
@group(0) @binding(3) var<storage, read> indices: array<u32>;

// The pixel's depth and point index.
fn pixel_key(i: u32) -> vec2<u32> {
    let k = vec2<u32>(depths[i], indices[i]);
    return select(k, ~k, step.complemented != 0u);
}
