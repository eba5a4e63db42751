// Hidden-point removal over the whole image (paper 003, 3.1.2). Each pixel's neighbourhood is
// the ring of eight cells around it on every pyramid level up to the level of equation 1, with
// the coarse depth taken from `pyr.coarse_level`. Per sector the most occluding neighbour
// counts; a mean occlusion below the threshold marks the pixel as a hole (a hidden point, or
// background enclosed by surface), else it stays a visible point or visible background.
// Also seeds level 0 of the pull-push pyramid with the visible points.
//
// One invocation serves an aligned 2x2 block of pixels. The block shares its cell on every
// level from 1 up, hence its coarse depth, its `reach` and its ring there: each neighbour is
// read and unprojected once for four pixels, and on level 0 the four rings fall inside one 4x4
// block of 16 cells instead of 32 reads. The labels are the same as with one pixel an
// invocation. (A workgroup tile in shared memory was tried and measured slower on lavapipe.)

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

// The level-0 ring, in sector order, of the block pixel whose cell is (a, b) + 1 in the 4x4
// block `q` around the 2x2 block (row-major, from the cell left of and above the block).
fn ring0(q: array<vec4<f32>, 16>, a: i32, b: i32) -> array<vec4<f32>, 8> {
    let c = a + 1 + (b + 1) * 4;
    return array<vec4<f32>, 8>(
        q[c + 1], q[c + 5], q[c + 4], q[c + 3], q[c - 1], q[c - 5], q[c - 4], q[c - 3],
    );
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

// Labels pixel `px` (skipped where it lies outside the frame) from its sectors and seeds the
// pull-push with it.
fn finish(px: vec2<u32>, s: Sectors) {
    if px.x >= frame.width || px.y >= frame.height {
        return;
    }
    let i = px.y * frame.width + px.x;
    let visible = dot(s.lo + s.hi, vec4<f32>(0.125)) >= pyr.threshold;
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

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let base = id.xy * 2u;
    if base.x >= frame.width || base.y >= frame.height {
        return;
    }
    let c = pyr.coarse_level;
    let coarse = pts[level_offset(c) + (base.y >> c) * level_size(c).x + (base.x >> c)];
    let z = max(bitcast<f32>(coarse.x), 1e-6);
    let top = i32(pyr.levels) - 1;
    let reach = clamp(i32(round(log2(pyr.hpr_scale / z))), 1, max(top, 1));
    // The ring of every level up to `reach` lies inside the 3x3 block of cells around the pixel
    // at `reach`. Where that block holds only the far plane (background away from any surface,
    // most of the image in an overview), nothing occludes and the eight sectors can be skipped.
    let top_size = vec2<i32>(level_size(u32(reach)));
    let top_off = level_offset(u32(reach));
    let top_cell = vec2<i32>(base) >> vec2<u32>(u32(reach));
    var nearest = EMPTY;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let cell = clamp(top_cell + vec2<i32>(dx, dy), vec2<i32>(0), top_size - 1);
            nearest = min(nearest, pts[top_off + u32(cell.y * top_size.x + cell.x)].x);
        }
    }
    let open = Sectors(vec4<f32>(1.0), vec4<f32>(1.0));
    var s00 = open;
    var s10 = open;
    var s01 = open;
    var s11 = open;
    if nearest < bitcast<u32>(pyr.far) {
        let size0 = vec2<i32>(level_size(0u));
        let corner = vec2<i32>(base) - 1;
        var q: array<vec4<f32>, 16>;
        for (var k = 0; k < 16; k++) {
            q[k] = neighbour(corner + vec2<i32>(k & 3, k >> 2), size0, 0u);
        }
        let x00 = q[5].xyz;
        let x10 = q[6].xyz;
        let x01 = q[9].xyz;
        let x11 = q[10].xyz;
        s00 = fold(s00, x00, ring0(q, 0, 0));
        s10 = fold(s10, x10, ring0(q, 1, 0));
        s01 = fold(s01, x01, ring0(q, 0, 1));
        s11 = fold(s11, x11, ring0(q, 1, 1));
        for (var l = 1; l <= reach; l++) {
            let size = vec2<i32>(level_size(u32(l)));
            let r = ring(vec2<i32>(base) >> vec2<u32>(u32(l)), size, level_offset(u32(l)));
            s00 = fold(s00, x00, r);
            s10 = fold(s10, x10, r);
            s01 = fold(s01, x01, r);
            s11 = fold(s11, x11, r);
        }
    }
    finish(base, s00);
    finish(base + vec2<u32>(1u, 0u), s10);
    finish(base + vec2<u32>(0u, 1u), s01);
    finish(base + vec2<u32>(1u, 1u), s11);
}
