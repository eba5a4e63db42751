// The frame's point filters (classes, intensity, elevation, return number, the ranges the loader
// marked, clip boxes), shared by
// the projection and the pipelines that splat points themselves: a point hidden here is hidden
// in every pipeline. Reads `frame` (frame.wgsl).

// Whether a point at `pos` (relative to the anchor) passes the frame's filters.
fn passes_filters(pos: vec3<f32>, a: u32) -> bool {
    let f = frame.filters;
    let cls = attribute_class(a);
    let word = frame.class_mask[cls / 128u][(cls / 32u) % 4u];
    let intensity = f32(a & 0xffffu);
    // Above 15 (RETURN_ABOVE_15): past every range a return number filter takes.
    let ret = select((a >> 24u) & 0xfu, 16u, (a & RETURN_ABOVE_15) != 0u);
    let kept = ((f & FILTER_CLASSES) == 0u || (word & (1u << (cls % 32u))) != 0u)
        && ((f & FILTER_INTENSITY) == 0u || (intensity >= frame.ranges.x && intensity <= frame.ranges.y))
        && ((f & FILTER_ELEVATION) == 0u || (pos.z >= frame.ranges.z && pos.z <= frame.ranges.w))
        && ((f & FILTER_RETURN) == 0u || (ret >= frame.return_lo && ret <= frame.return_hi))
        && ((f & FILTER_MARKED) == 0u || (a & MARK_HIDDEN) == 0u);
    if !kept || (f & FILTER_CLIP) == 0u {
        return kept;
    }
    // Inside some box that keeps its inside (where there is one), and inside none that hides it.
    var keeping = false;
    var kept_inside = false;
    for (var k = 0u; k < frame.clip_count; k++) {
        let lo = frame.clip_boxes[2u * k];
        let hi = frame.clip_boxes[2u * k + 1u];
        let inside = all(pos >= lo.xyz) && all(pos <= hi.xyz);
        if lo.w > 0.5 {
            if inside {
                return false;
            }
        } else {
            keeping = true;
            kept_inside = kept_inside || inside;
        }
    }
    return !keeping || kept_inside;
}
