// HPR, one invocation a 4x4 block of pixels: the shape for CPU adapters (see `HprShape`).
// Each neighbour is read and unprojected once for sixteen pixels. From level 2 up the block lies
// in one cell and shares its coarse depth, its `reach` and its ring; on level 1 it covers 2x2
// cells whose rings lie in 4x4 cells; on level 0 its rings lie in 6x6 cells. That is
// 36 + 16 + 8 (reach - 1) reads a block against 128 (reach + 1) one pixel an invocation. The
// block's pixels are written out row by row, never looped over: lavapipe kept looped-over arrays
// in memory, and the pass took over twice as long. On lavapipe 2x2 blocks took 1.4-1.7x as long
// as 4x4, and a workgroup tile in shared memory was slower still. The cells are held in
// function variables and passed by pointer: passed by value and indexed with a variable, each
// access copied the whole array, and NVIDIA's driver (580, H200) never finished compiling that
// module (by pointer it takes 1.7 s; the pixel shape 80 ms).

// One row of the block: its four pixels' sectors, left to right.
alias Row = array<Sectors, 4>;

// Level 0's 6x6 cells around the block, by rows, from the cell left of and above it.
alias Cells0 = array<array<vec4<f32>, 6>, 6>;
// Level 1's 4x4 cells around the block's 2x2 cells, by rows.
alias Cells1 = array<array<vec4<f32>, 4>, 4>;

// The ring, in sector order, of cell (a + 1, b + 1) of `q`: the level-0 ring of block pixel
// (a, b).
fn ring0(q: ptr<function, Cells0>, a: i32, b: i32) -> array<vec4<f32>, 8> {
    return array<vec4<f32>, 8>(
        q[b + 1][a + 2], q[b + 2][a + 2], q[b + 2][a + 1], q[b + 2][a],
        q[b + 1][a], q[b][a], q[b][a + 1], q[b][a + 2],
    );
}

// As ring0 on level 1's cells (WGSL has no generics): the ring of the block's level-1 cell
// (a, b).
fn ring1(q: ptr<function, Cells1>, a: i32, b: i32) -> array<vec4<f32>, 8> {
    return array<vec4<f32>, 8>(
        q[b + 1][a + 2], q[b + 2][a + 2], q[b + 2][a + 1], q[b + 2][a],
        q[b + 1][a], q[b][a], q[b][a + 1], q[b][a + 2],
    );
}

// Six cells of a level in a row from `p`.
fn cells6(p: vec2<i32>, size: vec2<i32>, off: u32) -> array<vec4<f32>, 6> {
    return array<vec4<f32>, 6>(
        neighbour(p, size, off),
        neighbour(p + vec2<i32>(1, 0), size, off),
        neighbour(p + vec2<i32>(2, 0), size, off),
        neighbour(p + vec2<i32>(3, 0), size, off),
        neighbour(p + vec2<i32>(4, 0), size, off),
        neighbour(p + vec2<i32>(5, 0), size, off),
    );
}

// As cells6, four cells.
fn cells4(p: vec2<i32>, size: vec2<i32>, off: u32) -> array<vec4<f32>, 4> {
    return array<vec4<f32>, 4>(
        neighbour(p, size, off),
        neighbour(p + vec2<i32>(1, 0), size, off),
        neighbour(p + vec2<i32>(2, 0), size, off),
        neighbour(p + vec2<i32>(3, 0), size, off),
    );
}

// The points of row `b` of the block.
fn points(q: ptr<function, Cells0>, b: i32) -> array<vec3<f32>, 4> {
    return array<vec3<f32>, 4>(q[b + 1][1].xyz, q[b + 1][2].xyz, q[b + 1][3].xyz, q[b + 1][4].xyz);
}

fn fold_row0(s: Row, x: array<vec3<f32>, 4>, q: ptr<function, Cells0>, b: i32) -> Row {
    return Row(
        fold(s[0], x[0], ring0(q, 0, b)),
        fold(s[1], x[1], ring0(q, 1, b)),
        fold(s[2], x[2], ring0(q, 2, b)),
        fold(s[3], x[3], ring0(q, 3, b)),
    );
}

fn fold_row1(s: Row, x: array<vec3<f32>, 4>, q: ptr<function, Cells1>, b: i32) -> Row {
    return Row(
        fold(s[0], x[0], ring1(q, 0, b / 2)),
        fold(s[1], x[1], ring1(q, 0, b / 2)),
        fold(s[2], x[2], ring1(q, 1, b / 2)),
        fold(s[3], x[3], ring1(q, 1, b / 2)),
    );
}

// Folds a ring the whole row shares (levels 2 and up).
fn fold_row(s: Row, x: array<vec3<f32>, 4>, r: array<vec4<f32>, 8>) -> Row {
    return Row(fold(s[0], x[0], r), fold(s[1], x[1], r), fold(s[2], x[2], r), fold(s[3], x[3], r));
}

// Labels the four pixels of row `b` of the block at `base`: `s` their sectors up to the point
// reach, `g` up to the background reach.
fn finish_row(base: vec2<u32>, b: u32, s: Row, g: Row) {
    finish(base + vec2<u32>(0u, b), s[0], g[0]);
    finish(base + vec2<u32>(1u, b), s[1], g[1]);
    finish(base + vec2<u32>(2u, b), s[2], g[2]);
    finish(base + vec2<u32>(3u, b), s[3], g[3]);
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let base = id.xy * 4u;
    if base.x >= frame.width || base.y >= frame.height {
        return;
    }
    // From level 2 up the block lies in one cell of the coarse level: one reach for all.
    let reaches = reach_at(base);
    let reach = reaches.point;
    let background = reaches.background;
    // The ring of every level up to `reach` lies inside the cells at `reach` around the block's
    // (3x3, or 4x4 at level 1).
    let lo = (vec2<i32>(base) >> vec2<u32>(u32(reach))) - 1;
    let hi = ((vec2<i32>(base) + 3) >> vec2<u32>(u32(reach))) + 1;
    let nearest = nearest_in(u32(reach), lo, hi);
    let open = Sectors(vec4<f32>(1.0), vec4<f32>(1.0));
    var s0 = Row(open, open, open, open);
    var s1 = s0;
    var s2 = s0;
    var s3 = s0;
    // The rows' sectors up to the background reach (the block shares it, as it shares `reach`).
    var g0 = s0;
    var g1 = s0;
    var g2 = s0;
    var g3 = s0;
    if nearest < bitcast<u32>(pyr.far) {
        let size0 = vec2<i32>(level_size(0u));
        let corner0 = vec2<i32>(base) - 1;
        var q0 = Cells0(
            cells6(corner0, size0, 0u),
            cells6(corner0 + vec2<i32>(0, 1), size0, 0u),
            cells6(corner0 + vec2<i32>(0, 2), size0, 0u),
            cells6(corner0 + vec2<i32>(0, 3), size0, 0u),
            cells6(corner0 + vec2<i32>(0, 4), size0, 0u),
            cells6(corner0 + vec2<i32>(0, 5), size0, 0u),
        );
        let x0 = points(&q0, 0);
        let x1 = points(&q0, 1);
        let x2 = points(&q0, 2);
        let x3 = points(&q0, 3);
        s0 = fold_row0(s0, x0, &q0, 0);
        s1 = fold_row0(s1, x1, &q0, 1);
        s2 = fold_row0(s2, x2, &q0, 2);
        s3 = fold_row0(s3, x3, &q0, 3);
        if background == 0 {
            g0 = s0;
            g1 = s1;
            g2 = s2;
            g3 = s3;
        }
        let size1 = vec2<i32>(level_size(1u));
        let corner1 = vec2<i32>(base >> vec2<u32>(1u)) - 1;
        let off1 = level_offset(1u);
        var q1 = Cells1(
            cells4(corner1, size1, off1),
            cells4(corner1 + vec2<i32>(0, 1), size1, off1),
            cells4(corner1 + vec2<i32>(0, 2), size1, off1),
            cells4(corner1 + vec2<i32>(0, 3), size1, off1),
        );
        s0 = fold_row1(s0, x0, &q1, 0);
        s1 = fold_row1(s1, x1, &q1, 1);
        s2 = fold_row1(s2, x2, &q1, 2);
        s3 = fold_row1(s3, x3, &q1, 3);
        if background == 1 {
            g0 = s0;
            g1 = s1;
            g2 = s2;
            g3 = s3;
        }
        for (var l = 2; l <= reach; l++) {
            let size = vec2<i32>(level_size(u32(l)));
            let r = ring(vec2<i32>(base >> vec2<u32>(u32(l))), size, level_offset(u32(l)));
            s0 = fold_row(s0, x0, r);
            s1 = fold_row(s1, x1, r);
            s2 = fold_row(s2, x2, r);
            s3 = fold_row(s3, x3, r);
            if background == l {
                g0 = s0;
                g1 = s1;
                g2 = s2;
                g3 = s3;
            }
        }
    }
    finish_row(base, 0u, s0, g0);
    finish_row(base, 1u, s1, g1);
    finish_row(base, 2u, s2, g2);
    finish_row(base, 3u, s3, g3);
}

