// The node spacing of a point of this arena: `ranges` holds the drawn ranges sorted by start
// after the header row (start = arena, count = rows), so the last row starting at or before
// the point's index holds it.
fn spacing_of(local: u32) -> f32 {
    var lo = 1u;
    var hi = ranges[0].count;
    while lo < hi {
        let mid = (lo + hi + 1u) / 2u;
        if ranges[mid].start <= local {
            lo = mid;
        } else {
            hi = mid - 1u;
        }
    }
    return ranges[lo].spacing;
}
