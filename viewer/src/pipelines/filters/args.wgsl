// Dispatch arguments for the next full-screen pass of a layer. A layer's shading: none where the
// layer is empty. A fill iteration: none once the previous one changed nothing (its output then
// equals its input in both buffers, so skipping the rest leaves the result where the last
// iteration would have put it); the first always runs, so that both buffers are this frame's.
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(2) var<storage, read> counters: array<u32>;
@group(0) @binding(3) var<storage, read_write> args: array<u32>;
@group(1) @binding(0) var<uniform> step: Step;

@compute @workgroup_size(1)
fn main() {
    var run = counters[step.layer] != 0u;
    if step.kind != ARGS_LAYER {
        run = step.iteration == 0u
            || counters[changed_slot(step.layer, step.kind, step.iteration - 1u)] != 0u;
    }
    let groups = vec2<u32>((frame.width + 15u) / 16u, (frame.height + 15u) / 16u);
    args[0] = select(0u, groups.x, run);
    args[1] = select(0u, groups.y, run);
    args[2] = 1u;
}
