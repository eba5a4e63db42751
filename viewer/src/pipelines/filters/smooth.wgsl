// Smoothing (section 3.4): the alleviated Gaussian, centre 16/28, edges 2/28, corners 1/28, over
// the non-background pixels, renormalised over the neighbours it takes. Beyond the paper it
// takes only neighbours within d~ of the centre's depth, so that a front surface does not
// bleed into the one behind it. Colour, opacity, normal and the light's share are smoothed;
// depth is kept.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(2) var<storage, read> src: array<Texel>;
@group(0) @binding(3) var<storage, read_write> dst: array<Texel>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let i = id.y * frame.width + id.x;
    let t = src[i];
    if t.x == 0u {
        dst[i] = t;
        return;
    }
    let d = bitcast<f32>(t.x);
    var colour = vec4<f32>(0.0);
    var weight = 0.0;
    var normal = vec3<f32>(0.0);
    var lit = 0.0;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let q = vec2<i32>(id.xy) + vec2<i32>(dx, dy);
            if q.x < 0 || q.y < 0 || q.x >= i32(frame.width) || q.y >= i32(frame.height) {
                continue;
            }
            let n = src[u32(q.y) * frame.width + u32(q.x)];
            if n.x == 0u || abs(bitcast<f32>(n.x) - d) > fil.dtilde {
                continue;
            }
            var w = 16.0;
            if dx != 0 || dy != 0 {
                w = select(1.0, 2.0, dx == 0 || dy == 0);
            }
            colour += w * unpack4x8unorm(n.y);
            lit += w * texel_lit(n);
            weight += w;
            if (n.w & 1u) != 0u {
                normal += w * decode_oct16(n.z);
            }
        }
    }
    var out = t;
    out.y = pack4x8unorm(colour / weight);
    out.w = with_lit(t.w, lit / weight);
    if (t.w & 1u) != 0u && dot(normal, normal) > 1e-12 {
        out.z = encode_oct16(normalize(normal));
    }
    dst[i] = out;
}
