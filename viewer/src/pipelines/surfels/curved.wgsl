// The curved surfels' variant of the depth and blend passes: c-surfels, their mesh of rings
// ray cast as cone frusta.

const DRAWS_CURVED: bool = true;

// Where the ray through `ndc` (direction `dir`, its parameter linear depth) meets the
// c-surfel: x the depth, y the squared radial distance in radius units; x < 0 where it misses.
fn shape_hit(s: Surfel, ndc: vec2<f32>, dir: vec3<f32>) -> vec2<f32> {
    let len = length(dir);
    let hit = intersect(s, dir / len);
    return vec2<f32>(hit.x / len, hit.y * hit.y);
}

// Where the ray (unit direction e, from the eye) first meets the surfel: x the distance
// along e, y the radial distance u in radius units; x < 0 where it misses. Solved around the
// ray's closest approach to the centre, so that every quantity is of the surfel's size.
fn intersect(s: Surfel, e: vec3<f32>) -> vec2<f32> {
    let miss = vec2<f32>(-1.0, 0.0);
    let tc = dot(s.p - surf.eye.xyz, e);
    let o = (surf.eye.xyz + tc * e - s.p) / s.radius;
    if dot(o, o) > s.bound * s.bound {
        return miss;
    }
    let a0 = dot(o, s.n);
    let ad = dot(e, s.n);
    let c0 = o - a0 * s.n;
    let cd = e - ad * s.n;
    if !s.curved {
        if abs(ad) < 1e-6 {
            return miss;
        }
        let k = -a0 / ad;
        let c = c0 + k * cd;
        let u = length(c);
        let dist = tc + k * s.radius;
        if dist > 0.0 && inside_polygon(s, c, u) {
            return vec2<f32>(dist, u);
        }
        return miss;
    }
    // The c-surfel: heights a = -phi(rho) along the normal (it bends away from the side its
    // normal faces, as a convex surface does), its profile linear between `rings` rings, so
    // each ring is a cone frustum a = alpha + beta rho.
    var best = miss;
    let rings = f32(surf.rings);
    var phi_in = 0.0;
    for (var k = 0u; k < surf.rings; k++) {
        let rho_in = f32(k) / rings;
        let rho_out = f32(k + 1u) / rings;
        let phi_out = phi(rho_out);
        let beta = -(phi_out - phi_in) * rings;
        let alpha = -phi_in - beta * rho_in;
        phi_in = phi_out;
        let s0 = a0 - alpha;
        var roots = vec2<f32>(-1e30);
        if abs(beta) < 1e-6 {
            if abs(ad) >= 1e-6 {
                roots.x = -s0 / ad;
            }
        } else {
            let b2 = beta * beta;
            let qa = ad * ad - b2 * dot(cd, cd);
            let qb = 2.0 * (s0 * ad - b2 * dot(c0, cd));
            let qc = s0 * s0 - b2 * dot(c0, c0);
            if abs(qa) < 1e-9 {
                if abs(qb) > 1e-12 {
                    roots.x = -qc / qb;
                }
            } else {
                let disc = qb * qb - 4.0 * qa * qc;
                if disc >= 0.0 {
                    let sq = sqrt(disc);
                    roots = vec2<f32>((-qb - sq) / (2.0 * qa), (-qb + sq) / (2.0 * qa));
                }
            }
        }
        for (var j = 0u; j < 2u; j++) {
            let kk = roots[j];
            if kk <= -1e29 {
                continue;
            }
            let c = c0 + kk * cd;
            let u = length(c);
            let height = s0 + kk * ad;
            let dist = tc + kk * s.radius;
            // On this ring, on the cone's sheet (not its mirror), in front of the eye.
            if u >= rho_in - 1e-4 && u <= rho_out + 1e-4 && height * beta >= -1e-5 && dist > 0.0
                && (best.x < 0.0 || dist < best.x) && inside_polygon(s, c, u) {
                best = vec2<f32>(dist, u);
            }
        }
    }
    return best;
}

