// A layer's texels from its depth and index planes or its 64-bit keys (resolve_planes.wgsl or
// resolve_keys.wgsl gives `pixel_key`), once per arena: each pixel whose point lives in this
// arena takes that point's colour, opacity (by its class), normal (turned to face the eye) and
// share of the light. Marks the layer, and the pixel's fill tile, as holding one.
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
@group(2) @binding(0) var<uniform> step: Step;

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
    var t = Texel(depth, pack4x8unorm(vec4<f32>(rgb, point_opacity(a))), 0u, with_lit(0u, share));
    let w = normals[local];
    if fil.normals != 0u && w != 0u {
        var n = decode_oct16(w);
        if dot(n, fil.eye.xyz - bitcast<vec3<f32>>(p.xyz)) < 0.0 {
            n = -n;
        }
        t.z = encode_oct16(n);
        t.w |= 1u;
    }
    texels[i] = t;
    counters[step.layer] = 1u;
    tiles[occupied_slot(id.xy / 16u)] = 1u;
}
