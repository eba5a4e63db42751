// The hole rate of the reconstruction: an empty pixel is a hole where covered pixels lie within
// HOLE_REACH on its left, its right, above and below it (inside the silhouette); the rate is
// holes over holes and covered pixels.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> reconstructed: array<u32>;
@group(0) @binding(2) var<storage, read_write> counts: array<atomic<u32>>;

// Also the height of the dispatch's tiles (passes.rs: 16 x 16 pixels a workgroup), and the
// width of the bit windows below: the three are one number.
const HOLE_REACH: i32 = 16;

fn covered(x: i32, y: i32) -> bool {
    if x < 0 || y < 0 || x >= i32(frame.width) || y >= i32(frame.height) {
        return false;
    }
    return reconstructed[u32(y) * frame.width + u32(x)] != EMPTY;
}

fn reaches(x: i32, y: i32, dx: i32, dy: i32) -> bool {
    for (var k = 1; k <= HOLE_REACH; k++) {
        if covered(x + k * dx, y + k * dy) {
            return true;
        }
    }
    return false;
}

// Which of the HOLE_REACH (16) pixels of column x from row y0 down are covered, as bits.
fn column_bits(x: i32, y0: i32) -> u32 {
    var bits = 0u;
    for (var k = 0; k < HOLE_REACH; k++) {
        bits |= select(0u, 1u << u32(k), covered(x, y0 + k));
    }
    return bits;
}

// Each thread counts a column of a 16 x 16 tile (workgroups of 16 threads over the same tiles a
// pixel-sized dispatch gives), from the covered bits of that column and of the 16 pixels above
// and below it: a pixel's reach up and down is then a test of 16 bits, and only the empty pixels
// covered both ways are scanned along their row. Most empty pixels lie outside the silhouette,
// and scanning every one of them along its row first took most of the pass. A thread adds its
// counts with one atomic each: a workgroup barrier to sum them first cost more on lavapipe.
@compute @workgroup_size(16, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(workgroup_id) wg: vec3<u32>) {
    if id.x >= frame.width {
        return;
    }
    let x = i32(id.x);
    let y0 = i32(wg.y) * HOLE_REACH;
    let above = column_bits(x, y0 - HOLE_REACH);
    let here = column_bits(x, y0);
    let below = column_bits(x, y0 + HOLE_REACH);
    // Bit j + 16 of `up` is row y0 + j (j from -16), bit j of `down` row y0 + j (j from 0).
    let up = above | (here << 16u);
    let down = here | (below << 16u);
    var holes = 0u;
    for (var k = 0u; k < u32(HOLE_REACH); k++) {
        if (here & (1u << k)) != 0u {
            continue;
        }
        let y = y0 + i32(k);
        // Rows y - 16 .. y - 1, and y + 1 .. y + 16.
        if y < i32(frame.height) && ((up >> k) & 0xffffu) != 0u && ((down >> (k + 1u)) & 0xffffu) != 0u
            && reaches(x, y, -1, 0) && reaches(x, y, 1, 0) {
            holes += 1u;
        }
    }
    if holes > 0u {
        atomicAdd(&counts[COUNT_HOLES], holes);
    }
    let covered_here = countOneBits(here);
    if covered_here > 0u {
        atomicAdd(&counts[COUNT_COVERED], covered_here);
    }
}
