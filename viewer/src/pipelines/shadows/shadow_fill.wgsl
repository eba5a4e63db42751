// The occluded fill (section 3.3) on the light map, so that a surface seen by the light through
// a gap between the points in front of it is not marked lit: a pixel more than d~ behind its
// neighbours takes the nearest of them unless a mask finds it beyond that front surface's border.
// Values are complements of depth bits (0: nothing there).

@group(0) @binding(1) var<storage, read> src: array<u32>;
@group(0) @binding(2) var<storage, read_write> dst: array<u32>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= sh.width || id.y >= sh.height {
        return;
    }
    let i = id.y * sh.width + id.x;
    let v = src[i];
    dst[i] = v;
    if v == 0u {
        return;
    }
    let limit = bitcast<f32>(~v) - sh.dtilde;
    var white = 0u;
    var nearest = v;
    for (var k = 0u; k < 8u; k++) {
        let q = vec2<i32>(id.xy) + OFFSETS[k];
        var n = 0u;
        if q.x >= 0 && q.y >= 0 && q.x < i32(sh.width) && q.y < i32(sh.height) {
            n = src[u32(q.y) * sh.width + u32(q.x)];
        }
        // Nothing there, or at the candidate's depth or behind: white.
        if n == 0u || bitcast<f32>(~n) > limit {
            white |= 1u << k;
        } else {
            nearest = max(nearest, n);
        }
    }
    if !some_mask_white(white) {
        dst[i] = nearest;
    }
}

// Empties a light map before the next sample's splat.
@compute @workgroup_size(16, 16)
fn clear(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x < sh.width && id.y < sh.height {
        dst[id.y * sh.width + id.x] = 0u;
    }
}
