// Projection: one thread per point, each writing the pixels its splat covers through `emit`,
// which the variant appended to this file defines (64-bit atomicMin, or the two 32-bit passes),
// skipping the points `culled` (cull.wgsl or no_cull.wgsl) turns away.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(1) @binding(0) var<storage, read> points: array<vec4<u32>>;
@group(1) @binding(1) var<storage, read> ranges: array<Range>;
@group(1) @binding(2) var<storage, read> attributes: array<u32>;

const MAX_SPLAT: f32 = 15.0;

@compute @workgroup_size(256)
fn main(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    let group = wg.x + wg.y * groups.x;
    if ranges[0].count == 0u {
        return;
    }
    let r = ranges[range_of(group)];
    let local = (group - r.first_group) * GROUP_SIZE + lane;
    if group < r.first_group || local >= r.count {
        return;
    }
    let idx = r.start + local;
    let p = points[idx];
    // A point the filters hide is never drawn: it leaves no hole and costs nothing downstream.
    if frame.filters != 0u && !passes_filters(bitcast<vec3<f32>>(p.xyz), attributes[idx]) {
        return;
    }
    if culled(idx, bitcast<vec3<f32>>(p.xyz)) {
        return;
    }
    let clip = frame.view_proj * vec4<f32>(bitcast<vec3<f32>>(p.xyz), 1.0);
    if clip.w <= 0.0 || clip.z < 0.0 || clip.z > clip.w {
        return;
    }
    let ndc = clip.xy / clip.w;
    let fx = (ndc.x * 0.5 + 0.5) * f32(frame.width);
    let fy = (0.5 - ndc.y * 0.5) * f32(frame.height);
    var size = frame.point_size;
    if frame.size_mode == 1u {
        size = r.spacing * frame.point_size * frame.focal_px / clip.w;
    }
    size = clamp(size, 1.0, MAX_SPLAT);
    let half = i32(floor((size - 1.0) * 0.5 + 0.5));
    let cx = i32(floor(fx));
    let cy = i32(floor(fy));
    if cx < -half || cy < -half || cx >= i32(frame.width) + half || cy >= i32(frame.height) + half {
        return;
    }
    // Linear depth (view-space distance along the axis): positive floats order like their bits.
    let depth = bitcast<u32>(clip.w);
    let global = (ranges[0].start << frame.arena_shift) | idx;
    let r2 = half * half + half;
    for (var dy = -half; dy <= half; dy++) {
        for (var dx = -half; dx <= half; dx++) {
            let x = cx + dx;
            let y = cy + dy;
            if dx * dx + dy * dy <= r2 && x >= 0 && y >= 0 && x < i32(frame.width) && y < i32(frame.height) {
                emit(u32(y) * frame.width + u32(x), depth, global);
            }
        }
    }
}
