// Hidden-point removal over the whole image (paper 003, 3.1.2). Each pixel's neighbourhood is
// the ring of eight cells around it on every pyramid level up to the level of equation 1, with
// the coarse depth taken from `pyr.coarse_level`. Per sector the most occluding neighbour
// counts; a mean occlusion below the threshold marks the pixel as a hole (a hidden point, or
// background enclosed by surface), else it stays a visible point or visible background.
// Also seeds level 0 of the pull-push pyramid with the visible points.

// The occlusion 1 - cos(y - x, -y) of x by the point y in cell `n` of a level at offset `off`;
// 1 (no occlusion) where `n` lies outside the level or y is x itself. Branch-free, so that the
// eight sectors run in lock step where invocations are SIMD lanes (CPU adapters). A workgroup
// tile of unprojected cells in shared memory was tried and measured slower on lavapipe (a tile
// cell is three words to read, a pyramid entry two).
fn occlusion(x: vec3<f32>, n: vec2<i32>, size: vec2<i32>, off: u32) -> f32 {
    let inside = all(n >= vec2<i32>(0)) && all(n < size);
    let c = clamp(n, vec2<i32>(0), size - 1);
    let y = entry_point(pts[off + u32(c.y * size.x + c.x)]);
    let dir = y - x;
    let dd = dot(dir, dir);
    let occ = 1.0 + dot(dir, y) * inverseSqrt(max(dd * dot(y, y), 1e-30));
    return select(1.0, occ, inside && dd > 1e-18 * dot(x, x));
}

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
    // The ring of every level up to `reach` lies inside the 3x3 block of cells around the pixel
    // at `reach`. Where that block holds only the far plane (background away from any surface,
    // most of the image in an overview), nothing occludes and the eight sectors can be skipped.
    let top_size = vec2<i32>(level_size(u32(reach)));
    let top_off = level_offset(u32(reach));
    let top_cell = vec2<i32>(id.xy) >> vec2<u32>(u32(reach));
    var nearest = EMPTY;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let cell = clamp(top_cell + vec2<i32>(dx, dy), vec2<i32>(0), top_size - 1);
            nearest = min(nearest, pts[top_off + u32(cell.y * top_size.x + cell.x)].x);
        }
    }
    var mean = 1.0;
    if nearest < bitcast<u32>(pyr.far) {
        // Sectors 0-3 and 4-7, counter-clockwise from +x.
        var s03 = vec4<f32>(1.0);
        var s47 = vec4<f32>(1.0);
        for (var l = 0; l <= reach; l++) {
            let size = vec2<i32>(level_size(u32(l)));
            let off = level_offset(u32(l));
            let p = vec2<i32>(id.xy) >> vec2<u32>(u32(l));
            s03 = min(s03, vec4<f32>(
                occlusion(x, p + vec2<i32>(1, 0), size, off),
                occlusion(x, p + vec2<i32>(1, 1), size, off),
                occlusion(x, p + vec2<i32>(0, 1), size, off),
                occlusion(x, p + vec2<i32>(-1, 1), size, off),
            ));
            s47 = min(s47, vec4<f32>(
                occlusion(x, p + vec2<i32>(-1, 0), size, off),
                occlusion(x, p + vec2<i32>(-1, -1), size, off),
                occlusion(x, p + vec2<i32>(0, -1), size, off),
                occlusion(x, p + vec2<i32>(1, -1), size, off),
            ));
        }
        mean = dot(s03 + s47, vec4<f32>(0.125));
    }
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
