// Once per arena: each pixel whose nearest point lives in this arena keeps it unless it lies
// behind the reprojected surface by more than its longest connection (the culling of the
// point projection, section 3.2), with its position and its search radius (the kept stream,
// or half its longest connection for a point that has none yet), and its normal where the
// normals tell a surface's sides apart or shade it.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> tri: Triangulate;
@group(0) @binding(2) var<storage, read> depths: array<u32>;
@group(0) @binding(3) var<storage, read> indices: array<u32>;
@group(0) @binding(4) var<storage, read> reprojected: array<u32>;
// Per pixel: the point's position (relative to the anchor) and search radius; w 0: none; w < 0:
// culled, a neighbour only (the passes that draw, estimate normals or learn radii skip w <= 0).
@group(0) @binding(5) var<storage, read_write> pts: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> counts: array<atomic<u32>>;
// Per pixel, where SIDES or `stored_normals`: the point's normal as four snorm8 (x, y, z, 1),
// for the search to compare without decoding, and for the normals and the raster; 0: none.
@group(0) @binding(7) var<storage, read_write> point_normals: array<u32>;
@group(1) @binding(0) var<storage, read> points: array<vec4<u32>>;
@group(1) @binding(1) var<storage, read> ranges: array<Range>;
// Per point: the search radius and the feedback distance of the last frame it was seen in.
@group(1) @binding(2) var<storage, read> kept: array<vec2<f32>>;
@group(1) @binding(3) var<storage, read> normals: array<u32>;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let p = id.y * frame.width + id.x;
    if depths[p] == EMPTY {
        return;
    }
    let g = indices[p];
    if (g >> frame.arena_shift) != ranges[0].start {
        return;
    }
    let local = g & ((1u << frame.arena_shift) - 1u);
    let pos = bitcast<vec3<f32>>(points[local].xyz);
    let depth = bitcast<f32>(depths[p]);
    let limit = connection_limit(depth, ranges[range_holding(local)].spacing);
    let front = reprojected_at(id.xy);
    let hidden = front != 0u && depth > bitcast<f32>(~front) + limit;
    if hidden {
        atomicAdd(&counts[COUNT_CULLED], 1u);
    }
    var radius = min(kept[local].x, limit);
    if radius <= 0.0 {
        // The paper's "average search radius between zero and the maximum connection".
        radius = 0.5 * limit;
    }
    // A culled point is kept as a neighbour only (w < 0): no fan of its own, no normal, no
    // radius of its own to learn, but the visible points of its surface beside the surface
    // that hides it connect to it, so that their fans reach under that surface's outline
    // rather than stopping a spacing short of it (a ring of holes round every near object).
    pts[p] = vec4<f32>(pos, select(radius, -radius, hidden));
    if SIDES || tri.stored_normals != 0u {
        let w = normals[local];
        point_normals[p] = select(0u, pack4x8snorm(vec4<f32>(decode_oct16(w) * normal_sign(), 1.0)), w != 0u);
    }
}

fn reprojected_or_empty(x: i32, y: i32) -> u32 {
    if x < 0 || y < 0 || x >= i32(frame.width) || y >= i32(frame.height) {
        return 0u;
    }
    return reprojected[u32(y) * frame.width + u32(x)];
}

// The reprojected depth at a pixel (complemented, 0: none). Moving each pixel of the last frame
// to one pixel of this one leaves one-pixel cracks where the view turns or nears; a crack
// between two reprojected pixels (left and right, or above and below) takes the farther of
// them, so that the points behind the surface there are culled too, while the outline of the
// surface does not grow (a pixel beside it has reprojected depth on one side only).
fn reprojected_at(id: vec2<u32>) -> u32 {
    let x = i32(id.x);
    let y = i32(id.y);
    let here = reprojected_or_empty(x, y);
    if here != 0u {
        return here;
    }
    var farthest = 0xffffffffu;
    let l = reprojected_or_empty(x - 1, y);
    let r = reprojected_or_empty(x + 1, y);
    if l != 0u && r != 0u {
        farthest = min(farthest, min(l, r));
    }
    let u = reprojected_or_empty(x, y - 1);
    let d = reprojected_or_empty(x, y + 1);
    if u != 0u && d != 0u {
        farthest = min(farthest, min(u, d));
    }
    return select(farthest, 0u, farthest == 0xffffffffu);
}
