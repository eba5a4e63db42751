// The first search pass: the least distance per sector (the paper's minimum blending), as the
// complement of its bits so that a cleared plane (0) holds none.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> tri: Triangulate;
@group(0) @binding(2) var<storage, read> pts: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> nearest: array<atomic<u32>>;
@group(0) @binding(4) var<storage, read> point_normals: array<u32>;

fn visit(slot: u32, dist: u32, p: u32) {
    atomicMax(&nearest[slot], ~dist);
}
