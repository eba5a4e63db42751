// Which surfel a thread of the listing depth module draws: the point of its dispatch slot. It
// also lists the slots whose surfel is curved (in hybrid mode the few near the silhouette),
// so that the curved modules run over those alone instead of over every point again.
// [0]: the count; [1..4]: the curved modules' indirect dispatch (groups, 1, 1); then the
// slots, group * GROUP_SIZE + lane.
@group(1) @binding(5) var<storage, read_write> curved_list: array<atomic<u32>>;

fn thread_surfel(wg: vec3<u32>, groups: vec3<u32>, lane: u32) -> Surfel {
    let group = wg.x + wg.y * groups.x;
    let s = surfel_at(group, lane);
    // Curved and not made: surfel_at stopped at the kind this module does not draw.
    if !s.ok && s.curved {
        let k = atomicAdd(&curved_list[0], 1u);
        atomicStore(&curved_list[LIST_HEADER + k], group * GROUP_SIZE + lane);
        if k % GROUP_SIZE == 0u {
            atomicAdd(&curved_list[1], 1u);
        }
    }
    return s;
}
