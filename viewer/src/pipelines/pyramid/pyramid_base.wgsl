// Level 0 of the point pyramid: every pixel's nearest point, background at the far plane.
@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let i = id.y * frame.width + id.x;
    let d = depths[i];
    pts[i] = vec2<u32>(select(d, bitcast<u32>(pyr.far), d == EMPTY), pack_pixel(id.xy));
}
