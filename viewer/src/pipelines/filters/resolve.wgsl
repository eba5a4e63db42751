// A layer's texels from its depth and index planes or its 64-bit keys (resolve_planes.wgsl or
// resolve_keys.wgsl gives `pixel_key`), once per arena: each pixel whose point lives in this
// arena takes that point's colour, opacity (by its class), normal (turned to face the eye) and
// share of the light, and the reach of its sampling. Marks the layer, and the pixel's fill tile,
// as holding one.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(4) var<storage, read_write> texels: array<Texel>;
@group(0) @binding(5) var<storage, read_write> counters: array<u32>;
// The fill's tile flags (`occupied_slot`).
@group(0) @binding(6) var<storage, read_write> tiles: array<u32>;
@group(1) @binding(0) var<storage, read> points: array<vec4<u32>>;
@group(1) @binding(1) var<storage, read> ranges: array<Range>;
@group(1) @binding(2) var<storage, read> attributes: array<u32>;
@group(1) @binding(3) var<storage, read> normals: array<u32>;
// Per point: the light samples that reached it (shadow.wgsl).
@group(1) @binding(4) var<storage, read> lit: array<f32>;
// Per point: its stored radius (the Radius stream; zeros where the dataset has none).
@group(1) @binding(5) var<storage, read> radii: array<f32>;
@group(2) @binding(0) var<uniform> step: Step;

// The widest hole, in pixels, the sampling around point `local` at linear depth `depth` can
// leave: discs of the radius it is drawn with cover its surface (SPEC.md section 4), so no
// empty disc between its samples is wider than two radii. A hole wider than that is one in the
// data, or beyond the silhouette of a scan's scattered outline, and the fill leaves it open.
// Without a stored radius no width is known (a leaf's spacing says nothing of the points it
// holds): the paper's fill, as far as the iterations go.
fn sampling_reach(local: u32, pos: vec3<f32>, depth: f32) -> u32 {
    let stored = radii[local];
    if stored <= 0.0 {
        return MAX_REACH_PX;
    }
    let radius = drawn_radius(ranges[range_holding(local)], pos, stored);
    let px = 2.0 * radius * frame.focal_px / max(depth, 1e-30);
    return u32(clamp(floor(px), 0.0, f32(MAX_REACH_PX)));
}

fn point_opacity(a: u32) -> f32 {
    let c = attribute_class(a);
    if c >= CLASSES {
        return fil.opacity;
    }
    return fil.opacity * fil.class_opacity[c / 4u][c % 4u];
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let i = id.y * frame.width + id.x;
    let key = pixel_key(i);
    let depth = key.x;
    let g = key.y;
    if depth == EMPTY || (g >> frame.arena_shift) != ranges[0].start {
        return;
    }
    let local = g & ((1u << frame.arena_shift) - 1u);
    let p = points[local];
    let a = attributes[local];
    let rgb = point_colour(p, a);
    var share = 1.0;
    if fil.lit_scale > 0.0 {
        share = lit[local] * fil.lit_scale;
    }
    let pos = bitcast<vec3<f32>>(p.xyz);
    let reach = sampling_reach(local, pos, bitcast<f32>(depth));
    var t = Texel(depth, pack4x8unorm(vec4<f32>(rgb, point_opacity(a))), 0u, with_lit(with_reach(0u, reach), share));
    let w = normals[local];
    if fil.normals != 0u && w != 0u {
        var n = decode_oct16(w);
        if dot(n, fil.eye.xyz - pos) < 0.0 {
            n = -n;
        }
        t.z = encode_oct16(n);
        t.w |= 1u;
    }
    texels[i] = t;
    counters[step.layer] = 1u;
    tiles[occupied_slot(id.xy / 16u)] = 1u;
}
