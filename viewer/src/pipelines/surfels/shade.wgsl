// Normalisation and shading (paper section 3.2): c = sum c_i w_i / sum w_i per pixel, the
// normal likewise, lit by the shared headlight; the blended surface kept for the harness.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> surf: Surfels;
@group(0) @binding(2) var<storage, read> planes: array<u32>;
@group(0) @binding(3) var<storage, read> sums: array<u32>;
// View-space normal (x right, y up, z towards the eye) and linear depth; w < 0: background.
@group(0) @binding(4) var<storage, read_write> surface: array<vec4<f32>>;
// Unlit colour, alpha 0 on background.
@group(0) @binding(5) var<storage, read_write> albedo: array<u32>;
@group(0) @binding(6) var output: texture_storage_2d<rgba8unorm, write>;

// A pixel's blend sums, and the depth they blend.
struct Blend {
    w: f32,
    // Sums of w * colour and w * (normal / 2 + 1/2).
    rgb: vec3<f32>,
    normal: vec3<f32>,
    depth: f32,
    // The w of back faces, and the depth of the blended layer (the least depth plus z_o,
    // less the least depth: at most the z_o of the surfel nearest the eye).
    back: f32,
    offset: f32,
}

fn empty_blend() -> Blend {
    return Blend(0.0, vec3<f32>(0.0), vec3<f32>(0.0), 0.0, 0.0, 0.0);
}

fn blend_at(p: u32) -> Blend {
    let i = SUM_WORDS * p;
    let w = f32(sums[i]);
    var b = Blend(w, vec3<f32>(f32(sums[i + 1u]), f32(sums[i + 2u]), f32(sums[i + 3u])),
        vec3<f32>(f32(sums[i + 4u]), f32(sums[i + 5u]), f32(sums[i + 6u])), 0.0,
        f32(sums[i + 8u]), 0.0);
    if w > 0.0 {
        let front = bitcast<f32>(~planes[PLANE_WORDS * p]);
        let nearest = bitcast<f32>(~planes[PLANE_WORDS * p + 1u]);
        b.depth = nearest + (front - nearest) * f32(sums[i + 7u]) / w;
        b.offset = front - nearest;
    }
    return b;
}

// The sum of two blends, their depths weighted by their w.
fn add_blends(a: Blend, b: Blend) -> Blend {
    var s = Blend(a.w + b.w, a.rgb + b.rgb, a.normal + b.normal, 0.0, a.back + b.back, 0.0);
    s.depth = (a.depth * a.w + b.depth * b.w) / max(s.w, 1e-30);
    return s;
}

// Pixels searched each way for the near surface about a pinhole.
const FAR_REACH: i32 = 2;

// The first pixel from `id` along `step` that is mostly front faces, where it lies in front
// of `depth` by more than twice its z_o; empty where the search meets background, the
// border, or front faces about as deep (the same surface, its normals leaning), which
// `enclosed` looks past instead (the hole's own pixels).
fn near_side_towards(id: vec2<u32>, step: vec2<i32>, depth: f32, enclosed: bool) -> Blend {
    for (var k = 1; k <= FAR_REACH; k++) {
        let q = vec2<i32>(id) + step * k;
        if q.x < 0 || q.y < 0 || q.x >= i32(frame.width) || q.y >= i32(frame.height) {
            break;
        }
        let p = u32(q.y) * frame.width + u32(q.x);
        let i = SUM_WORDS * p;
        let w = f32(sums[i]);
        if w <= 0.0 {
            break;
        }
        if surf.back_faces != 0u && 2.0 * f32(sums[i + 8u]) > w {
            continue;
        }
        // Its blend lies no nearer than its nearest surfel, z_o (front - nearest) before its
        // front: where even that is not far enough in front, its whole blend (eleven words)
        // is not read. Every pixel of a surface searches, and most stop here.
        let front = bitcast<f32>(~planes[PLANE_WORDS * p]);
        let nearest = bitcast<f32>(~planes[PLANE_WORDS * p + 1u]);
        if depth - nearest <= 2.0 * (front - nearest) {
            if enclosed {
                continue;
            }
            // Front faces about as deep as a back face: the near side of a shell thinner than
            // z_o, whose far side shows through a gap its surfels left.
            return blend_at(p);
        }
        let n = blend_at(p);
        if depth - n.depth > 2.0 * n.offset {
            return n;
        }
        if enclosed {
            continue;
        }
        break;
    }
    return empty_blend();
}

// The far side of a closed surface seen through a pinhole of the near one, which the depth
// pass let win, takes the blend of the near pixels about it. A pixel drawn mostly by back
// faces is one where the near surface lies in front of it on two opposite sides, in any of
// the four directions. A pixel that is not (a layer behind a sparse near surface faces the
// eye, and normals pointing either way, or none, mark no back face) is one only where the
// near surface lies in front of it in all four directions across it, looking past pixels of
// its own surface within reach: a hole, not a slit, which shows the surface behind rightly.
// A back face with nothing in front about it (a thin plate seen from behind, the inside of
// an open object) stays. `enclosed`: the rule for pixels that are not back faces.
fn near_side(id: vec2<u32>, depth: f32, enclosed: bool) -> Blend {
    var b = empty_blend();
    let steps = array<vec2<i32>, 4>(vec2<i32>(1, 0), vec2<i32>(0, 1), vec2<i32>(1, 1), vec2<i32>(1, -1));
    for (var d = 0; d < 4; d++) {
        let ahead = near_side_towards(id, steps[d], depth, enclosed);
        if ahead.w > 0.0 {
            let behind = near_side_towards(id, -steps[d], depth, enclosed);
            if behind.w > 0.0 {
                b = add_blends(b, add_blends(ahead, behind));
                continue;
            }
        }
        if enclosed {
            return empty_blend();
        }
    }
    return b;
}

// A pixel's blend, or where it is the far side seen through a pinhole, the near side's.
fn seen_at(id: vec2<u32>) -> Blend {
    var b = blend_at(id.y * frame.width + id.x);
    if b.w > 0.0 {
        let near = near_side(id, b.depth, 2.0 * b.back <= b.w);
        if near.w > 0.0 {
            b = near;
        }
    }
    return b;
}

// An empty pixel between two drawn ones, left and right or above and below, is a crack: the
// radius rule (SPEC.md, `r_k sqrt(ln 100 / k)`) leaves about 1 % of a randomly sampled
// surface uncovered, mostly in such one-pixel gaps, and widening every surfel to close them
// costs far more. It takes the blend of the pairs about it that are drawn; any other empty
// pixel stays empty (w 0).
fn crack(id: vec2<u32>) -> Blend {
    var b = empty_blend();
    if id.x == 0u || id.y == 0u || id.x + 1u >= frame.width || id.y + 1u >= frame.height {
        return b;
    }
    let around = array<vec2<u32>, 4>(id - vec2<u32>(1u, 0u), id + vec2<u32>(1u, 0u),
        id - vec2<u32>(0u, 1u), id + vec2<u32>(0u, 1u));
    var covered = array<bool, 4>(false, false, false, false);
    for (var k = 0; k < 4; k++) {
        covered[k] = sums[SUM_WORDS * (around[k].y * frame.width + around[k].x)] != 0u;
    }
    let across = covered[0] && covered[1];
    let along = covered[2] && covered[3];
    if !across && !along {
        return b;
    }
    for (var k = 0; k < 4; k++) {
        if (k < 2 && !across) || (k >= 2 && !along) {
            continue;
        }
        b = add_blends(b, seen_at(around[k]));
    }
    return b;
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let p = id.y * frame.width + id.x;
    var b = seen_at(id.xy);
    if b.w <= 0.0 {
        b = crack(id.xy);
    }
    if b.w <= 0.0 {
        surface[p] = vec4<f32>(0.0, 0.0, 0.0, -1.0);
        albedo[p] = 0u;
        textureStore(output, id.xy, unpack4x8unorm(frame.background));
        return;
    }
    let rgb = b.rgb / b.w;
    let blended = b.normal / b.w * 2.0 - 1.0;
    let depth = b.depth;
    let dir = surf.forward.xyz + ((f32(id.x) + 0.5) / f32(frame.width) * 2.0 - 1.0) * surf.right.xyz
        + (1.0 - (f32(id.y) + 0.5) / f32(frame.height) * 2.0) * surf.up.xyz;
    let to_eye = -normalize(dir);
    var n = to_eye;
    if dot(blended, blended) > 1e-8 {
        n = normalize(blended);
    }
    var colour = rgb;
    if surf.normals != NORMALS_NONE {
        colour = headlight(rgb, n, to_eye);
    }
    let right = normalize(surf.right.xyz);
    let up = normalize(surf.up.xyz);
    surface[p] = vec4<f32>(dot(n, right), dot(n, up), -dot(n, surf.forward.xyz), depth);
    albedo[p] = pack4x8unorm(vec4<f32>(rgb, 1.0));
    textureStore(output, id.xy, vec4<f32>(clamp(colour, vec3<f32>(0.0), vec3<f32>(1.0)), 1.0));
}
