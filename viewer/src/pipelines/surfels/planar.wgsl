// The planar surfels' variant of the depth and blend passes: n-gons ray cast by their plane.

const DRAWS_CURVED: bool = false;

// Where the ray through `ndc` (direction `dir`, its parameter linear depth) meets the n-gon:
// x the depth, y the squared radial distance in radius units; x < 0 where it misses.
fn shape_hit(s: Surfel, ndc: vec2<f32>, dir: vec3<f32>) -> vec2<f32> {
    let miss = vec2<f32>(-1.0, 0.0);
    // The plane: depth t where (eye + t dir - p) . n = 0.
    let den = s.plane_den.x + ndc.x * s.plane_den.y + ndc.y * s.plane_den.z;
    if abs(den) < 1e-12 {
        return miss;
    }
    let t = s.plane_num / den;
    let c = (surf.eye.xyz - s.p + t * dir) / s.radius;
    let u2 = dot(c, c);
    if t <= 0.0 || u2 > 1.0 || (u2 > s.apothem * s.apothem && !inside_polygon(s, c, sqrt(u2))) {
        return miss;
    }
    return vec2<f32>(t, u2);
}
