// After the 64-bit search: each sector's neighbour id as the two-pass search leaves it (the
// complement, 0 for none), which is the low word of the complemented key.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> keys: array<u64>;
@group(0) @binding(2) var<storage, read_write> neighbours: array<u32>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let first = (id.y * frame.width + id.x) * SECTORS;
    for (var s = 0u; s < SECTORS; s++) {
        neighbours[first + s] = u32(keys[first + s] & 0xfffffffflu);
    }
}
