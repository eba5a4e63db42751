//! What pipelines that reconstruct their own surface read back for the quality harness and
//! picking: the unlit colour and the surface per pixel, as their shading passes write them.

use crate::renderer::SurfacePixel;

/// RGBA8 per pixel, alpha 0 on background: the unlit colour, `None` on background.
pub fn albedo_from(bytes: &[u8]) -> Vec<Option<[u8; 3]>> {
    bytes
        .chunks_exact(4)
        .map(|c| (c[3] != 0).then_some([c[0], c[1], c[2]]))
        .collect()
}

/// Four f32 per pixel, the view-space normal then the linear depth (negative on background).
pub fn surface_from(bytes: &[u8]) -> Vec<Option<SurfacePixel>> {
    bytes
        .chunks_exact(16)
        .map(|b| {
            let f =
                |k: usize| f32::from_le_bytes([b[4 * k], b[4 * k + 1], b[4 * k + 2], b[4 * k + 3]]);
            (f(3) >= 0.0).then(|| SurfacePixel {
                depth: f(3),
                normal: Some([f(0), f(1), f(2)]),
            })
        })
        .collect()
}
