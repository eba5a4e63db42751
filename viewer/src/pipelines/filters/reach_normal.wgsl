// How far behind the previous layer a point still belongs to it: d~ measured along the normal,
// so d~ / |cos| along the view ray, the factor truncated at MAX_REACH (section 6's offset,
// used for the transparency layers too: at grazing angles one surface spans many times d~ in
// depth within a pixel, and would otherwise come back as a layer of its own). Reads the
// Normals stream that cull.wgsl binds.
const MAX_REACH: f32 = 4.0;

fn layer_reach(index: u32) -> f32 {
    let local = index & ((1u << frame.arena_shift) - 1u);
    let w = normals[local];
    if w == 0u {
        return fil.dtilde;
    }
    let p = bitcast<vec3<f32>>(points[local].xyz);
    let cosine = abs(dot(decode_oct16(w), normalize(frame.eye.xyz - p)));
    return fil.dtilde * min(1.0 / max(cosine, 1e-6), MAX_REACH);
}
