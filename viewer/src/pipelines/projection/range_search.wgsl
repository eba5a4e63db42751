// The last row of the module's `ranges` whose first group (or, `by_start`, whose start) is not
// after `key` (row 0 is the header: start = arena, count = rows that follow; at least one).
// The rows of an arena are in the order of both (`range_table`).
fn last_row_not_after(key: u32, by_start: bool) -> u32 {
    var lo = 1u;
    var hi = ranges[0].count;
    while lo < hi {
        let mid = lo + (hi - lo + 1u) / 2u;
        if select(ranges[mid].first_group, ranges[mid].start, by_start) <= key {
            lo = mid;
        } else {
            hi = mid - 1u;
        }
    }
    return lo;
}

// The range a point workgroup draws. Shared by the passes that walk the drawn ranges a thread
// per point.
fn range_of(group: u32) -> u32 {
    return last_row_not_after(group, false);
}

// The range that holds point `local` of the arena (its index in the arena's buffers).
fn range_holding(local: u32) -> u32 {
    return last_row_not_after(local, true);
}
