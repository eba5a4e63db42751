// The facing check (facing.rs): which side of the surfaces the stored normals point to, seen
// from this view. Normals kept from the inputs may point into every surface (a mesh wound the
// other way, a scan oriented away from its scanner): culled by them, the near side of every
// surface is lost and the far side shown. A sample of the drawn points keeps, per cell of
// CELL x CELL pixels, the nearest depth of the points whose normal clearly faces the eye and
// that of the points whose normal clearly turns away (`sample`); `tally` then counts the
// cells that hold both where the side facing the eye lies clearly in front, and those where
// the side turned away does. A closed surface's far side lies clearly behind its near side.
// Where both lie at about the same depth the cell says nothing: a sheet seen at a slant, its
// two faces a hair apart, puts either in front of the other within a cell as often as normals
// pointing either way over one surface do. A cell counts only for the side of the front it
// lies in: the nearest sampled point of either side, grazing ones included (then it counts
// for neither), in it or the cells around it. Behind a sparse shell's near wall, whose points
// a cell's sample may miss, the inner walls put the side turned away clearly in front of the
// side facing the eye, and so do a gorge's walls behind the grazing ground before it; both
// lie behind a front of the side facing the eye, or a grazing one, and say nothing.

@group(0) @binding(0) var<uniform> frame: Frame;
// Per cell: the nearest depth of the side facing the eye, then of the side turned away, as the
// complement of the linear depth's bits (so that the largest is the nearest, and a cleared
// buffer, 0, is empty); then the front, the same of any point around it, its lowest two bits
// its side (0: facing the eye, 1: turned away, 2: grazing, which says nothing).
@group(0) @binding(1) var<storage, read_write> cells: array<atomic<u32>>;
// The cells where the side facing the eye lies clearly in front, then those where the side
// turned away does.
@group(0) @binding(2) var<storage, read_write> tallies: array<atomic<u32>, 2>;
@group(1) @binding(0) var<storage, read> points: array<vec4<u32>>;
@group(1) @binding(1) var<storage, read> ranges: array<Range>;
@group(1) @binding(2) var<storage, read> attributes: array<u32>;
@group(1) @binding(3) var<storage, read> normals: array<u32>;

// Pixels on a side of a cell: coarse enough that a cell holds points of both sides of a thin
// object, fine enough that it does not reach across to another object's.
const CELL: u32 = 4u;
// Every STRIDE-th point of a drawn range is sampled (the ranges' table is made for workgroups
// of GROUP_SIZE * STRIDE points).
override STRIDE: u32 = 4u;
// A normal within this cosine of grazing says little about its side: its point is left out.
const GRAZING: f32 = 0.25;
// One side lies clearly in front of the other where its depth is nearer by this share.
const DEPTH_MARGIN: f32 = 0.01;

fn cells_across() -> u32 {
    return (frame.width + CELL - 1u) / CELL;
}

@compute @workgroup_size(256)
fn sample(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    let group = wg.x + wg.y * groups.x;
    if ranges[0].count == 0u {
        return;
    }
    let r = ranges[range_of(group)];
    if group < r.first_group {
        return;
    }
    let local = ((group - r.first_group) * GROUP_SIZE + lane) * STRIDE;
    if local >= r.count {
        return;
    }
    let idx = r.start + local;
    let word = normals[idx];
    if word == 0u {
        return;
    }
    let pos = bitcast<vec3<f32>>(points[idx].xyz);
    if frame.filters != 0u && !passes_filters(pos, attributes[idx]) {
        return;
    }
    let clip = frame.view_proj * vec4<f32>(pos, 1.0);
    if !in_depth_range(clip, frame.near, frame.far) {
        return;
    }
    let ndc = clip.xy / clip.w;
    let fx = (ndc.x * 0.5 + 0.5) * f32(frame.width);
    let fy = (0.5 - ndc.y * 0.5) * f32(frame.height);
    if fx < 0.0 || fy < 0.0 || fx >= f32(frame.width) || fy >= f32(frame.height) {
        return;
    }
    let to_eye = frame.eye.xyz - pos;
    let facing = dot(decode_oct16(word), to_eye) / length(to_eye);
    let side = select(0u, 1u, facing < 0.0);
    // The front's side: 2 where it grazes, and says nothing.
    let front_side = select(side, 2u, abs(facing) < GRAZING);
    let nearness = ~bitcast<u32>(clip.w);
    let cx = i32(u32(fx) / CELL);
    let cy = i32(u32(fy) / CELL);
    let rows = i32((frame.height + CELL - 1u) / CELL);
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let x = cx + dx;
            let y = cy + dy;
            if x >= 0 && y >= 0 && x < i32(cells_across()) && y < rows {
                let around = u32(y) * cells_across() + u32(x);
                atomicMax(&cells[3u * around + 2u], (nearness & ~3u) | front_side);
            }
        }
    }
    if abs(facing) < GRAZING {
        return;
    }
    let cell = u32(cy) * cells_across() + u32(cx);
    atomicMax(&cells[3u * cell + side], nearness);
}

var<workgroup> counted: array<atomic<u32>, 2>;

@compute @workgroup_size(256)
fn tally(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    let cell = (wg.x + wg.y * groups.x) * GROUP_SIZE + lane;
    let rows = (frame.height + CELL - 1u) / CELL;
    if cell < cells_across() * rows {
        let towards = atomicLoad(&cells[3u * cell]);
        let away = atomicLoad(&cells[3u * cell + 1u]);
        let front_side = atomicLoad(&cells[3u * cell + 2u]) & 3u;
        if towards != 0u && away != 0u {
            let t = bitcast<f32>(~towards);
            let a = bitcast<f32>(~away);
            if t < a * (1.0 - DEPTH_MARGIN) && front_side == 0u {
                atomicAdd(&counted[0], 1u);
            } else if a < t * (1.0 - DEPTH_MARGIN) && front_side == 1u {
                atomicAdd(&counted[1], 1u);
            }
        }
    }
    workgroupBarrier();
    if lane < 2u {
        let n = atomicLoad(&counted[lane]);
        if n != 0u {
            atomicAdd(&tallies[lane], n);
        }
    }
}
