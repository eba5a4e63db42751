// Point colour for the current colouring mode; shared by resolve and finish.

fn ramp(t: f32) -> vec3<f32> {
    // A perceptually ordered blue-green-yellow ramp (viridis-like), five stops.
    let c0 = vec3<f32>(0.267, 0.005, 0.329);
    let c1 = vec3<f32>(0.229, 0.322, 0.546);
    let c2 = vec3<f32>(0.128, 0.567, 0.551);
    let c3 = vec3<f32>(0.369, 0.789, 0.383);
    let c4 = vec3<f32>(0.993, 0.906, 0.144);
    let s = clamp(t, 0.0, 1.0) * 4.0;
    if s < 1.0 { return mix(c0, c1, s); }
    if s < 2.0 { return mix(c1, c2, s - 1.0); }
    if s < 3.0 { return mix(c2, c3, s - 2.0); }
    return mix(c3, c4, s - 3.0);
}

fn class_colour(c: u32) -> vec3<f32> {
    // ASPRS standard classes.
    switch c {
        case 2u: { return vec3<f32>(0.63, 0.45, 0.27); }  // ground
        case 3u: { return vec3<f32>(0.56, 0.80, 0.45); }  // low vegetation
        case 4u: { return vec3<f32>(0.30, 0.65, 0.25); }  // medium vegetation
        case 5u: { return vec3<f32>(0.10, 0.45, 0.10); }  // high vegetation
        case 6u: { return vec3<f32>(0.85, 0.30, 0.25); }  // building
        case 7u: { return vec3<f32>(1.00, 0.00, 1.00); }  // low point (noise)
        case 9u: { return vec3<f32>(0.20, 0.45, 0.90); }  // water
        case 10u, 11u: { return vec3<f32>(0.40, 0.40, 0.40); }  // rail, road
        case 17u: { return vec3<f32>(0.90, 0.80, 0.20); }  // bridge deck
        default: { return vec3<f32>(0.75, 0.75, 0.75); }
    }
}

fn point_colour(p: vec4<u32>, a: u32) -> vec3<f32> {
    switch frame.colour_mode {
        case 1u: {
            let v = pow(min(f32(a & 0xffffu) * frame.intensity_scale, 1.0), 0.75);
            return vec3<f32>(v, v, v);
        }
        case 2u: { return class_colour(attribute_class(a)); }
        case 3u: {
            let z = bitcast<f32>(p.z);
            return ramp((z - frame.z_min) / max(frame.z_max - frame.z_min, 1e-6));
        }
        // Surface variation, which the loader puts in the colour's alpha byte.
        case 5u: { return ramp(unpack4x8unorm(p.w).a); }
        // The stored colour, or the normal where the loader put it there instead (4).
        default: { return unpack4x8unorm(p.w).rgb; }
    }
}
