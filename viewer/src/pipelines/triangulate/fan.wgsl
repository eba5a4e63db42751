// A point's fan (sections 3.4 and 3.5): its sector neighbours in circular order, and the
// triangles between consecutive ones whose opening angle seen from the point is below pi.
// The fan is walked sector by sector, never gathered into an array: on lavapipe a per-thread
// array indexed by a number that varies between threads costs a memory round trip per thread
// for every access.

// Words per sector in the neighbour buffer: 1 for the two-pass search's ids, 2 where the
// 64-bit search's keys are read in place (the id's complement is the low word of the key's,
// and an empty sector's key is 0), so that no pass copies them out.
override NEIGHBOUR_STRIDE: u32 = 1u;

// Step `s` (0 to SECTORS) of the walk round pixel p's fan: the neighbour in sector s, as its
// pixel id's complement (0: the sector is empty); after the last sector the first neighbour
// again, closing the fan, where the walk met at least two (`first` and `previous`: the first
// and the latest neighbour met, 0 where none).
fn fan_step(p: u32, s: u32, first: u32, previous: u32) -> u32 {
    if s < SECTORS {
        return neighbours[(p * SECTORS + s) * NEIGHBOUR_STRIDE];
    }
    return select(0u, first, previous != first);
}

// The screen offset of pixel `q` from pixel `p`, y down.
fn offset_px(p: u32, q: u32) -> vec2<f32> {
    let a = vec2<f32>(f32(p % frame.width), f32(p / frame.width));
    let b = vec2<f32>(f32(q % frame.width), f32(q / frame.width));
    return b - a;
}

// Whether the fan's triangle from neighbour a to the next one, b, is drawn: its opening angle
// is below pi counter-clockwise on screen from a to b.
fn opens(p: u32, a: u32, b: u32) -> bool {
    let oa = offset_px(p, a);
    let ob = offset_px(p, b);
    // Counter-clockwise on screen with y down: a negative cross product of (a, b).
    return oa.x * ob.y - oa.y * ob.x < 0.0;
}
