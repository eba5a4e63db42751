// Back-face culling by the point normal (paper 004, section 3.1), for pipelines that ask for it
// on datasets whose normals face outwards: a point whose normal turns away from the eye is not
// drawn. A point without a normal (0) is always drawn.
@group(1) @binding(3) var<storage, read> normals: array<u32>;

fn culled(idx: u32, pos: vec3<f32>) -> bool {
    let w = normals[idx];
    return w != 0u && dot(decode_oct16(w), frame.eye.xyz - pos) < 0.0;
}
