// Hole filling (sections 3.2 and 3.3), one iteration per dispatch, from `src` into `dst`.
// A candidate keeps its texel where one of eight 3x3 masks finds all its cells
// "white": it then lies beyond a silhouette (background fill) or beyond the border of a front
// surface (occluded fill). Else it takes the texel of its nearest neighbour (background fill)
// or of the farthest neighbour in front of it (occluded fill, see `occluder`). Every texel is
// written, so that an iteration that changed nothing leaves `dst` equal to `src`. A workgroup
// is one 16x16 tile of the iteration's list, which tiles.wgsl made (its count is the
// dispatch's workgroup count): after the first iteration only tiles that changed, or lie
// beside one that changed, in the iteration before. Any other tile cannot change, and both
// buffers already hold it (it did not change when the other was written), so the late
// iterations that close a few long gaps cost little.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(2) var<storage, read> src: array<Texel>;
@group(0) @binding(3) var<storage, read_write> dst: array<Texel>;
@group(0) @binding(4) var<storage, read_write> counters: array<u32>;
// Per kind, iteration and 16x16 tile: 1 where the iteration changed a pixel of the tile (then
// the resolve's occupied tiles, `occupied_slot`).
@group(0) @binding(5) var<storage, read_write> tiles: array<u32>;
// The iterations' lists (`list_base`); this one's tiles to work on, y << 16 | x.
@group(0) @binding(6) var<storage, read> tile_lists: array<u32>;
@group(1) @binding(0) var<uniform> step: Step;


struct Neighbours {
    // Bit k: cell OFFSETS[k] is background (or off the image).
    background: u32,
    // Depths (0 for background).
    depth: array<f32, 8>,
}

// Reads the neighbours' depths only (a quarter of their texels); the caller fetches the
// texels it needs more of.
fn neighbours(c: vec2<i32>) -> Neighbours {
    var n: Neighbours;
    n.background = 0u;
    for (var k = 0; k < 8; k++) {
        let q = c + OFFSETS[k];
        var bits = 0u;
        if q.x >= 0 && q.y >= 0 && q.x < i32(frame.width) && q.y < i32(frame.height) {
            bits = src[u32(q.y) * frame.width + u32(q.x)].x;
        }
        n.depth[k] = bitcast<f32>(bits);
        if bits == 0u {
            n.background |= 1u << u32(k);
        }
    }
    return n;
}

struct Listed {
    ok: bool,
    tile: vec2<u32>,
}

// The tile of workgroup `wg` in this iteration's list; not ok past the list's end (the last
// row of workgroups is not full).
fn listed_tile(wg: vec2<u32>) -> Listed {
    let base = list_base(list_of(step.kind, step.iteration));
    let k = wg.y * MAX_GROUPS_X + wg.x;
    if k >= tile_lists[base + 3u] {
        return Listed(false, vec2<u32>(0u));
    }
    let packed = tile_lists[base + LIST_HEADER + k];
    return Listed(true, vec2<u32>(packed & 0xffffu, packed >> 16u));
}

// Writes the texel of pixel `id` (index `i`): where `fill`, a copy of its neighbour `source`
// (an index into OFFSETS), else `keep`. A copy the background fill `carried` reaches a pixel
// less far, and is marked as carried.
fn finish(id: vec2<u32>, i: u32, keep: Texel, fill: bool, source: i32, carried: bool, tile: vec2<u32>) {
    if fill {
        let q = vec2<i32>(id) + OFFSETS[source];
        var t = src[u32(q.y) * frame.width + u32(q.x)];
        if carried {
            t.w = with_reach(t.w, texel_reach(t) - 1u) | CARRIED;
        }
        dst[i] = t;
        counters[changed_slot(step.layer, step.kind, step.iteration)] = 1u;
        tiles[tile_slot(step.kind, step.iteration, tile)] = 1u;
    } else {
        dst[i] = keep;
    }
}

// Whether surface lies within `reach` pixels of background pixel `c` to its left, its right,
// above and below it: then it lies inside a hole, where a straight outline leaves one side
// open. The masks see three by three pixels and take the edge of a hole four pixels across
// for an outline: such a hole never closes (only its corners fill).
fn enclosed(c: vec2<i32>, reach: u32) -> bool {
    let far = i32(min(reach, MAX_ENCLOSED_PX));
    for (var a = 0; a < 4; a++) {
        let step = AXES[a];
        var hit = false;
        for (var k = 1; k <= far && !hit; k++) {
            let q = c + k * step;
            if q.x < 0 || q.y < 0 || q.x >= i32(frame.width) || q.y >= i32(frame.height) {
                break;
            }
            hit = src[u32(q.y) * frame.width + u32(q.x)].x != 0u;
        }
        if !hit {
            return false;
        }
    }
    return true;
}

const AXES = array<vec2<i32>, 4>(vec2<i32>(1, 0), vec2<i32>(-1, 0), vec2<i32>(0, 1), vec2<i32>(0, -1));
// The widest hole `enclosed` looks across.
const MAX_ENCLOSED_PX: u32 = 16u;

// Section 3.2: a background pixel is filled unless it lies beyond the silhouette, or beside a
// point whose sampling leaves no empty pixel (reach 0, `sampling_reach`): but for the 1 % its
// radius leaves open, no gap of its sampling can be there, as between the points scattered
// along a scan's outline, which the masks take for a hole. Else it takes the texel of its
// nearest neighbour that may be carried a pixel further (`texel_reach`): a texel travels no
// farther than two radii from its point. Where that width is known (a stored radius), a pixel
// the masks take for one beyond the silhouette is filled all the same when surface encloses it
// within that width (`enclosed`): a hole in the sampling no wider than two radii.
@compute @workgroup_size(16, 16)
fn background(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) local: vec3<u32>) {
    let listed = listed_tile(wg.xy);
    if !listed.ok {
        return;
    }
    let tile = listed.tile;
    let id = tile * 16u + local.xy;
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let i = id.y * frame.width + id.x;
    let t = src[i];
    if t.x != 0u {
        dst[i] = t;
        return;
    }
    let n = neighbours(vec2<i32>(id.xy));
    var nearest = -1;
    var nearest_reach = 0u;
    var dense = false;
    for (var k = 0; k < 8; k++) {
        let d = n.depth[k];
        if d != 0.0 {
            // Its flags word alone, as `neighbours` reads the depth alone.
            let q = vec2<i32>(id.xy) + OFFSETS[k];
            let w = src[u32(q.y) * frame.width + u32(q.x)].w;
            let reach = reach_of(w);
            dense = dense || (reach == 0u && (w & CARRIED) == 0u);
            if reach > 0u && (nearest < 0 || d < n.depth[nearest]) {
                nearest = k;
                nearest_reach = reach;
            }
        }
    }
    var fill = !dense && nearest >= 0;
    if fill && some_mask_white(n.background) {
        fill = nearest_reach < MAX_REACH_PX && enclosed(vec2<i32>(id.xy), nearest_reach);
    }
    finish(id, i, t, fill, nearest, true, tile);
}

// Section 3.3: a pixel showing a surface more than d~ behind its neighbours is filled with one
// of them (see `occluder`) unless it lies beyond the border of that front surface. Cells at the
// candidate's depth or behind (within d~) are white, and so is background: nothing occludes
// beyond a silhouette (taking background as depth 0, in front, as a literal reading would, lets
// the pixels along a silhouette take each other's texels iteration after iteration).
@compute @workgroup_size(16, 16)
fn occluded(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) local: vec3<u32>) {
    let listed = listed_tile(wg.xy);
    if !listed.ok {
        return;
    }
    let tile = listed.tile;
    let id = tile * 16u + local.xy;
    if id.x >= frame.width || id.y >= frame.height {
        return;
    }
    let i = id.y * frame.width + id.x;
    let t = src[i];
    if t.x == 0u {
        dst[i] = t;
        return;
    }
    let n = neighbours(vec2<i32>(id.xy));
    let limit = bitcast<f32>(t.x) - fil.dtilde;
    var white = 0u;
    // The occluder: the farthest of the neighbours in front. The paper takes the nearest, but
    // iterated, that carries the front-most surface through the holes of the one behind it (a
    // tree's texels climbing a sparse wall behind it, one hole an iteration), where the hole is
    // the wall's.
    var occluder = -1;
    var occluder_depth = 0.0;
    for (var k = 0; k < 8; k++) {
        if n.depth[k] > limit || (n.background & (1u << u32(k))) != 0u {
            white |= 1u << u32(k);
        } else if n.depth[k] > occluder_depth {
            occluder = k;
            occluder_depth = n.depth[k];
        }
    }
    finish(id, i, t, occluder >= 0 && !some_mask_white(white), occluder, false, tile);
}
