// Smoothing (section 3.4): the alleviated Gaussian, centre 16/28, edges 2/28, corners 1/28, over
// the non-background pixels, renormalised over the neighbours it takes. Beyond the paper it
// takes only neighbours within d~ of the centre's depth, so that a front surface does not
// bleed into the one behind it. Colour, opacity, normal and the light's share are smoothed;
// depth is kept. Taken by the shade as it reads each texel, where a pass of its own wrote every
// texel out and read it back (a full-screen pass, on lavapipe a tenth of the frame).

// Texel `t`, at `q` of the filled `texels`, smoothed; background stays background.
fn smoothed(q: vec2<i32>, t: Texel) -> Texel {
    if t.x == 0u {
        return t;
    }
    let d = bitcast<f32>(t.x);
    var colour = vec4<f32>(0.0);
    var weight = 0.0;
    var normal = vec3<f32>(0.0);
    var lit = 0.0;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let o = q + vec2<i32>(dx, dy);
            if o.x < 0 || o.y < 0 || o.x >= i32(frame.width) || o.y >= i32(frame.height) {
                continue;
            }
            let n = texels[u32(o.y) * frame.width + u32(o.x)];
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
    return out;
}
