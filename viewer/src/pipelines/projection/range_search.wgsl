// The range a point workgroup draws: the last row of the module's `ranges` whose first group is
// not after `group` (row 0 is the header: start = arena, count = rows that follow; at least
// one). Shared by the passes that walk the drawn ranges a thread per point.
fn range_of(group: u32) -> u32 {
    var lo = 1u;
    var hi = ranges[0].count;
    while lo < hi {
        let mid = (lo + hi + 1u) / 2u;
        if ranges[mid].first_group <= group {
            lo = mid;
        } else {
            hi = mid - 1u;
        }
    }
    return lo;
}
