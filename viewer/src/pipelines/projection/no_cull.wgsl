// Every point is drawn, whichever way it faces.
fn culled(idx: u32, pos: vec3<f32>) -> bool {
    return false;
}
