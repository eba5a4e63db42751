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
