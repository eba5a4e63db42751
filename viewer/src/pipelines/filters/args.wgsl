// Dispatch arguments for the next pass of a layer. A layer's shading: none where the layer is
// empty. A fill iteration: a workgroup per tile of the list tiles.wgsl made (in the first
// iteration every tile that can change, so that both buffers are this frame's; none once an
// iteration changed nothing, its output then equal to its input in both buffers).
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(2) var<storage, read> counters: array<u32>;
@group(0) @binding(3) var<storage, read_write> args: array<u32>;
// [0]: the tiles a fill iteration works on (tiles.wgsl); read and reset to 0 for the next.
@group(0) @binding(4) var<storage, read_write> tile_list: array<u32>;
@group(1) @binding(0) var<uniform> step: Step;

@compute @workgroup_size(1)
fn main() {
    if step.kind != ARGS_LAYER {
        // A workgroup per listed tile.
        args[0] = tile_list[0];
        args[1] = 1u;
        args[2] = 1u;
        tile_list[0] = 0u;
        return;
    }
    let run = counters[step.layer] != 0u;
    args[0] = select(0u, tiles_x(), run);
    args[1] = select(0u, tiles_y(), run);
    args[2] = 1u;
}
