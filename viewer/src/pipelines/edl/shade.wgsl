// The edl pipeline's shading: the nearest point's colour darkened by eye-dome lighting.
fn shade_pixel(id: vec2<u32>, d: u32, rgb: vec3<f32>) -> vec3<f32> {
    return rgb * edl_factor(id, d);
}
