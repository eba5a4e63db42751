// Pixel rays and linear depth in this frame's and the previous frame's view.

// The world position on the ray through pixel centre (x, y) at linear depth d, with the given rays.
fn on_ray(eye: vec4<f32>, forward: vec4<f32>, right: vec4<f32>, up: vec4<f32>, x: u32, y: u32, d: f32) -> vec3<f32> {
    let nx = (f32(x) + 0.5) / f32(frame.width) * 2.0 - 1.0;
    let ny = 1.0 - (f32(y) + 0.5) / f32(frame.height) * 2.0;
    return eye.xyz + d * (forward.xyz + nx * right.xyz + ny * up.xyz);
}

// Linear depth of a world position in this frame.
fn linear_depth(p: vec3<f32>) -> f32 {
    return dot(p - tri.eye.xyz, normalize(tri.forward.xyz));
}

// Pixels a connection may always span: one point per pixel survives the projection, so on a
// surface sampled more densely than the screen, neighbours lie a pixel or more apart however
// short `max_connection` is (a diagonal neighbour and the depth slope between them).
const CONNECT_PX: f32 = 3.0;

// The longest connection of a point at linear depth `depth` in a node of `spacing`:
// `max_connection`; where it is automatic, `spacing_factor` node spacings where the point's
// node is coarser than the median of the view (a view draws coarse nodes far away); and
// CONNECT_PX pixels at its depth, where that is longer.
fn connection_limit(depth: f32, spacing: f32) -> f32 {
    return max(max(tri.max_connection, tri.spacing_factor * spacing), CONNECT_PX * depth / frame.focal_px);
}
