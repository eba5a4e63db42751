// Surfels (paper 001): each drawn point becomes a planar n-gon or a curved c-surfel, oriented by
// its normal and scaled by its radius, and is ray cast per pixel of its screen box. Shared by
// the depth and the blend pass, which must agree on every surfel and every hit. Each pass is
// compiled per kind, with planar.wgsl or curved.wgsl giving `shape_hit` and `DRAWS_CURVED` (a
// module carrying the c-surfel's code runs planar surfels at half the speed on lavapipe), and
// a thread_*.wgsl choosing each thread's surfel: the depth pass thrice (planar, planar listing
// the curved, curved over that list), the blend pass twice (planar, curved over the list).

// Words before the slots in the list of curved surfels (thread_listing.wgsl).
const LIST_HEADER: u32 = 4u;

// Corners of the planar n-gon (and of each ring of the c-surfel): an override, fixed when the
// pipeline is made, so that the n-gon test's rounds are known to the compiler.
override SIDES: u32 = 6u;

// Largest screen reach of a surfel, in pixels: a thread walks its box alone.
const MAX_REACH_PX: f32 = 16.0;
const PI: f32 = 3.14159265;

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> surf: Surfels;
@group(1) @binding(0) var<storage, read> points: array<vec4<u32>>;
@group(1) @binding(1) var<storage, read> ranges: array<Range>;
@group(1) @binding(2) var<storage, read> attributes: array<u32>;
@group(1) @binding(3) var<storage, read> normals: array<u32>;
@group(1) @binding(4) var<storage, read> radii: array<f32>;

struct Surfel {
    ok: bool,
    idx: u32,
    p: vec3<f32>,
    n: vec3<f32>,
    radius: f32,
    curved: bool,
    // Distance from p that bounds the surfel, in multiples of the radius.
    bound: f32,
    // How far a c-surfel bends: its heights are -bend phi(rho) along n (0 for a planar one).
    bend: f32,
    // How far its rim drops along -n, in radii: bend phi(1).
    drop: f32,
    // Screen box: centre and reach in pixels, and the pixels it can cover (x0, y0, x1, y1).
    centre_px: vec2<f32>,
    reach_px: f32,
    box_px: vec4<f32>,
    // A basis of the surfel's plane that depends on n alone (Duff et al. 2017), for the
    // n-gon's corners.
    b1: vec3<f32>,
    b2: vec3<f32>,
    // The n-gon's apothem over its circumradius, cos(pi / SIDES).
    apothem: f32,
    // Linear depth of the centre.
    depth: f32,
    // For the planar ray cast: dot(p - eye, n), and n against the ray's three parts
    // (forward, right, up), so that a pixel costs a few multiply-adds and one division.
    plane_num: f32,
    plane_den: vec3<f32>,
}

fn phi(r: f32) -> f32 {
    let q = r * r / (surf.h * surf.h);
    return 1.0 - exp(-q * q);
}

// How far a c-surfel of stored radius `stored`, drawn `drawn` wide, bends (its heights are
// -bend phi(rho)): where the dataset gives each point's surface variation (the paper's future
// work: adapt the surfel to its neighbourhood's curvature) its rim drops as far as a sphere of
// that curvature falls away from its tangent plane there, kappa drawn / 2 radii, at most the
// paper's phi(1) (bend 1); a plane's c-surfels are flat. Else the paper's c-surfel, bend 1.
// `rim` is phi(1).
fn curvature_bend(stored: f32, drawn: f32, colour: u32, rim: f32) -> f32 {
    if surf.curvature <= 0.0 || stored <= 0.0 {
        return 1.0;
    }
    // kappa stored = curvature sqrt(variation share), the share in the colour's alpha byte.
    let kappa_stored = surf.curvature * sqrt(f32(colour >> 24u) / 255.0);
    return min(0.5 * kappa_stored * drawn / stored / rim, 1.0);
}

// The surfel of this thread's point, or one with ok = false (no point, filtered, off screen,
// or the other kind's: then with `curved` as that kind has it).
fn surfel_at(group: u32, lane: u32) -> Surfel {
    var s: Surfel;
    s.ok = false;
    if ranges[0].count == 0u {
        return s;
    }
    let r = ranges[range_of(group)];
    let local = (group - r.first_group) * GROUP_SIZE + lane;
    if group < r.first_group || local >= r.count {
        return s;
    }
    let idx = r.start + local;
    let p = bitcast<vec3<f32>>(points[idx].xyz);
    if frame.filters != 0u && !passes_filters(p, attributes[idx]) {
        return s;
    }
    let to_eye = surf.eye.xyz - p;
    let v = normalize(to_eye);
    s.radius = drawn_radius(r, p, radii[idx]);
    let word = normals[idx];
    if surf.normals != NORMALS_NONE && word != 0u {
        // Pointing out of its surface (the facing check's sign): a c-surfel bends away from it.
        s.n = decode_oct16(word) * normal_sign();
        if surf.normals == NORMALS_FACING_EYE && dot(s.n, v) < 0.0 {
            s.n = -s.n;
        }
        let grazing = abs(dot(s.n, v)) <= surf.sin_epsilon;
        s.curved = surf.mode == MODE_CURVED || (surf.mode == MODE_HYBRID && grazing);
    } else {
        s.n = v;
        s.curved = false;
    }
    let clip = frame.view_proj * vec4<f32>(p, 1.0);
    if s.curved {
        let rim = phi(1.0);
        s.bend = curvature_bend(radii[idx], s.radius, points[idx].w, rim);
        s.drop = s.bend * rim;
        // A c-surfel whose rim drops no further than `flat_px` off its plane on the screen is
        // drawn planar, at a planar one's cost: a flat one (a plane's) always.
        let drop_px = s.drop * s.radius * frame.focal_px / max(clip.w - s.radius, 1e-30);
        s.curved = clip.w <= s.radius || drop_px > surf.flat_px;
    }
    // Each module draws one kind (DRAWS_CURVED) and leaves the other's surfels unmade, with
    // `curved` set where they are curved: the planar depth pass lists those for the curved
    // modules (thread_listing.wgsl).
    if s.curved != DRAWS_CURVED {
        return s;
    }
    s.bend = select(0.0, s.bend, s.curved);
    s.drop = select(0.0, s.drop, s.curved);
    s.bound = sqrt(1.0 + s.drop * s.drop);
    let reach = s.bound * s.radius;
    // Nearer than the near plane or beyond the far one: not drawn, as the projection drops
    // them.
    if !in_depth_range(clip, frame.near, frame.far) {
        return s;
    }
    let ndc = clip.xy / clip.w;
    s.centre_px = vec2<f32>((ndc.x * 0.5 + 0.5) * f32(frame.width), (0.5 - ndc.y * 0.5) * f32(frame.height));
    // A surfel that reaches behind the eye (the eye close to a large one) has no bounded
    // image: it takes the largest box, and each pixel's ray finds where it meets it.
    s.reach_px = select(MAX_REACH_PX, min(reach * frame.focal_px / (clip.w - reach), MAX_REACH_PX), clip.w > reach);
    let size = vec2<f32>(f32(frame.width), f32(frame.height));
    if any(s.centre_px + s.reach_px < vec2<f32>(0.0)) || any(s.centre_px - s.reach_px > size) {
        return s;
    }
    set_shape(&s);
    s.plane_num = dot(p - surf.eye.xyz, s.n);
    s.plane_den = vec3<f32>(dot(surf.forward.xyz, s.n), dot(surf.right.xyz, s.n), dot(surf.up.xyz, s.n));
    s.depth = clip.w;
    s.idx = idx;
    s.p = p;
    s.box_px = screen_box(s);
    s.ok = true;
    return s;
}

// The n-gon's basis and apothem, from the normal and SIDES.
fn set_shape(s: ptr<function, Surfel>) {
    let n = (*s).n;
    let sgn = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (sgn + n.z);
    let b = n.x * n.y * a;
    (*s).b1 = vec3<f32>(1.0 + sgn * n.x * n.x * a, sgn * b, -sgn * n.x);
    (*s).b2 = vec3<f32>(b, sgn + n.y * n.y * a, -n.y);
    (*s).apothem = cos(PI / f32(SIDES));
}

// The screen box of the surfel's bounding box (its square of the plane, and for a c-surfel the
// slab it bends into, down to -drop along the normal) within the square of its reach: a
// grazing surfel, seen edge-on, covers a thin band of that square.
fn screen_box(s: Surfel) -> vec4<f32> {
    let square = vec4<f32>(s.centre_px - s.reach_px, s.centre_px + s.reach_px);
    var lo = vec2<f32>(1e30);
    var hi = vec2<f32>(-1e30);
    // A planar surfel's box is flat: its four corners.
    let corners = select(4u, 8u, s.drop > 0.0);
    for (var k = 0u; k < corners; k++) {
        let u = select(-1.0, 1.0, (k & 1u) != 0u);
        let v = select(-1.0, 1.0, (k & 2u) != 0u);
        let a = select(0.0, -s.drop, (k & 4u) != 0u);
        let corner = s.p + s.radius * (u * s.b1 + v * s.b2 + a * s.n);
        let clip = frame.view_proj * vec4<f32>(corner, 1.0);
        // A corner behind the eye has no place on the screen: the square bounds it.
        if clip.w <= 1e-6 {
            return square;
        }
        let ndc = clip.xy / clip.w;
        let px = vec2<f32>((ndc.x * 0.5 + 0.5) * f32(frame.width), (0.5 - ndc.y * 0.5) * f32(frame.height));
        lo = min(lo, px);
        hi = max(hi, px);
    }
    return vec4<f32>(max(lo, square.xy), min(hi, square.zw));
}

// Where the surfel covers pixel (x, y): x its linear depth, y the squared radial distance in
// radius units; x < 0 where it does not. A surfel within half a pixel of its centre covers its
// centre's pixel alone, as a point does: its shape is below what the pixel can show.
fn hit_pixel(s: Surfel, x: u32, y: u32) -> vec2<f32> {
    let miss = vec2<f32>(-1.0, 0.0);
    let d = vec2<f32>(f32(x) + 0.5, f32(y) + 0.5) - s.centre_px;
    if s.reach_px < 0.5 {
        return vec2<f32>(s.depth, 0.0);
    }
    // The box's corners lie beyond the reach.
    let r = s.reach_px + 0.71;
    if dot(d, d) > r * r {
        return miss;
    }
    let ndc = vec2<f32>(
        (f32(x) + 0.5) / f32(frame.width) * 2.0 - 1.0,
        1.0 - (f32(y) + 0.5) / f32(frame.height) * 2.0,
    );
    let dir = surf.forward.xyz + ndc.x * surf.right.xyz + ndc.y * surf.up.xyz;
    return shape_hit(s, ndc, dir);
}

// The pixel box a thread walks: x0, y0, x1, y1 (inclusive).
fn pixel_box(s: Surfel) -> vec4<u32> {
    if s.reach_px < 0.5 {
        let size = vec2<f32>(f32(frame.width), f32(frame.height));
        if any(s.centre_px < vec2<f32>(0.0)) || any(s.centre_px >= size) {
            // Empty.
            return vec4<u32>(1u, 1u, 0u, 0u);
        }
        let c = vec2<u32>(floor(s.centre_px));
        return vec4<u32>(c, c);
    }
    return vec4<u32>(
        u32(max(floor(s.box_px.x), 0.0)),
        u32(max(floor(s.box_px.y), 0.0)),
        u32(clamp(s.box_px.z, 0.0, f32(frame.width - 1u))),
        u32(clamp(s.box_px.w, 0.0, f32(frame.height - 1u))),
    );
}

// Whether a point of the surfel's plane at offset c (radius units) from its centre, at
// distance u, lies inside its n-gon (corners at angles 2k pi / SIDES, paper section 3.2).
// With off the angle between c and the nearest edge's normal, it does where u cos(off) <=
// apothem: |off| >= acos(apothem / u). Both sides times SIDES lie in [0, pi], where cos
// falls, so: where cos(SIDES off) <= cos(SIDES acos(apothem / u)) = T(apothem / u), T the
// Chebyshev polynomial of degree SIDES. No angle is taken: atan2 and cos for every pixel of
// every surfel were a fifth of the surfel passes on lavapipe.
fn inside_polygon(s: Surfel, c: vec3<f32>, u: f32) -> bool {
    if u > 1.0 {
        return false;
    }
    if u <= s.apothem {
        return true;
    }
    // T(cos theta) = cos(SIDES theta), theta the angle of c from b1; the corners lie at theta
    // = 2k pi / SIDES - pi, so cos(SIDES off) = -(-1)^SIDES cos(SIDES theta).
    let t = chebyshev_sides(vec2<f32>(dot(c, s.b1) / u, s.apothem / u));
    let parity = select(-1.0, 1.0, (SIDES & 1u) != 0u);
    return parity * t.x <= t.y;
}

// The Chebyshev polynomial of degree SIDES at both of x (in [-1, 1]), by its recurrence.
fn chebyshev_sides(x: vec2<f32>) -> vec2<f32> {
    var previous = vec2<f32>(1.0);
    var t = x;
    for (var k = 1u; k < SIDES; k++) {
        let next = 2.0 * x * t - previous;
        previous = t;
        t = next;
    }
    return t;
}

// The paper's alpha texture, exp(-(distance from the texture centre)^2 / d^2) with the rim at
// texture distance 1/2, of the squared radial distance u2 in radius units.
fn surfel_weight(u2: f32) -> f32 {
    return exp(-0.25 * u2 / (surf.falloff * surf.falloff));
}
