// The points pipeline's shading: each pixel shows its nearest point's colour as it is.
fn shade_pixel(id: vec2<u32>, d: u32, rgb: vec3<f32>) -> vec3<f32> {
    return rgb;
}
