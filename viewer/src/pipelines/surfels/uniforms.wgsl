// The surfel pipeline's own uniforms, read by all its passes.

// Words per pixel of the depth planes: the front (the nearest depth pushed back by z_o), the
// nearest depth, and the nearest depth of a surfel facing the eye.
const PLANE_WORDS: u32 = 3u;

struct Surfels {
    // The eye; a pixel's ray is forward + ndc.x * right + ndc.y * up, so that the ray
    // parameter of a hit is its linear depth (the projection's clip.w).
    eye: vec4<f32>,
    forward: vec4<f32>,
    right: vec4<f32>,
    up: vec4<f32>,
    // 1: the normals point out of every surface, so one turned away from the eye marks a
    // back face (the far side of a closed surface, which the shade keeps from showing
    // through the near side's pinholes).
    back_faces: u32,
    // Rings of the c-surfel's mesh: its profile is linear between them.
    rings: u32,
    // MODE_*.
    mode: u32,
    // NORMALS_*: without, every surfel is a disc facing the eye.
    normals: u32,
    // A surfel is curved in hybrid mode where |cos(view, normal)| <= this (90 deg +- epsilon).
    sin_epsilon: f32,
    // The c-surfel's curvature constant h of phi(r) = 1 - exp(-(r^2 / h^2)^2).
    h: f32,
    // The Gaussian fall-off d of the alpha texture (paper section 3.2, texture units).
    falloff: f32,
    // z_o in multiples of each surfel's radius (section 3.3).
    depth_offset: f32,
    // kappa r / sqrt(s) for a point of stored radius r whose colour's alpha byte holds the
    // share s of the dataset's surface variation (StreamDataset::curvature_scale); 0: every
    // c-surfel bends as the paper's does.
    curvature: f32,
    // A c-surfel whose rim drops no further than this off its plane on the screen, in pixels,
    // is drawn planar.
    flat_px: f32,
    pad1: f32,
    pad2: f32,
    // phi at the outer edge of each ring, k / rings for k = 1..rings, at [(k - 1) / 4][(k - 1) % 4]
    // (the same for every surfel: worked out once on the CPU, not an exp per ring and pixel).
    ring_phi: array<vec4<f32>, 4>,
}

const MODE_PLANAR: u32 = 0u;
const MODE_CURVED: u32 = 1u;
const MODE_HYBRID: u32 = 2u;
const NORMALS_NONE: u32 = 0u;
// Normals oriented (as stored, towards scanners, or up).
const NORMALS_OUTWARD: u32 = 1u;
// Normals not oriented: each is turned towards the eye first.
const NORMALS_FACING_EYE: u32 = 2u;
