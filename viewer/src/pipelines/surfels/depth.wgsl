// Visibility, first pass (paper section 3.3): every surfel writes its depth pushed back by
// z_o, and its own depth, as minima; one facing the eye also its depth in a plane of its own
// (`PLANE_WORDS`). Planes hold the complement of the depth bits, so that a cleared (zero)
// plane is empty and atomicMax keeps the nearest.
@group(0) @binding(2) var<storage, read_write> planes: array<atomic<u32>>;
// Surfels drawn this frame: planar, curved.
@group(0) @binding(3) var<storage, read_write> counts: array<atomic<u32>, 2>;

@compute @workgroup_size(256)
fn main(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    let s = thread_surfel(wg, groups, lane);
    // Not ok as well where the surfel is the other kind's, which the other module draws.
    if !s.ok {
        return;
    }
    atomicAdd(&counts[select(0u, 1u, s.curved)], 1u);
    let facing = dot(s.n, s.p - surf.eye.xyz) <= 0.0;
    let offset = surf.depth_offset * s.radius;
    let b = pixel_box(s);
    let pixels = box_pixels(b);
    var next = b.xy;
    for (var k = 0u; k < pixels; k++) {
        let x = next.x;
        let y = next.y;
        next = box_next(b, next);
        let hit = hit_pixel(s, x, y);
        if hit.x < 0.0 {
            continue;
        }
        let i = PLANE_WORDS * (y * frame.width + x);
        atomicMax(&planes[i], ~bitcast<u32>(hit.x + offset));
        atomicMax(&planes[i + 1u], ~bitcast<u32>(hit.x));
        if facing {
            atomicMax(&planes[i + 2u], ~bitcast<u32>(hit.x));
        }
    }
}
