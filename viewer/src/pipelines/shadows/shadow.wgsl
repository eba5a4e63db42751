// Point shadow textures (section 6), for one light direction (one sample of the area light):
// `splat` draws every drawn point into the light map (the nearest depth along the light per
// pixel), and after the light map's occluded fill `mark` counts each point lit that lies within
// Δd = d~ / |<l, n>| (truncated) of the front layer at its pixel. Marking every point against
// the filled front depth at once gives what the paper's repeated peeling converges to.

// Complement of the nearest depth's bits per light map pixel (0: nothing there).
@group(0) @binding(1) var<storage, read_write> light_map: array<atomic<u32>>;
@group(0) @binding(2) var<uniform> frame: Frame;
@group(1) @binding(0) var<storage, read> points: array<vec4<u32>>;
@group(1) @binding(1) var<storage, read> ranges: array<Range>;
@group(1) @binding(2) var<storage, read> attributes: array<u32>;
@group(1) @binding(3) var<storage, read> normals: array<u32>;
// Per point: the light samples that reached it so far.
@group(1) @binding(4) var<storage, read_write> lit: array<f32>;

struct LightPoint {
    ok: bool,
    idx: u32,
    pixel: u32,
    depth: f32,
}

fn light_point(group: u32, lane: u32) -> LightPoint {
    var out: LightPoint;
    out.ok = false;
    if ranges[0].count == 0u {
        return out;
    }
    let r = ranges[range_of(group)];
    let local = (group - r.first_group) * GROUP_SIZE + lane;
    if group < r.first_group || local >= r.count {
        return out;
    }
    let idx = r.start + local;
    let p = bitcast<vec3<f32>>(points[idx].xyz);
    // What the filters hide casts no shadow either.
    if frame.filters != 0u && !passes_filters(p, attributes[idx]) {
        return out;
    }
    let px = vec2<f32>(dot(p, sh.u_axis.xyz) - sh.u_axis.w, dot(p, sh.v_axis.xyz) - sh.v_axis.w);
    if any(px < vec2<f32>(0.0)) || px.x >= f32(sh.width) || px.y >= f32(sh.height) {
        return out;
    }
    out.ok = true;
    out.idx = idx;
    out.pixel = u32(px.y) * sh.width + u32(px.x);
    out.depth = max(sh.light.w - dot(p, sh.light.xyz), 0.0);
    return out;
}

@compute @workgroup_size(256)
fn splat(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    let q = light_point(wg.x + wg.y * groups.x, lane);
    if q.ok {
        atomicMax(&light_map[q.pixel], ~bitcast<u32>(q.depth));
    }
}

@compute @workgroup_size(256)
fn mark(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    let q = light_point(wg.x + wg.y * groups.x, lane);
    if !q.ok {
        return;
    }
    let front = atomicLoad(&light_map[q.pixel]);
    if front == 0u {
        return;
    }
    var reach = sh.dtilde;
    let w = normals[q.idx];
    if sh.normals != 0u && w != 0u {
        let cosine = abs(dot(decode_oct16(w), sh.light.xyz));
        reach = sh.dtilde * min(1.0 / max(cosine, 1e-6), MAX_REACH);
    }
    if q.depth <= bitcast<f32>(~front) + reach {
        lit[q.idx] += 1.0;
    }
}
