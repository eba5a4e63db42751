// Reprojection (Figure 2, first pass): each pixel of the previous frame's reconstructed depth is
// moved to where its surface lies in this frame; the nearest wins. The plane holds the
// complement of the depth bits, so that a cleared plane (0) is empty.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> tri: Triangulate;
@group(0) @binding(2) var<storage, read> previous: array<u32>;
@group(0) @binding(3) var<storage, read_write> reprojected: array<atomic<u32>>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let bits = previous[id.y * frame.width + id.x];
    if bits == EMPTY {
        return;
    }
    let world = on_ray(tri.prev_eye, tri.prev_forward, tri.prev_right, tri.prev_up, id.x, id.y, bitcast<f32>(bits));
    let clip = frame.view_proj * vec4<f32>(world, 1.0);
    if !in_depth_range(clip, frame.near, frame.far) {
        return;
    }
    let ndc = clip.xy / clip.w;
    let x = i32(floor((ndc.x * 0.5 + 0.5) * f32(frame.width)));
    let y = i32(floor((0.5 - ndc.y * 0.5) * f32(frame.height)));
    if x < 0 || y < 0 || x >= i32(frame.width) || y >= i32(frame.height) {
        return;
    }
    atomicMax(&reprojected[u32(y) * frame.width + u32(x)], ~bitcast<u32>(clip.w));
}
