// SPEC.md's oct16 normals, shared by every pass that reads the Normals stream (0: no normal).

// U low, V high, unorm16 each.
fn decode_oct16(w: u32) -> vec3<f32> {
    let uv = unpack2x16unorm(w) * 2.0 - 1.0;
    var n = vec3<f32>(uv.x, uv.y, 1.0 - abs(uv.x) - abs(uv.y));
    if n.z < 0.0 {
        let s = select(vec2<f32>(-1.0), vec2<f32>(1.0), uv >= vec2<f32>(0.0));
        n = vec3<f32>((1.0 - abs(uv.y)) * s.x, (1.0 - abs(uv.x)) * s.y, n.z);
    }
    return normalize(n);
}

// What multiplies a stored normal to point it out of its surface (`Frame::normals_turned`).
fn normal_sign() -> f32 {
    return select(1.0, -1.0, frame.normals_turned != 0u);
}
