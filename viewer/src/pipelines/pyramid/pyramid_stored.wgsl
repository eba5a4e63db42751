// The dataset's normals into level 0 of the normal pyramid, once per arena (beyond paper 003,
// whose points carry none): each pixel whose nearest point lives in this arena and has a
// normal takes it, in view space and turned towards the eye (the picture shows the side it
// sees, and averaging a surface's normals must not cancel ones stored pointing either way).
// The HPR pass then keeps it only where the point is visible, and the pull-push carries it
// into the holes like colour.
@group(2) @binding(0) var<storage, read> ranges: array<Range>;
@group(2) @binding(1) var<storage, read> point_normals: array<u32>;
@group(2) @binding(2) var<storage, read> indices: array<u32>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let i = id.y * frame.width + id.x;
    let g = indices[i];
    let d = depths[i];
    if d == EMPTY || (g >> frame.arena_shift) != ranges[0].start {
        return;
    }
    let w = point_normals[g & ((1u << frame.arena_shift) - 1u)];
    if w == 0u {
        return;
    }
    let world = decode_oct16(w);
    var n = vec3<f32>(dot(pyr.view_rows[0].xyz, world), dot(pyr.view_rows[1].xyz, world), dot(pyr.view_rows[2].xyz, world));
    let p = view_point(vec2<f32>(id.xy) + 0.5, bitcast<f32>(d));
    if dot(n, p) > 0.0 {
        n = -n;
    }
    normals[i] = encode_normal(n);
}
