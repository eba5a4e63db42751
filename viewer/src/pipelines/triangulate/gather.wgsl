// Once per arena: each pixel whose nearest point lives in this arena keeps it unless it lies
// behind the reprojected surface by more than its longest connection (the culling of the
// point projection, section 3.2), with its position and its search radius (the kept stream,
// or half its longest connection for a point that has none yet).
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> tri: Triangulate;
@group(0) @binding(2) var<storage, read> depths: array<u32>;
@group(0) @binding(3) var<storage, read> indices: array<u32>;
@group(0) @binding(4) var<storage, read> reprojected: array<u32>;
// Per pixel: the point's position (relative to the anchor) and search radius; w 0: none.
@group(0) @binding(5) var<storage, read_write> pts: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> counts: array<atomic<u32>>;
@group(1) @binding(0) var<storage, read> points: array<vec4<u32>>;
@group(1) @binding(1) var<storage, read> ranges: array<Range>;
// Per point: the search radius and the feedback distance of the last frame it was seen in.
@group(1) @binding(2) var<storage, read> kept: array<vec2<f32>>;

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
    let limit = connection_limit(depth, spacing_of(local));
    let front = reprojected[p];
    if front != 0u && depth > bitcast<f32>(~front) + limit {
        atomicAdd(&counts[COUNT_CULLED], 1u);
        return;
    }
    var radius = min(kept[local].x, limit);
    if radius <= 0.0 {
        // The paper's "average search radius between zero and the maximum connection".
        radius = 0.5 * limit;
    }
    pts[p] = vec4<f32>(pos, radius);
}
