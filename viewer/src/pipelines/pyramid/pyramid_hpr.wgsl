// Hidden-point removal over the whole image (paper 003, 3.1.2). Each pixel's neighbourhood is
// the ring of eight cells around it on every pyramid level up to the level of equation 1, with
// the coarse depth taken from `pyr.coarse_level` (a background pixel where the points lie
// denser than half a pixel: level 0 only, see `reach_at`). Per sector the most occluding neighbour
// counts; a mean occlusion below the threshold marks the pixel as a hole (a hidden point, or
// background enclosed by surface), else it stays a visible point or visible background.
// Also seeds level 0 of the pull-push pyramid with the visible points.
//
// What both shapes of the pass share (pyramid_hpr_pixel.wgsl: one pixel an invocation, for
// GPUs; pyramid_hpr_block.wgsl: a 4x4 block, for CPU adapters). They give the same labels.

// A neighbour: its view-space point and that point's squared length. A cell outside the level
// gives a point on the view axis beyond the far plane instead: seen from any pixel's point
// (never beyond the far plane) it lies behind, its occlusion exceeds 1 and cannot lower a
// sector, which starts at 1. That spares the occlusion a test per neighbour.
fn neighbour(n: vec2<i32>, size: vec2<i32>, off: u32) -> vec4<f32> {
    let inside = all(n >= vec2<i32>(0)) && all(n < size);
    let c = clamp(n, vec2<i32>(0), size - 1);
    let beyond = vec3<f32>(0.0, 0.0, -2.0 * pyr.far);
    let y = select(beyond, entry_point(pts[off + u32(c.y * size.x + c.x)]), inside);
    return vec4<f32>(y, dot(y, y));
}

// The occlusion 1 - cos(y - x, -y) of x by the neighbour y. A ring never holds x itself (its
// cells are other pixels, or other cells of a level), so y - x is never zero. Branch-free, so
// that the eight sectors run in lock step where invocations are SIMD lanes (CPU adapters).
fn occlusion(x: vec3<f32>, y: vec4<f32>) -> f32 {
    let dir = y.xyz - x;
    return 1.0 + dot(dir, y.xyz) * inverseSqrt(max(dot(dir, dir) * y.w, 1e-30));
}

// Per sector, counter-clockwise from +x: 0-3 in `lo`, 4-7 in `hi`.
struct Sectors {
    lo: vec4<f32>,
    hi: vec4<f32>,
}

// Folds one ring (its cells in sector order) into a pixel's sectors.
fn fold(s: Sectors, x: vec3<f32>, r: array<vec4<f32>, 8>) -> Sectors {
    let lo = vec4<f32>(
        occlusion(x, r[0]),
        occlusion(x, r[1]),
        occlusion(x, r[2]),
        occlusion(x, r[3]),
    );
    let hi = vec4<f32>(
        occlusion(x, r[4]),
        occlusion(x, r[5]),
        occlusion(x, r[6]),
        occlusion(x, r[7]),
    );
    return Sectors(min(s.lo, lo), min(s.hi, hi));
}

// The ring of cell `p` of a level, in sector order.
fn ring(p: vec2<i32>, size: vec2<i32>, off: u32) -> array<vec4<f32>, 8> {
    return array<vec4<f32>, 8>(
        neighbour(p + vec2<i32>(1, 0), size, off),
        neighbour(p + vec2<i32>(1, 1), size, off),
        neighbour(p + vec2<i32>(0, 1), size, off),
        neighbour(p + vec2<i32>(-1, 1), size, off),
        neighbour(p + vec2<i32>(-1, 0), size, off),
        neighbour(p + vec2<i32>(-1, -1), size, off),
        neighbour(p + vec2<i32>(0, -1), size, off),
        neighbour(p + vec2<i32>(1, -1), size, off),
    );
}

// The highest levels whose rings count for pixel `p`: equation 1 with the coarse level's depth
// at `p`; for a background pixel the same, but level 0 where the points lie too densely to
// leave a hole wider than a pixel (`dense_scale`).
struct Reach {
    point: i32,
    background: i32,
}

fn reach_at(p: vec2<u32>) -> Reach {
    let c = pyr.coarse_level;
    let coarse = pts[level_offset(c) + (p.y >> c) * level_size(c).x + (p.x >> c)];
    let z = max(bitcast<f32>(coarse.x), 1e-6);
    let top = i32(pyr.levels) - 1;
    let point = clamp(i32(round(log2(pyr.hpr_scale / z))), 1, max(top, 1));
    return Reach(point, select(point, 0, pyr.dense_scale < z));
}

// The nearest depth among cells `lo` to `hi` (inclusive, clamped into level `l`). Where it is
// the far plane (background away from any surface, most of the image in an overview), nothing
// there occludes and the sectors can be skipped.
fn nearest_in(l: u32, lo: vec2<i32>, hi: vec2<i32>) -> u32 {
    let size = vec2<i32>(level_size(l));
    let off = level_offset(l);
    var nearest = EMPTY;
    for (var y = lo.y; y <= hi.y; y++) {
        for (var x = lo.x; x <= hi.x; x++) {
            let cell = clamp(vec2<i32>(x, y), vec2<i32>(0), size - 1);
            nearest = min(nearest, pts[off + u32(cell.y * size.x + cell.x)].x);
        }
    }
    return nearest;
}

// Labels pixel `px` (skipped where it lies outside the frame) from its sectors, `s` up to its
// point reach and `b` up to its background reach, and seeds the pull-push with it.
fn finish(px: vec2<u32>, s: Sectors, b: Sectors) {
    if px.x >= frame.width || px.y >= frame.height {
        return;
    }
    let i = px.y * frame.width + px.x;
    let d = depths[i];
    let sectors = select(s.lo + s.hi, b.lo + b.hi, d == EMPTY);
    let visible = dot(sectors, vec4<f32>(0.125)) >= pyr.threshold;
    var label = LABEL_HOLE;
    if visible {
        label = select(LABEL_POINT, LABEL_BACKGROUND, d == EMPTY);
    }
    labels[i] = label;
    let point = label == LABEL_POINT;
    fill[i] = vec2<f32>(select(0.0, bitcast<f32>(d), point), select(0.0, 1.0, point));
    fill_colour[i] = select(0u, colours[i], point);
    if pyr.stored_normals != 0u && !point {
        normals[i] = NO_NORMAL;
    }
}
