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
}

fn blend_at(p: u32) -> Blend {
    let i = SUM_WORDS * p;
    let w = f32(sums[i]);
    var b = Blend(w, vec3<f32>(f32(sums[i + 1u]), f32(sums[i + 2u]), f32(sums[i + 3u])),
        vec3<f32>(f32(sums[i + 4u]), f32(sums[i + 5u]), f32(sums[i + 6u])), 0.0);
    if w > 0.0 {
        let front = bitcast<f32>(~planes[2u * p]);
        let nearest = bitcast<f32>(~planes[2u * p + 1u]);
        b.depth = nearest + (front - nearest) * f32(sums[i + 7u]) / w;
    }
    return b;
}

// An empty pixel between two drawn ones, left and right or above and below, is a crack: the
// radius rule (SPEC.md, `r_k sqrt(ln 100 / k)`) leaves about 1 % of a randomly sampled
// surface uncovered, mostly in such one-pixel gaps, and widening every surfel to close them
// costs far more. It takes the blend of the pairs about it that are drawn; any other empty
// pixel stays empty (w 0).
fn crack(id: vec2<u32>) -> Blend {
    var b = Blend(0.0, vec3<f32>(0.0), vec3<f32>(0.0), 0.0);
    if id.x == 0u || id.y == 0u || id.x + 1u >= frame.width || id.y + 1u >= frame.height {
        return b;
    }
    let p = id.y * frame.width + id.x;
    let around = array<u32, 4>(p - 1u, p + 1u, p - frame.width, p + frame.width);
    var covered = array<bool, 4>(false, false, false, false);
    for (var k = 0; k < 4; k++) {
        covered[k] = sums[SUM_WORDS * around[k]] != 0u;
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
        let n = blend_at(around[k]);
        b.w += n.w;
        b.rgb += n.rgb;
        b.normal += n.normal;
        b.depth += n.depth * n.w;
    }
    b.depth /= b.w;
    return b;
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let p = id.y * frame.width + id.x;
    var b = blend_at(p);
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
