// Projection: one thread per point, each writing the pixels its splat covers through `emit`,
// which the variant appended to this file defines (64-bit atomicMin, or the two 32-bit passes),
// skipping the points `culled` (cull.wgsl or no_cull.wgsl) turns away.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(1) @binding(0) var<storage, read> points: array<vec4<u32>>;
@group(1) @binding(1) var<storage, read> ranges: array<Range>;
@group(1) @binding(2) var<storage, read> attributes: array<u32>;
// Per point: its stored radius (the Radius stream; another buffer, never read, where the
// frame's footprint is 0).
@group(1) @binding(4) var<storage, read> radii: array<f32>;

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
    if !in_depth_range(clip, frame.near, frame.far) {
        return;
    }
    let ndc = clip.xy / clip.w;
    let fx = (ndc.x * 0.5 + 0.5) * f32(frame.width);
    let fy = (0.5 - ndc.y * 0.5) * f32(frame.height);
    var size = frame.point_size;
    if frame.size_mode == 1u {
        size = r.spacing * frame.point_size * frame.focal_px / clip.w;
    }
    if frame.footprint > 0.0 {
        // A pipeline that needs projected neighbours about a pixel apart (paper 004) draws a
        // sparse point as wide as the sampling around it: its radius, or where the LOD drew
        // fewer points than the dataset holds, the spacing of the finest level drawn.
        // A disc seen obliquely covers |cos| of its area: the square drawn covers as much, so
        // that a silhouette, seen edge-on, does not grow.
        let pos = bitcast<vec3<f32>>(p.xyz);
        let radius = drawn_radius(r, pos, radii[idx]) * sqrt(max(facing(idx, pos), 1e-3));
        size = max(size, frame.footprint * radius * frame.focal_px / clip.w);
    }
    size = clamp(size, 1.0, MAX_SPLAT);
    // A disc `w` pixels across: per axis, the w pixels whose centres lie within w/2 of the
    // point. An odd w centres on the point's pixel; an even one reaches one further towards
    // the half of the pixel the point lies in (so 2 is 2x2, not 3x3 as a centred span gives).
    let w = i32(round(size));
    let half = w / 2;
    let cx = i32(floor(fx));
    let cy = i32(floor(fy));
    if cx < -half || cy < -half || cx >= i32(frame.width) + half || cy >= i32(frame.height) + half {
        return;
    }
    let even = i32(w % 2 == 0);
    let x0 = cx - half + even * i32(fract(fx) >= 0.5);
    let y0 = cy - half + even * i32(fract(fy) >= 0.5);
    // Linear depth (view-space distance along the axis): positive floats order like their bits.
    let depth = bitcast<u32>(clip.w);
    let global = (ranges[0].start << frame.arena_shift) | idx;
    // In doubled units from the disc's centre, so that half pixels are whole numbers.
    let r2 = w * w;
    for (var j = 0; j < w; j++) {
        for (var i = 0; i < w; i++) {
            let x = x0 + i;
            let y = y0 + j;
            let dx = 2 * i + 1 - w;
            let dy = 2 * j + 1 - w;
            if dx * dx + dy * dy <= r2 && x >= 0 && y >= 0 && x < i32(frame.width) && y < i32(frame.height) {
                emit(u32(y) * frame.width + u32(x), depth, global);
            }
        }
    }
}

// How squarely the point's surface faces the eye: |cos| of the angle between its normal and
// the view ray (1 without a normal).
fn facing(idx: u32, pos: vec3<f32>) -> f32 {
    let w = normals[idx];
    if w == 0u {
        return 1.0;
    }
    return abs(dot(decode_oct16(w), normalize(frame.eye.xyz - pos)));
}
