// Normals of one level of the filled depth pyramid, by the cross product of the differences to
// neighbouring cells; on each axis the side with the smaller depth step, so that normals do not
// bend across silhouettes. Only cells that held measured points count (weight above 1 after
// the push): depth extrapolated past an edge is flat and would tilt normals towards the eye.
// Oriented towards the eye.
fn level_point(l: u32, c: vec2<u32>, d: f32) -> vec3<f32> {
    let scale = f32(1u << l);
    return view_point((vec2<f32>(c) + 0.5) * scale, d);
}

fn filled(l: u32, c: vec2<i32>) -> vec2<f32> {
    let size = vec2<i32>(level_size(l));
    if c.x < 0 || c.y < 0 || c.x >= size.x || c.y >= size.y {
        return vec2<f32>(0.0, 0.0);
    }
    return fill[level_offset(l) + u32(c.y * size.x + c.x)];
}

fn side(l: u32, c: vec2<i32>, step: vec2<i32>, p: vec3<f32>, d: f32) -> vec3<f32> {
    let a = filled(l, c + step);
    let b = filled(l, c - step);
    let pa = level_point(l, vec2<u32>(c + step), a.x);
    let pb = level_point(l, vec2<u32>(c - step), b.x);
    let has_a = a.y > 1.0;
    let has_b = b.y > 1.0;
    if has_a && (!has_b || abs(a.x - d) <= abs(b.x - d)) {
        return pa - p;
    }
    if has_b {
        return p - pb;
    }
    return vec3<f32>(0.0);
}

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let l = level.index;
    let size = level_size(l);
    if id.x >= size.x || id.y >= size.y {
        return;
    }
    let o = level_offset(l) + id.y * size.x + id.x;
    let f = fill[o];
    if f.y <= 1.0 {
        normals[o] = NO_NORMAL;
        return;
    }
    let c = vec2<i32>(id.xy);
    let p = level_point(l, id.xy, f.x);
    let dx = side(l, c, vec2<i32>(1, 0), p, f.x);
    let dy = side(l, c, vec2<i32>(0, 1), p, f.x);
    var n = cross(dy, dx);
    let len = length(n);
    if !(len > 0.0) {
        normals[o] = NO_NORMAL;
        return;
    }
    n = n / len;
    if dot(n, -p) < 0.0 {
        n = -n;
    }
    normals[o] = encode_normal(n);
}
