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
    // The c-surfel: heights a = -bend phi(rho) along the normal (it bends away from the side its
    // normal faces, as a convex surface does), its profile linear between `rings` rings, so
    // each ring is a cone frustum a = alpha + beta rho.
    if !within_slab(a0, ad, c0, cd, s.drop) {
        return miss;
    }
    var best = miss;
    let rings = f32(surf.rings);
    var phi_in = 0.0;
    for (var k = 0u; k < surf.rings; k++) {
        let rho_in = f32(k) / rings;
        let rho_out = f32(k + 1u) / rings;
        let phi_out = s.bend * surf.ring_phi[k / 4u][k % 4u];
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
            // qa k^2 + 2 hb k + qc = 0, its discriminant (over 4) written so that no two large
            // terms cancel: a flat cone's (small beta) would otherwise be lost to rounding.
            let b2 = beta * beta;
            let qa = ad * ad - b2 * dot(cd, cd);
            let hb = s0 * ad - b2 * dot(c0, cd);
            let qc = s0 * s0 - b2 * dot(c0, c0);
            let w = ad * c0 - s0 * cd;
            let x = cross(c0, cd);
            let disc = b2 * (dot(w, w) - b2 * dot(x, x));
            if abs(qa) < 1e-9 {
                if abs(hb) > 1e-12 {
                    roots.x = -0.5 * qc / hb;
                }
            } else if disc >= 0.0 {
                // The root nearer zero from qc / q, not from a difference of near equals.
                let q = -(hb + select(-1.0, 1.0, hb >= 0.0) * sqrt(disc));
                if abs(q) > 1e-30 {
                    roots = vec2<f32>(q / qa, qc / q);
                } else {
                    roots.x = -hb / qa;
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
            // On this ring, on the cone's sheet (height / beta is +u there, -u on its mirror;
            // a little slack at the apex, where they meet), in front of the eye.
            if u >= rho_in - 1e-4 && u <= rho_out + 1e-4 && height * beta >= -1e-4 * beta * beta && dist > 0.0
                && (best.x < 0.0 || dist < best.x) && inside_polygon(s, c, u) {
                best = vec2<f32>(dist, u);
            }
        }
    }
    return best;
}

// Whether the ray (heights a0 + k ad along the normal, offsets c0 + k cd in the plane, radius
// units) comes within radius 1 of the axis while between heights -drop (bend phi(1)) and 0, where
// the c-surfel lies: most rays through a grazing surfel's pixel box do not, and skip its rings.
// With a little slack, so that it never turns away a ray the rings would hit.
fn within_slab(a0: f32, ad: f32, c0: vec3<f32>, cd: vec3<f32>, drop: f32) -> bool {
    let slack = 1e-3;
    let low = -drop - slack;
    var k0 = -1e30;
    var k1 = 1e30;
    if abs(ad) > 1e-6 {
        let ka = (low - a0) / ad;
        let kb = (slack - a0) / ad;
        k0 = min(ka, kb);
        k1 = max(ka, kb);
    } else if a0 < low || a0 > slack {
        return false;
    }
    let cc = dot(cd, cd);
    var k = 0.0;
    if cc > 1e-12 {
        k = -dot(c0, cd) / cc;
    }
    let c = c0 + clamp(k, k0, k1) * cd;
    return dot(c, c) <= (1.0 + slack) * (1.0 + slack);
}
