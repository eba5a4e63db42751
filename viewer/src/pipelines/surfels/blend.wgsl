// Visibility, second pass, and blending (paper sections 3.2 and 3.3): every surfel hit within
// z_o of the front surface adds its colour, normal and depth weighted by its alpha texture.
// Sums are fixed point, so that the image does not depend on the order threads run in.
@group(0) @binding(2) var<storage, read> planes: array<u32>;
// Per pixel: w, then w * (r, g, b), w * (normal / 2 + 1/2), w * (where in the blended layer),
// and the w of surfels whose normal was turned away from the eye (back faces).
@group(0) @binding(3) var<storage, read_write> sums: array<atomic<u32>>;

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
    let rgb = point_colour(points[s.idx], attributes[s.idx]);
    // Normals blended as seen: each turned towards the eye first. Which were turned is kept
    // apart where that marks a back face, for the shade to tell a closed surface's far side.
    let turned = dot(s.n, s.p - surf.eye.xyz) > 0.0;
    let back = turned && surf.back_faces != 0u;
    let n = select(s.n, -s.n, turned);
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
        let depth = hit.x;
        let p = y * frame.width + x;
        let front = bitcast<f32>(~planes[PLANE_WORDS * p]);
        if depth > front {
            continue;
        }
        // A back face behind a surfel facing the eye is the far side of a shell thinner than
        // z_o: its colour would tint the near side (an open cup's inner wall through its
        // outer one). A back face with nothing facing the eye in front of it stays.
        let facing_front = planes[PLANE_WORDS * p + 2u];
        if back && facing_front != 0u && bitcast<f32>(~facing_front) <= depth {
            continue;
        }
        let nearest = bitcast<f32>(~planes[PLANE_WORDS * p + 1u]);
        let layer = clamp((depth - nearest) / max(front - nearest, 1e-30), 0.0, 1.0);
        // At least one unit: every pixel the depth pass covered is covered here too.
        let w = max(surfel_weight(hit.y) * WEIGHT_ONE, 1.0);
        let i = SUM_WORDS * p;
        atomicAdd(&sums[i], u32(w + 0.5));
        atomicAdd(&sums[i + 1u], u32(w * rgb.r + 0.5));
        atomicAdd(&sums[i + 2u], u32(w * rgb.g + 0.5));
        atomicAdd(&sums[i + 3u], u32(w * rgb.b + 0.5));
        atomicAdd(&sums[i + 4u], u32(w * (0.5 * n.x + 0.5) + 0.5));
        atomicAdd(&sums[i + 5u], u32(w * (0.5 * n.y + 0.5) + 0.5));
        atomicAdd(&sums[i + 6u], u32(w * (0.5 * n.z + 0.5) + 0.5));
        atomicAdd(&sums[i + 7u], u32(w * layer + 0.5));
        if back {
            atomicAdd(&sums[i + 8u], u32(w + 0.5));
        }
    }
}
