// Points drawn: the points of the drawn ranges that pass the frame's filters, counted a thread
// per point, summed in the workgroup, then once per workgroup into `drawn`. Runs only while a
// filter is set (without one, every point of the drawn nodes is drawn).

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read_write> drawn: atomic<u32>;
@group(1) @binding(0) var<storage, read> points: array<vec4<u32>>;
@group(1) @binding(1) var<storage, read> ranges: array<Range>;
@group(1) @binding(2) var<storage, read> attributes: array<u32>;

var<workgroup> passed: atomic<u32>;

@compute @workgroup_size(256)
fn main(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    let group = wg.x + wg.y * groups.x;
    if ranges[0].count != 0u {
        let r = ranges[range_of(group)];
        let local = (group - r.first_group) * GROUP_SIZE + lane;
        if group >= r.first_group && local < r.count {
            let idx = r.start + local;
            if passes_filters(bitcast<vec3<f32>>(points[idx].xyz), attributes[idx]) {
                atomicAdd(&passed, 1u);
            }
        }
    }
    workgroupBarrier();
    if lane == 0u {
        let n = atomicLoad(&passed);
        if n != 0u {
            atomicAdd(&drawn, n);
        }
    }
}
