// The neighbour search (section 3.3): each point P covers the pixels within its search radius
// projected to the screen, and for each point Q there that lies within that radius in world
// space, offers itself as Q's neighbour in the sector of Q in which P lies. The variant
// appended before this file defines `visit`: the distance pass keeps the least distance per
// sector, the id pass registers the point at that distance.

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let p = id.y * frame.width + id.x;
    let me = pts[p];
    if me.w <= 0.0 {
        return;
    }
    let depth = linear_depth(me.xyz);
    if depth <= 0.0 {
        return;
    }
    let reach = i32(min(ceil(me.w * frame.focal_px / depth), f32(tri.max_search_px)));
    let reach2 = (reach + 1) * (reach + 1);
    for (var dy = -reach; dy <= reach; dy++) {
        let y = i32(id.y) + dy;
        if y < 0 || y >= i32(frame.height) {
            continue;
        }
        for (var dx = -reach; dx <= reach; dx++) {
            let x = i32(id.x) + dx;
            if x < 0 || x >= i32(frame.width) || dx * dx + dy * dy > reach2 || (dx == 0 && dy == 0) {
                continue;
            }
            let q = u32(y) * frame.width + u32(x);
            let other = pts[q];
            if other.w <= 0.0 {
                continue;
            }
            let dist = distance(me.xyz, other.xyz);
            if dist > me.w {
                continue;
            }
            // P lies at (-dx, -dy) from Q.
            visit(q * SECTORS + sector_of(f32(-dx), f32(-dy)), bitcast<u32>(dist), p);
        }
    }
}
