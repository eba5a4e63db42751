// How far behind the previous layer a point still belongs to it, without normals: d~.
fn layer_reach(index: u32) -> f32 {
    return fil.dtilde;
}
