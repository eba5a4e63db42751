// A point's fan (sections 3.4 and 3.5): its sector neighbours in circular order, and the
// triangles between consecutive ones whose opening angle seen from the point is below pi.

struct Fan {
    // Pixel ids of the neighbours found, in sector order.
    ids: array<u32, 8>,
    count: u32,
}

fn fan_of(p: u32) -> Fan {
    var f: Fan;
    f.count = 0u;
    for (var s = 0u; s < SECTORS; s++) {
        let v = neighbours[p * SECTORS + s];
        if v != 0u {
            f.ids[f.count] = ~v;
            f.count += 1u;
        }
    }
    return f;
}

// The screen offset of pixel `q` from pixel `p`, y down.
fn offset_px(p: u32, q: u32) -> vec2<f32> {
    let a = vec2<f32>(f32(p % frame.width), f32(p / frame.width));
    let b = vec2<f32>(f32(q % frame.width), f32(q / frame.width));
    return b - a;
}

// Whether the fan's k-th triangle (neighbours k and k + 1, circularly) is drawn: at least two
// neighbours, and an opening angle below pi counter-clockwise on screen from k to k + 1.
fn opens(p: u32, f: Fan, k: u32) -> bool {
    if f.count < 2u {
        return false;
    }
    let a = offset_px(p, f.ids[k]);
    let b = offset_px(p, f.ids[(k + 1u) % f.count]);
    // Counter-clockwise on screen with y down: a negative cross product of (a, b).
    let cross = a.x * b.y - a.y * b.x;
    return cross < 0.0;
}
