// Back-face culling by the point normal (paper 004, section 3.1), for pipelines that ask for it
// on datasets whose normals face outwards: a point whose normal turns away from the eye is not
// drawn (its normal turned first where the facing check found them pointing inwards). A point
// without a normal (0) is always drawn.
@group(1) @binding(3) var<storage, read> normals: array<u32>;

// Normals are estimates: one fitted across an edge (PCA over neighbours on both faces), or a
// mesh's normals interpolated around a sharp corner, leans up to 45-55° off its face, and a
// point of a visible face then seems to turn away; culled, a strip along every such edge is
// left open, wider than the fill closes. So the opaque surface culls a point only where it
// turns away by more than this margin (the sine of the angle past grazing); the back side's
// points it spares near a silhouette lie behind the front side, which hides them. The
// transparency peels cull strictly (0): there a spared back point would be a layer of its own.
override BACK_FACE_MARGIN: f32 = 0.5;

fn culled(idx: u32, pos: vec3<f32>) -> bool {
    let w = normals[idx];
    let to_eye = frame.eye.xyz - pos;
    return w != 0u && dot(decode_oct16(w), to_eye) * normal_sign() < -BACK_FACE_MARGIN * length(to_eye);
}
