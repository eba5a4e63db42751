// Pull: one coarser level of the pull-push pyramid, the weighted mean of each 2x2 block, its
// weight the sum of the block's weights clamped to 1 (Kraus 2009). The colour's alpha is the
// share of the light that reaches the surface (pyramid_lit.wgsl), averaged like colour; so are
// the stored normals (`stored_normals`), over the cells that have one.
@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let l = level.index;
    let size = level_size(l);
    if id.x >= size.x || id.y >= size.y {
        return;
    }
    let fine = level_size(l - 1u);
    let fine_off = level_offset(l - 1u);
    var depth = 0.0;
    var colour = vec4<f32>(0.0);
    var weight = 0.0;
    var normal = vec3<f32>(0.0);
    let stored = pyr.stored_normals != 0u;
    for (var dy = 0u; dy < 2u; dy++) {
        for (var dx = 0u; dx < 2u; dx++) {
            let c = id.xy * 2u + vec2<u32>(dx, dy);
            if c.x < fine.x && c.y < fine.y {
                let j = fine_off + c.y * fine.x + c.x;
                let f = fill[j];
                depth += f.x * f.y;
                colour += unpack4x8unorm(fill_colour[j]) * f.y;
                weight += f.y;
                if stored && normals[j] != NO_NORMAL {
                    normal += decode_normal(normals[j]) * f.y;
                }
            }
        }
    }
    let o = level_offset(l) + id.y * size.x + id.x;
    if weight > 0.0 {
        fill[o] = vec2<f32>(depth / weight, min(weight, 1.0));
        fill_colour[o] = pack4x8unorm(colour / weight);
    } else {
        fill[o] = vec2<f32>(0.0, 0.0);
        fill_colour[o] = 0u;
    }
    if stored {
        normals[o] = select(NO_NORMAL, encode_normal(normalize(normal)), dot(normal, normal) > 1e-12);
    }
}
