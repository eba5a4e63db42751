// Pixel access for passes after the 64-bit projection: depth in the high word, index low.
@group(0) @binding(1) var<storage, read> keys: array<vec2<u32>>;

fn pixel_depth(i: u32) -> u32 {
    return keys[i].y;
}

fn pixel_index(i: u32) -> u32 {
    return keys[i].x;
}
