// Normalisation and shading: colour and normal are the sums over the fragments divided by
// their weight, lit by the shared headlight; the depth is the least. The reconstructed depth
// plane is what the next frame reprojects; the surface and the albedo are kept for the harness.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> tri: Triangulate;
// Bindings 2 and 7, the blend sums of the front and the back faces: shade_sums32.wgsl or
// shade_sums64.wgsl, with blend_at.
@group(0) @binding(3) var<storage, read> front: array<u32>;
// Linear depth bits per pixel, EMPTY on background.
@group(0) @binding(4) var<storage, read_write> reconstructed: array<u32>;
// View-space normal (x right, y up, z towards the eye) and linear depth; w < 0: background.
@group(0) @binding(5) var<storage, read_write> surface: array<vec4<f32>>;
// Unlit colour, alpha 0 on background.
@group(0) @binding(6) var<storage, read_write> albedo: array<u32>;
@group(0) @binding(8) var output: texture_storage_2d<rgba8unorm, write>;

// Whether something is drawn beside pixel `c`: left, right, above, below.
fn drawn_beside(c: vec2<u32>) -> vec4<bool> {
    let i = c.y * frame.width + c.x;
    return vec4<bool>(
        c.x > 0u && front[i - 1u] != 0u,
        c.x + 1u < frame.width && front[i + 1u] != 0u,
        c.y > 0u && front[i - frame.width] != 0u,
        c.y + 1u < frame.height && front[i + frame.width] != 0u,
    );
}

// What a pixel shows: the sums of its colour, normal (as blend_at gives them) and depth over
// `weight` pixels (1, or the four about a pinhole); weight 0: nothing.
struct Drawn {
    weight: f32,
    colour: vec3<f32>,
    normal: vec3<f32>,
    depth: f32,
}

// A pixel shows the back faces' blend (SIDES) only where no front face's fragment fell.
fn drawn_at(p: u32) -> Drawn {
    var blend = blend_at(p, false);
    if SIDES && blend.fragments == 0u {
        blend = blend_at(p, true);
    }
    if blend.fragments == 0u || front[p] == 0u {
        return Drawn(0.0, vec3<f32>(0.0), vec3<f32>(0.0), 0.0);
    }
    return Drawn(1.0, blend.colour, blend.normal, bitcast<f32>(~front[p]));
}

// An empty pixel whose four neighbours are all drawn is a pinhole the fans left (a triangle
// skipped for its opening angle, a radius that has not yet grown): it takes their mean, so
// that the next frame's reprojected depth has no hole there either. Any other empty pixel
// stays empty (weight 0). Closing the cracks between two drawn pixels as well, as surfels
// does, gained more on sparse scenes but also filled one-pixel gaps in outlines (quality:
// the bunny scans' albedo SSIM 0.888 -> 0.887, two planes' PSNR 33.4 -> 32.8 dB).
fn pinhole(c: vec2<u32>) -> Drawn {
    var d = Drawn(0.0, vec3<f32>(0.0), vec3<f32>(0.0), 0.0);
    if !all(drawn_beside(c)) {
        return d;
    }
    let p = c.y * frame.width + c.x;
    let around = array<u32, 4>(p - 1u, p + 1u, p - frame.width, p + frame.width);
    for (var k = 0; k < 4; k++) {
        let n = drawn_at(around[k]);
        d.weight += n.weight;
        d.colour += n.colour;
        d.normal += n.normal;
        d.depth += n.depth;
    }
    return d;
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let p = id.y * frame.width + id.x;
    var drawn = drawn_at(p);
    if drawn.weight == 0.0 {
        drawn = pinhole(id.xy);
    }
    if drawn.weight == 0.0 {
        reconstructed[p] = EMPTY;
        surface[p] = vec4<f32>(0.0, 0.0, 0.0, -1.0);
        albedo[p] = 0u;
        textureStore(output, id.xy, unpack4x8unorm(frame.background));
        return;
    }
    let rgb = drawn.colour / drawn.weight;
    let blended = drawn.normal / drawn.weight * 2.0 - 1.0;
    let depth = drawn.depth / drawn.weight;
    let nx = (f32(id.x) + 0.5) / f32(frame.width) * 2.0 - 1.0;
    let ny = 1.0 - (f32(id.y) + 0.5) / f32(frame.height) * 2.0;
    let to_eye = -normalize(tri.forward.xyz + nx * tri.right.xyz + ny * tri.up.xyz);
    var n = to_eye;
    // Fragments without a normal add the middle of the range, which reads back as a zero
    // vector up to the sums' rounding (at most about 2.4e-4 on each axis).
    if dot(blended, blended) > 1e-6 {
        n = normalize(blended);
    } else {
        // Only points whose fans open no triangle drew here (each covers its own pixel,
        // adding no normal). Such a point has its neighbours on one side: it lies on an
        // outline, where the surface turns edge-on, its normal across the view and away from
        // the pixels drawn beside it (across the view all the same where they surround it).
        // The eye's direction would light it as if it faced the viewer, a bright speck; it
        // stays where nothing is drawn beside the pixel (a point alone, nothing to say where
        // the surface turns). On lavapipe every pixel pays for this branch (about 8 ms of 300
        // on the 1 M city).
        let beside = drawn_beside(id.xy);
        let away = vec2<f32>(f32(beside.x) - f32(beside.y), f32(beside.w) - f32(beside.z));
        var across = away.x * normalize(tri.right.xyz) + away.y * normalize(tri.up.xyz);
        if dot(away, away) < 1.0 {
            across = tri.up.xyz;
        }
        let edge_on = across - dot(across, to_eye) * to_eye;
        if any(beside) && dot(edge_on, edge_on) > 1e-12 {
            n = normalize(edge_on);
        }
    }
    let colour = headlight(rgb, n, to_eye);
    let right = normalize(tri.right.xyz);
    let up = normalize(tri.up.xyz);
    reconstructed[p] = bitcast<u32>(depth);
    surface[p] = vec4<f32>(dot(n, right), dot(n, up), -dot(n, normalize(tri.forward.xyz)), depth);
    albedo[p] = pack4x8unorm(vec4<f32>(rgb, 1.0));
    textureStore(output, id.xy, vec4<f32>(clamp(colour, vec3<f32>(0.0), vec3<f32>(1.0)), 1.0));
}
