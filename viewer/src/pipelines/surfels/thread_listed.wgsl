// Which surfel a thread of a curved module draws: one of the slots the planar depth pass
// listed (thread_listing.wgsl), dispatched indirectly, one thread a listed slot.
@group(1) @binding(5) var<storage, read> curved_list: array<u32>;

fn thread_surfel(wg: vec3<u32>, groups: vec3<u32>, lane: u32) -> Surfel {
    let k = wg.x * GROUP_SIZE + lane;
    if k >= curved_list[0] {
        var none: Surfel;
        none.ok = false;
        return none;
    }
    let slot = curved_list[LIST_HEADER + k];
    return surfel_at(slot / GROUP_SIZE, slot % GROUP_SIZE);
}
