// Every point is drawn, whichever way it faces. The Normals stream is bound where the arena
// has one (another buffer, never read, where not: the frame's footprint is then 0).
@group(1) @binding(3) var<storage, read> normals: array<u32>;

fn culled(idx: u32, pos: vec3<f32>) -> bool {
    return false;
}
