// Deferred shading of the reconstructed surface: background where the HPR found visible
// background, else the filled colour lit by the headlight (or a light fixed in the world, with
// the shadows' lit share) with the normal interpolated between
// the two pyramid levels nearest the pixel's normal radius, or the coarser level the frame's
// depth noise calls for (bilinear within each level); with `stored_normals`, the dataset's
// normals the pull-push carried, at the level their own noise calls for. EDL may darken it on top. Writes the
// output image and the per-pixel surface for readback.

fn pixel_depth(i: u32) -> u32 {
    if labels[i] == LABEL_BACKGROUND || fill[i].y < 1.0 {
        return EMPTY;
    }
    return bitcast<u32>(fill[i].x);
}

fn level_normal(l: u32, px: vec2<f32>) -> vec3<f32> {
    let size = vec2<i32>(level_size(l));
    let off = level_offset(l);
    let u = px / f32(1u << l) - 0.5;
    let base = vec2<i32>(floor(u));
    let t = u - vec2<f32>(base);
    var n = vec3<f32>(0.0);
    for (var dy = 0; dy < 2; dy++) {
        for (var dx = 0; dx < 2; dx++) {
            let c = clamp(base + vec2<i32>(dx, dy), vec2<i32>(0), size - 1);
            let e = normals[off + u32(c.y * size.x + c.x)];
            if e != NO_NORMAL {
                let b = select(1.0 - t.x, t.x, dx == 1) * select(1.0 - t.y, t.y, dy == 1);
                n += decode_normal(e) * b;
            }
        }
    }
    return n;
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let i = id.y * frame.width + id.x;
    let d = pixel_depth(i);
    if d == EMPTY {
        textureStore(output, vec2<i32>(id.xy), unpack4x8unorm(frame.background));
        surface[i] = vec2<u32>(EMPTY, NO_NORMAL);
        return;
    }
    let depth = bitcast<f32>(d);
    let px = vec2<f32>(id.xy) + 0.5;
    let p = view_point(px, depth);
    let v = normalize(-p);
    let top = f32(pyr.levels - 1u);
    // The level of the normal radius, or coarser where the depth noise needs more averaging.
    // Stored normals need no radius, only as much averaging as their own noise calls for.
    let spacing_level = log2(max(pyr.normal_scale / depth, 1e-6));
    let noise_level = 0.5 * log2(max(pyr.noise_scale / depth, 1e-12));
    var lambda = clamp(max(spacing_level, noise_level), 0.0, top);
    if pyr.stored_normals != 0u {
        lambda = clamp(pyr.stored_level, 0.0, top);
    }
    let l0 = u32(floor(lambda));
    let l1 = min(l0 + 1u, pyr.levels - 1u);
    var n = mix(level_normal(l0, px), level_normal(l1, px), lambda - f32(l0));
    // No measured surface around at that scale: take the nearest finer level that has one.
    for (var l = i32(l0) - 1; l >= 0 && !(length(n) > 1e-6); l--) {
        n = level_normal(u32(l), px);
    }
    if !(length(n) > 1e-6) {
        n = v;
    }
    n = normalize(n);
    let filled = unpack4x8unorm(fill_colour[i]);
    var rgb = headlight(filled.rgb, n, v);
    if pyr.light.w != 0.0 {
        // A light fixed in the world, or shadows: Blinn-Phong with the share of the light the
        // pull-push carried in the colour's alpha, the normal turned to face the eye (for the
        // lighting only: the surface read back keeps the pyramid's own).
        let facing = select(n, -n, dot(n, v) < 0.0);
        let l = select(v, pyr.light.xyz, dot(pyr.light.xyz, pyr.light.xyz) > 0.0);
        rgb = phong(filled.rgb, facing, v, l, filled.a);
    }
    rgb *= edl_factor(id.xy, d);
    textureStore(output, vec2<i32>(id.xy), vec4<f32>(clamp(rgb, vec3<f32>(0.0), vec3<f32>(1.0)), 1.0));
    surface[i] = vec2<u32>(d, encode_normal(n));
}
