// The second search pass: the point at the least distance registers its pixel id in the
// sector (the lowest id among equals), as the complement so that 0 is none.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> tri: Triangulate;
@group(0) @binding(2) var<storage, read> pts: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> nearest: array<u32>;
@group(0) @binding(4) var<storage, read_write> neighbours: array<atomic<u32>>;
@group(0) @binding(5) var<storage, read> point_normals: array<u32>;

// Distances within this many ulps of the least count as it: the two passes are separate
// modules, and a driver may round the same expression differently in each.
const SAME_DISTANCE_ULPS: u32 = 8u;

fn visit(slot: u32, dist: u32, p: u32) {
    if dist <= ~nearest[slot] + SAME_DISTANCE_ULPS {
        atomicMax(&neighbours[slot], ~p);
    }
}
