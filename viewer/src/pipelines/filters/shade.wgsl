// A layer's smoothing, shading, anti-aliasing and blending (sections 3.4, 3.5 and 5): each
// filled texel smoothed as it is read (smooth.wgsl), lit by the shared light with its smoothed
// normal (or one estimated from the filled depth where the points carry none); edge pixels
// found by the Laplace filter on depth blended with their neighbours, a silhouette's
// background share taken off the pixel's coverage; then blended front to back under the layers
// before it, and the image so far written out. The first layer also leaves its surface and
// unlit colour for the quality harness.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(2) var<storage, read> texels: array<Texel>;
@group(0) @binding(3) var<storage, read_write> accum: array<vec4<f32>>;
// View-space normal (x right, y up, z towards the eye) and linear depth; w < 0: background.
@group(0) @binding(4) var<storage, read_write> surface: array<vec4<f32>>;
// Unlit colour, alpha 0 on background.
@group(0) @binding(5) var<storage, read_write> albedo: array<u32>;
@group(0) @binding(6) var output: texture_storage_2d<rgba8unorm, write>;
@group(1) @binding(0) var<uniform> step: Step;

// The pass's mode, fixed when its pipeline is made (`ShadeVariant`): a compiled pass holds
// only its own mode's code.
const ANTIALIAS_OFF: u32 = 0u;
const ANTIALIAS_SILHOUETTES: u32 = 1u;
const ANTIALIAS_EDGES: u32 = 2u;
// ANTIALIAS_*: which edges the Laplace filter smooths.
override ANTIALIAS: u32 = ANTIALIAS_SILHOUETTES;
// The points carry no normals: estimate them from the filled depth. Else a texel without one
// (a point given none) faces the eye.
override ESTIMATE_NORMALS: bool = false;
// Blinn-Phong from `fil.light` with the texel's lit share; else the headlight.
override PHONG: bool = false;

// The ray through pixel position `px`, scaled so that linear depth d along it lies at eye + d * ray.
fn pixel_ray(px: vec2<f32>) -> vec3<f32> {
    let ndc = vec2<f32>(px.x / f32(frame.width) * 2.0 - 1.0, 1.0 - px.y / f32(frame.height) * 2.0);
    return fil.forward.xyz + ndc.x * fil.right.xyz + ndc.y * fil.up.xyz;
}

fn texel_at(q: vec2<i32>) -> Texel {
    if q.x < 0 || q.y < 0 || q.x >= i32(frame.width) || q.y >= i32(frame.height) {
        return Texel(0u, 0u, 0u, 0u);
    }
    return texels[u32(q.y) * frame.width + u32(q.x)];
}

fn position_at(q: vec2<i32>, depth: f32) -> vec3<f32> {
    return fil.eye.xyz + depth * pixel_ray(vec2<f32>(q) + 0.5);
}

// The difference of positions across `q` along `axis`, from the neighbours on the same layer
// (within d~ of each other): central where both are there, else one-sided.
fn tangent(q: vec2<i32>, d: f32, axis: vec2<i32>) -> vec3<f32> {
    let a = texel_at(q - axis);
    let b = texel_at(q + axis);
    let da = bitcast<f32>(a.x);
    let db = bitcast<f32>(b.x);
    let here = position_at(q, d);
    let use_a = a.x != 0u && abs(da - d) <= fil.dtilde * 4.0;
    let use_b = b.x != 0u && abs(db - d) <= fil.dtilde * 4.0;
    var lo = here;
    var hi = here;
    if use_a {
        lo = position_at(q - axis, da);
    }
    if use_b {
        hi = position_at(q + axis, db);
    }
    return hi - lo;
}

// The unit normal of texel `t` at `q`, facing the eye.
fn normal_of(t: Texel, q: vec2<i32>, to_eye: vec3<f32>) -> vec3<f32> {
    var n = to_eye;
    if (t.w & 1u) != 0u {
        n = decode_oct16(t.z);
    } else if ESTIMATE_NORMALS {
        let d = bitcast<f32>(t.x);
        let c = cross(tangent(q, d, vec2<i32>(1, 0)), tangent(q, d, vec2<i32>(0, 1)));
        if dot(c, c) > 1e-20 {
            n = normalize(c);
        }
    }
    return select(n, -n, dot(n, to_eye) < 0.0);
}

fn eye_dir(q: vec2<i32>) -> vec3<f32> {
    return -normalize(pixel_ray(vec2<f32>(q) + 0.5));
}

// Texel `t` at `q` lit, its normal `n` and the unit direction to the eye given.
fn lit_colour(t: Texel, n: vec3<f32>, to_eye: vec3<f32>) -> vec3<f32> {
    let rgb = unpack4x8unorm(t.y).rgb;
    if !PHONG {
        return headlight(rgb, n, to_eye);
    }
    // Section 6: c = k_a + m (k_d + k_s), m the share of the light that reaches the point.
    let l = select(to_eye, fil.light.xyz, fil.light.w != 0.0);
    return phong(rgb, n, to_eye, l, texel_lit(t));
}

const AXES = array<vec2<i32>, 4>(vec2<i32>(1, 0), vec2<i32>(-1, 0), vec2<i32>(0, 1), vec2<i32>(0, -1));

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let i = id.y * frame.width + id.x;
    let q = vec2<i32>(id.xy);
    let t = smoothed(q, texels[i]);
    // The first layer starts the blend (and writes every pixel of it); later ones add to it.
    var sum = vec4<f32>(0.0);
    if step.layer > 0u {
        sum = accum[i];
    }
    // The normal, for the surface the first layer leaves; background pixels need none.
    var n = vec3<f32>(0.0);
    if t.x != 0u {
        let to_eye = eye_dir(q);
        n = normal_of(t, q, to_eye);
        let d = bitcast<f32>(t.x);
        var colour = lit_colour(t, n, to_eye);
        var alpha = unpack4x8unorm(t.y).a;
        if ANTIALIAS != ANTIALIAS_OFF {
            // Laplace on depth, background at depth 0 (section 3.5).
            var laplace = 4.0 * d;
            var silhouette = false;
            for (var k = 0; k < 4; k++) {
                let depth = texel_at(q + AXES[k]).x;
                laplace -= bitcast<f32>(depth);
                silhouette = silhouette || depth == 0u;
            }
            if abs(laplace) > fil.dtilde && (ANTIALIAS == ANTIALIAS_EDGES || silhouette) {
                var around = vec3<f32>(0.0);
                var covered = 0.0;
                for (var k = 0; k < 4; k++) {
                    let o = q + AXES[k];
                    let u = texel_at(o);
                    if u.x != 0u {
                        let s = smoothed(o, u);
                        let u_eye = eye_dir(o);
                        around += lit_colour(s, normal_of(s, o, u_eye), u_eye);
                        covered += 1.0;
                    }
                }
                colour = 0.5 * colour + 0.5 * around / max(covered, 1.0) * (covered / 4.0);
                let coverage = 0.5 + 0.5 * covered / 4.0;
                colour /= coverage;
                alpha *= coverage;
            }
        }
        sum += vec4<f32>(colour * alpha, alpha) * (1.0 - sum.a);
    }
    if t.x != 0u || step.layer == 0u {
        accum[i] = sum;
    }
    if step.layer == 0u {
        if t.x == 0u {
            surface[i] = vec4<f32>(0.0, 0.0, 0.0, -1.0);
            albedo[i] = 0u;
        } else {
            let right = normalize(fil.right.xyz);
            let up = normalize(fil.up.xyz);
            surface[i] = vec4<f32>(dot(n, right), dot(n, up), -dot(n, fil.forward.xyz), bitcast<f32>(t.x));
            albedo[i] = pack4x8unorm(vec4<f32>(unpack4x8unorm(t.y).rgb, 1.0));
        }
    }
    let background = unpack4x8unorm(frame.background).rgb;
    textureStore(output, id.xy, vec4<f32>(clamp(sum.rgb + (1.0 - sum.a) * background, vec3<f32>(0.0), vec3<f32>(1.0)), 1.0));
}
