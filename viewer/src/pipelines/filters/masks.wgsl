// The 3x3 masks of the hole filling (section 3.2), shared by the layers' fill and the light
// map's.

// The eight neighbours, row by row: TL T TR / L R / BL B BR.
const OFFSETS = array<vec2<i32>, 8>(
    vec2<i32>(-1, -1), vec2<i32>(0, -1), vec2<i32>(1, -1),
    vec2<i32>(-1, 0), vec2<i32>(1, 0),
    vec2<i32>(-1, 1), vec2<i32>(0, 1), vec2<i32>(1, 1),
);

// The eight masks of Figure 3 as bit sets over OFFSETS: a full row or column on one side and
// one of the two cells beside the centre next to it. Beyond a straight outline, and beside a
// pixel sticking out of one, some mask is all background, so iterating does not grow the
// silhouette (half-plane masks of five cells let it grow by a pixel an iteration along every
// protrusion); inside a hole up to three pixels across none is once its corners are filled,
// and it closes. The edge of a wider hole matches a mask as an outline does: the background
// fill closes those with `enclosed` (fill.wgsl) where the sampling's width is known.
const MASKS = array<u32, 8>(
    0x0fu,  // top row and L
    0x17u,  // top row and R
    0xe8u,  // bottom row and L
    0xf0u,  // bottom row and R
    0x2bu,  // left column and T
    0x69u,  // left column and B
    0x96u,  // right column and T
    0xd4u,  // right column and B
);

// Whether some mask has all its cells in `white`.
fn some_mask_white(white: u32) -> bool {
    for (var m = 0; m < 8; m++) {
        if (white & MASKS[m]) == MASKS[m] {
            return true;
        }
    }
    return false;
}
