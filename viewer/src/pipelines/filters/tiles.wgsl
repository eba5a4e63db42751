// The tiles a fill iteration works on, appended to its list (`list_base`), whose count is the
// iteration's workgroup count: in the first iteration every tile of a peeled layer, and the
// first layer's tiles that hold a point or lie beside one; then those that changed, or lie
// beside one that changed, in the iteration before. The first layer's other tiles are
// background in both texel buffers (both cleared), and no fill changes them: a background
// pixel is filled only from a neighbour, one pixel an iteration, so at most MAX_ITERATIONS
// (16, the tile's width) background iterations reach no further than the tile beside a
// point's; an occluded pixel is not background.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(2) var<storage, read> tiles: array<u32>;
@group(0) @binding(3) var<storage, read_write> tile_lists: array<atomic<u32>>;
@group(1) @binding(0) var<uniform> step: Step;

// Whether `tile` or one beside it has its flag set, in the flags that start at `first` (those
// of the tile at 0, 0).
fn flagged_near(tile: vec2<u32>, first: u32) -> bool {
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let t = vec2<i32>(tile) + vec2<i32>(dx, dy);
            if t.x >= 0 && t.y >= 0 && t.x < i32(tiles_x()) && t.y < i32(tiles_y())
                && tiles[first + u32(t.y) * tiles_x() + u32(t.x)] != 0u {
                return true;
            }
        }
    }
    return false;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let n = tiles_x() * tiles_y();
    if id.x >= n {
        return;
    }
    let tile = vec2<u32>(id.x % tiles_x(), id.x / tiles_x());
    var listed: bool;
    if step.iteration > 0u {
        listed = flagged_near(tile, tile_slot(step.kind, step.iteration - 1u, vec2<u32>(0u)));
    } else {
        listed = step.layer > 0u || flagged_near(tile, occupied_slot(vec2<u32>(0u)));
    }
    if listed {
        let base = list_base(list_of(step.kind, step.iteration));
        let at = atomicAdd(&tile_lists[base + 3u], 1u);
        atomicStore(&tile_lists[base + LIST_HEADER + at], tile.y << 16u | tile.x);
        // The dispatch: rows of MAX_GROUPS_X workgroups, enough for every tile listed so far
        // (a list no tile joins dispatches nothing: its header stays 0, 0, 0).
        atomicMax(&tile_lists[base], min(at + 1u, MAX_GROUPS_X));
        atomicMax(&tile_lists[base + 1u], at / MAX_GROUPS_X + 1u);
        atomicStore(&tile_lists[base + 2u], 1u);
    }
}
