// Which surfel a thread of a planar module that lists nothing draws (the blend pass, and the
// depth pass where no surfel can be curved): the point of its dispatch slot.
fn thread_surfel(wg: vec3<u32>, groups: vec3<u32>, lane: u32) -> Surfel {
    return surfel_at(wg.x + wg.y * groups.x, lane);
}
