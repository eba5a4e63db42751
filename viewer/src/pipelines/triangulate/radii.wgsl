// Once per arena, after the feedback: each point drawn this frame keeps the search radius for
// its next frame (section 3.6) beside its arena. With f the largest distance at which a
// neighbour took it this frame and f' that of the last frame it was seen in:
// - f grew: the radius grows further;
// - else it grows until it reaches THRESHOLD * f, then falls back to f;
// - a point nobody took grows towards its longest connection (`connection_limit`).
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> tri: Triangulate;
@group(0) @binding(2) var<storage, read> indices: array<u32>;
@group(0) @binding(3) var<storage, read> pts: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> feedback: array<u32>;
@group(1) @binding(0) var<storage, read> ranges: array<Range>;
@group(1) @binding(1) var<storage, read_write> kept: array<vec2<f32>>;

// The growth of a radius per frame while it probes for farther neighbours.
const GROWTH: f32 = 1.25;
// How far beyond the farthest neighbour that took the point its radius probes.
const THRESHOLD: f32 = 2.0;
// Slack on falling back to f, so that the farthest neighbour stays within reach.
const SLACK: f32 = 1.0001;

@compute @workgroup_size(16, 16)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let p = id.y * frame.width + id.x;
    let me = pts[p];
    if me.w <= 0.0 {
        return;
    }
    let g = indices[p];
    if (g >> frame.arena_shift) != ranges[0].start {
        return;
    }
    let local = g & ((1u << frame.arena_shift) - 1u);
    let f = bitcast<f32>(feedback[p]);
    let last = kept[local].y;
    let limit = connection_limit(linear_depth(me.xyz), ranges[range_holding(local)].spacing);
    var next = min(me.w * GROWTH, limit);
    if f > 0.0 && f <= last && me.w >= THRESHOLD * f {
        next = min(f * SLACK, limit);
    }
    kept[local] = vec2<f32>(next, f);
}
