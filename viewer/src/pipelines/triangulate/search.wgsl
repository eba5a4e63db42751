// The neighbour search (section 3.3): each point P covers the pixels of its search sphere
// projected to the screen (at most `max_search_px` either side), and for each point Q there that lies within that radius in world
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
    // The screen box of the search sphere: the box of its bounding cube's projected corners,
    // which holds the sphere's projection wherever it lies in the view (off the axis a sphere
    // projects larger than r * focal / depth); a corner behind the eye takes the largest box.
    let me_px = vec2<f32>(f32(id.x) + 0.5, f32(id.y) + 0.5);
    var lo = me_px;
    var hi = me_px;
    var behind = false;
    for (var c = 0u; c < 8u; c++) {
        let corner = me.xyz + me.w * vec3<f32>(
            select(-1.0, 1.0, (c & 1u) != 0u),
            select(-1.0, 1.0, (c & 2u) != 0u),
            select(-1.0, 1.0, (c & 4u) != 0u),
        );
        let clip = frame.view_proj * vec4<f32>(corner, 1.0);
        if clip.w <= 0.0 {
            behind = true;
            break;
        }
        let px = vec2<f32>((clip.x / clip.w * 0.5 + 0.5) * f32(frame.width), (0.5 - clip.y / clip.w * 0.5) * f32(frame.height));
        lo = min(lo, px);
        hi = max(hi, px);
    }
    let most = i32(tri.max_search_px);
    var x0 = -most;
    var x1 = most;
    var y0 = -most;
    var y1 = most;
    if !behind {
        x0 = max(i32(floor(lo.x)) - i32(id.x), -most);
        x1 = min(i32(floor(hi.x)) - i32(id.x), most);
        y0 = max(i32(floor(lo.y)) - i32(id.y), -most);
        y1 = min(i32(floor(hi.y)) - i32(id.y), most);
    }
    for (var dy = y0; dy <= y1; dy++) {
        let y = i32(id.y) + dy;
        if y < 0 || y >= i32(frame.height) {
            continue;
        }
        for (var dx = x0; dx <= x1; dx++) {
            let x = i32(id.x) + dx;
            if x < 0 || x >= i32(frame.width) || (dx == 0 && dy == 0) {
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
