// The uniforms of one light sample of the shadow passes (section 6).

struct Shadow {
    // xyz: the unit direction towards the light; w: the largest dot(p, light) over the bounds,
    // so that depth w - dot(p, light) is positive and grows away from the light.
    light: vec4<f32>,
    // A light map pixel: (dot(p, u_axis.xyz) - u_axis.w, dot(p, v_axis.xyz) - v_axis.w).
    u_axis: vec4<f32>,
    v_axis: vec4<f32>,
    width: u32,
    height: u32,
    dtilde: f32,
    // 1: the points carry normals (Δd by the normal).
    normals: u32,
}

// The most Δd grows over d~ at grazing light.
const MAX_REACH: f32 = 4.0;

@group(0) @binding(0) var<uniform> sh: Shadow;
