// Fills a word buffer with EMPTY (the far end of atomicMin).
@group(0) @binding(0) var<storage, read_write> words: array<u32>;

@compute @workgroup_size(256)
fn main(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = id.x + id.y * groups.x * GROUP_SIZE;
    if i < arrayLength(&words) {
        words[i] = EMPTY;
    }
}
