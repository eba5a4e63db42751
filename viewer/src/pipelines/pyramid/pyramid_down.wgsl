// One coarser level of the point pyramid: of each 2x2 block, the point with the least depth.
@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let l = level.index;
    let size = level_size(l);
    if id.x >= size.x || id.y >= size.y {
        return;
    }
    let fine = level_size(l - 1u);
    let fine_off = level_offset(l - 1u);
    var best = vec2<u32>(EMPTY, EMPTY);
    for (var dy = 0u; dy < 2u; dy++) {
        for (var dx = 0u; dx < 2u; dx++) {
            let c = id.xy * 2u + vec2<u32>(dx, dy);
            if c.x < fine.x && c.y < fine.y {
                let e = pts[fine_off + c.y * fine.x + c.x];
                if e.x < best.x || (e.x == best.x && e.y < best.y) {
                    best = e;
                }
            }
        }
    }
    pts[level_offset(l) + id.y * size.x + id.x] = best;
}
