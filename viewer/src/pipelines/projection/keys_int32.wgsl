// Pixel access for passes after the two 32-bit projection passes.
@group(0) @binding(1) var<storage, read> depths: array<u32>;
@group(0) @binding(2) var<storage, read> indices: array<u32>;

fn pixel_depth(i: u32) -> u32 {
    return depths[i];
}

fn pixel_index(i: u32) -> u32 {
    return indices[i];
}
