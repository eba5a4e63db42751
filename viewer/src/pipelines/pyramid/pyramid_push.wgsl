// Push: fills one level from the (already filled) coarser one, bilinearly interpolated, in
// proportion to what the level lacks: v = w v_fine + (1 - w) v_coarse. Afterwards the level
// holds a value wherever the coarser one did, and its weight becomes 1 + w: at least 1 means
// filled, and the part above 1 keeps how much real data the cell had, which the normals need
// to tell measured surface from extrapolated. The top level only gets its weights marked.
// Colour's alpha (the lit share) is interpolated with it, and so are the stored normals
// (`stored_normals`), which also fill a cell whose point had none.
@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let l = level.index;
    let size = level_size(l);
    if id.x >= size.x || id.y >= size.y {
        return;
    }
    let o = level_offset(l) + id.y * size.x + id.x;
    let f = fill[o];
    let top = l + 1u >= pyr.levels;
    let fine_normal = normals[o];
    let push_values = f.y < 1.0 && !top;
    let push_normal = pyr.stored_normals != 0u && !top && (f.y < 1.0 || fine_normal == NO_NORMAL);
    if !push_values && f.y > 0.0 {
        fill[o] = vec2<f32>(f.x, 1.0 + min(f.y, 1.0));
    }
    if !push_values && !push_normal {
        return;
    }
    let coarse = level_size(l + 1u);
    let coarse_off = level_offset(l + 1u);
    let u = (vec2<f32>(id.xy) + 0.5) * 0.5 - 0.5;
    let base = vec2<i32>(floor(u));
    let t = u - vec2<f32>(base);
    var depth = 0.0;
    var colour = vec4<f32>(0.0);
    var weight = 0.0;
    var normal = vec3<f32>(0.0);
    for (var dy = 0; dy < 2; dy++) {
        for (var dx = 0; dx < 2; dx++) {
            let c = clamp(base + vec2<i32>(dx, dy), vec2<i32>(0), vec2<i32>(coarse) - 1);
            let b = select(1.0 - t.x, t.x, dx == 1) * select(1.0 - t.y, t.y, dy == 1);
            let j = coarse_off + u32(c.y) * coarse.x + u32(c.x);
            let w = select(0.0, b, fill[j].y >= 1.0);
            depth += fill[j].x * w;
            colour += unpack4x8unorm(fill_colour[j]) * w;
            weight += w;
            if push_normal && normals[j] != NO_NORMAL {
                normal += decode_normal(normals[j]) * w;
            }
        }
    }
    if push_normal && dot(normal, normal) > 1e-12 {
        // The cell's own normal keeps the share of the cell its data covered.
        let keep = select(0.0, min(f.y, 1.0), fine_normal != NO_NORMAL);
        var n = (1.0 - keep) * normalize(normal);
        if keep > 0.0 {
            n += keep * decode_normal(fine_normal);
        }
        if dot(n, n) > 1e-12 {
            normals[o] = encode_normal(normalize(n));
        }
    }
    if !push_values || weight <= 0.0 {
        return;
    }
    let keep = f.y;
    let fine_colour = unpack4x8unorm(fill_colour[o]);
    fill[o] = vec2<f32>(keep * f.x + (1.0 - keep) * depth / weight, 1.0 + keep);
    fill_colour[o] = pack4x8unorm(keep * fine_colour + (1.0 - keep) * colour / weight);
}
