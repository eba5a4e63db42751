// Headlight Blinn-Phong: the light sits at the eye, so the half vector is the view direction.
// Shared by the pyramid pipeline and the quality harness's reference meshes, so that both are
// shaded the same way.

const AMBIENT: f32 = 0.25;
const DIFFUSE: f32 = 0.75;
const SPECULAR: f32 = 0.25;
const SHININESS: f32 = 32.0;

// `n` and `v` are unit vectors: the surface normal and the direction from the surface to the eye.
fn headlight(albedo: vec3<f32>, n: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    // Two-sided: a surface seen from behind is lit like its front.
    let nv = abs(dot(n, v));
    return albedo * (AMBIENT + DIFFUSE * nv) + vec3<f32>(SPECULAR * pow(nv, SHININESS));
}

// Blinn-Phong with a light in the unit direction `l` (towards the light) and the same terms;
// with l = v on a normal facing the eye it equals `headlight`. `lit`: the share of the light
// that reaches the point (1: unshadowed), scaling the diffuse and specular terms.
fn phong(albedo: vec3<f32>, n: vec3<f32>, v: vec3<f32>, l: vec3<f32>, lit: f32) -> vec3<f32> {
    let nl = max(dot(n, l), 0.0);
    let nh = max(dot(n, normalize(l + v)), 0.0);
    let specular = select(0.0, SPECULAR * pow(nh, SHININESS), nl > 0.0);
    return albedo * (AMBIENT + lit * DIFFUSE * nl) + vec3<f32>(lit * specular);
}
