// Dispatch arguments of a peeled layer's shading: none where the layer is empty. (A fill
// iteration's are the count of its tile list.)
@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(2) var<storage, read> counters: array<u32>;
@group(0) @binding(3) var<storage, read_write> args: array<u32>;
@group(1) @binding(0) var<uniform> step: Step;

@compute @workgroup_size(1)
fn main() {
    let run = counters[step.layer] != 0u;
    args[0] = select(0u, tiles_x(), run);
    args[1] = select(0u, tiles_y(), run);
    args[2] = 1u;
}
