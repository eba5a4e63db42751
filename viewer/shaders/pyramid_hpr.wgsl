// Hidden-point removal over the whole image (paper 003, 3.1.2). Each pixel's neighbourhood is
// the ring of eight cells around it on every pyramid level up to the level of equation 1, with
// the coarse depth taken from `pyr.coarse_level`. Per sector the most occluding neighbour
// counts; a mean occlusion below the threshold marks the pixel as a hole (a hidden point, or
// background enclosed by surface), else it stays a visible point or visible background.
// Also seeds level 0 of the pull-push pyramid with the visible points.

const RING = array<vec2<i32>, 8>(
    vec2<i32>(1, 0), vec2<i32>(1, 1), vec2<i32>(0, 1), vec2<i32>(-1, 1),
    vec2<i32>(-1, 0), vec2<i32>(-1, -1), vec2<i32>(0, -1), vec2<i32>(1, -1),
);

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let i = id.y * frame.width + id.x;
    let x = entry_point(pts[i]);
    let c = pyr.coarse_level;
    let coarse = pts[level_offset(c) + (id.y >> c) * level_size(c).x + (id.x >> c)];
    let z = max(bitcast<f32>(coarse.x), 1e-6);
    let top = i32(pyr.levels) - 1;
    let reach = clamp(i32(round(log2(pyr.hpr_scale / z))), 1, max(top, 1));
    var sector = array<f32, 8>(1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0);
    for (var l = 0; l <= reach; l++) {
        let size = vec2<i32>(level_size(u32(l)));
        let off = level_offset(u32(l));
        let centre = vec2<i32>(id.xy) >> vec2<u32>(u32(l));
        for (var s = 0; s < 8; s++) {
            let n = centre + RING[s];
            if n.x < 0 || n.y < 0 || n.x >= size.x || n.y >= size.y {
                continue;
            }
            let y = entry_point(pts[off + u32(n.y * size.x + n.x)]);
            let dir = y - x;
            let len = length(dir);
            if len <= 1e-9 * length(x) {
                continue;
            }
            let occlusion = 1.0 - dot(dir / len, normalize(-y));
            sector[s] = min(sector[s], occlusion);
        }
    }
    var mean = 0.0;
    for (var s = 0; s < 8; s++) {
        mean += sector[s];
    }
    mean /= 8.0;
    let visible = mean >= pyr.threshold;
    let d = depths[i];
    var label = LABEL_HOLE;
    if visible {
        label = select(LABEL_POINT, LABEL_BACKGROUND, d == EMPTY);
    }
    labels[i] = label;
    let point = label == LABEL_POINT;
    fill[i] = vec2<f32>(select(0.0, bitcast<f32>(d), point), select(0.0, 1.0, point));
    fill_colour[i] = select(0u, colours[i], point);
}
