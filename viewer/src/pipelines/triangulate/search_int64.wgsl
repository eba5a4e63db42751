// Both search passes in one where the device has 64-bit atomics: the distance in the high
// word and the pixel id in the low, so that the nearest (the lowest id among equals) wins, kept
// as the complement so that a cleared plane (0) holds none.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> tri: Triangulate;
@group(0) @binding(2) var<storage, read> pts: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> keys: array<atomic<u64>>;
@group(0) @binding(4) var<storage, read> point_normals: array<u32>;

fn visit(slot: u32, dist: u32, p: u32) {
    atomicMax(&keys[slot], ~((u64(dist) << 32u) | u64(p)));
}
