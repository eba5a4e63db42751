//! The pyramid's uniforms (`Pyramid` in pyramid.wgsl): the paper's constants, what the passes
//! need of the frame, and the table of levels.

use super::passes::PyramidTargets;
use bytemuck::{Pod, Zeroable};

/// The paper's HPR neighbourhood size, in multiples of s0 (its section 3.1.2).
pub const HPR_SCALE_S0: f32 = 10.0;
/// Point spacing, in pixels, below which the sampling leaves no hole wider than a pixel (four
/// points or more a pixel: random sampling leaves a pixel empty 2 % of the time, and two
/// neighbours empty 0.3 %). A background pixel there looks for enclosing surface on level 0
/// only, the eight pixels about it: beyond the paper, whose 10·s0 neighbourhood takes
/// background enclosed that far for a hole, and closes the notches of a dense scan's outline
/// (between a bunny's ears). Sparser points keep the paper's neighbourhood, whose reach their
/// holes need.
pub const DENSE_SPACING_PX: f32 = 0.5;
/// Mean sector occlusion below which a pixel is a hole (the paper's 0.1 for all datasets).
pub const HPR_THRESHOLD: f32 = 0.1;
/// The pyramid level whose min depth decides each pixel's HPR neighbourhood (the paper's 4th).
pub const COARSE_LEVEL: u32 = 4;
/// Radius of the surface the normals are estimated over, in multiples of s0, where the depth
/// noise does not call for more (pyramid_noise.wgsl). The paper leaves it open. Measured with
/// the quality harness (960x720), noise-aware: 4·s0 gives 22.2 dB / SSIM 0.82 on the real
/// bunny scans and 22.6 dB / 0.78 on the clean sampled bunny, 8·s0 21.8 / 0.82 and 21.1 / 0.75
/// (a larger radius rounds off edges; without the noise estimate it was the only defence
/// against noisy normals).
pub const NORMAL_SCALE_S0: f32 = 4.0;
/// Pyramid levels at most (`MAX_LEVELS` in pyramid.wgsl).
pub const MAX_LEVELS: usize = 16;

/// Everything the pyramid passes need to know of the frame beyond `FrameUniforms`.
#[derive(Debug, Clone, Copy)]
pub struct PyramidFrame {
    /// The metric scale of the point sampling, in dataset units.
    pub s0: f32,
    pub fov_y: f32,
    pub far: f32,
    pub focal_px: f32,
    /// `light` of pyramid.wgsl's uniforms: a world light's view-space direction, and w = 1 for
    /// Blinn-Phong with the lit share.
    pub light: [f32; 4],
    /// Shade with the dataset's normals, carried through the pull-push (`stored_normals`).
    pub stored_normals: bool,
    /// The rows of the view's rotation: world directions to view space.
    pub view_rows: [[f32; 4]; 3],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct PyramidUniforms {
    pub(super) pixel_scale: [f32; 2],
    pub(super) pixel_bias: [f32; 2],
    pub(super) far: f32,
    pub(super) hpr_scale: f32,
    pub(super) normal_scale: f32,
    pub(super) threshold: f32,
    pub(super) levels: u32,
    pub(super) coarse_level: u32,
    pub(super) s0: f32,
    /// Copied on the GPU from the noise estimate (`PyramidTargets::noise`) each frame.
    pub(super) noise_scale: f32,
    pub(super) dense_scale: f32,
    /// 1: the stored normals are carried through the pull-push and shade (pyramid_stored.wgsl).
    pub(super) stored_normals: u32,
    /// Copied on the GPU from the noise estimate (`PyramidTargets::noise`) each frame.
    pub(super) stored_level: f32,
    pub(super) pad2: f32,
    pub(super) light: [f32; 4],
    pub(super) view_rows: [[f32; 4]; 3],
    pub(super) table: [[u32; 4]; MAX_LEVELS],
}

impl PyramidUniforms {
    pub(super) fn new(t: &PyramidTargets, frame: &PyramidFrame) -> PyramidUniforms {
        let top = t.levels.len() as u32 - 1;
        let tan_y = (frame.fov_y * 0.5).tan();
        let tan_x = tan_y * t.width as f32 / t.height.max(1) as f32;
        let mut params = PyramidUniforms {
            pixel_scale: [2.0 * tan_x / t.width as f32, -2.0 * tan_y / t.height as f32],
            pixel_bias: [-tan_x, tan_y],
            far: frame.far,
            hpr_scale: HPR_SCALE_S0 * frame.s0 * frame.focal_px,
            normal_scale: NORMAL_SCALE_S0 * frame.s0 * frame.focal_px,
            threshold: HPR_THRESHOLD,
            levels: t.levels.len() as u32,
            coarse_level: COARSE_LEVEL.min(top),
            s0: frame.s0,
            noise_scale: 0.0,
            dense_scale: frame.s0 * frame.focal_px / DENSE_SPACING_PX,
            stored_normals: frame.stored_normals as u32,
            stored_level: 0.0,
            pad2: 0.0,
            light: frame.light,
            view_rows: frame.view_rows,
            table: [[0; 4]; MAX_LEVELS],
        };
        for (slot, l) in params.table.iter_mut().zip(&t.levels) {
            *slot = [l[0], l[1], l[2], 0];
        }
        params
    }
}

/// Per level of a `width` x `height` pyramid: offset into the pyramid buffers, width, height.
pub(super) fn level_table(width: u32, height: u32) -> Vec<[u32; 3]> {
    let mut levels = Vec::new();
    let (mut w, mut h, mut offset) = (width.max(1), height.max(1), 0u32);
    loop {
        levels.push([offset, w, h]);
        offset += w * h;
        if (w == 1 && h == 1) || levels.len() == MAX_LEVELS {
            break;
        }
        w = w.div_ceil(2);
        h = h.div_ceil(2);
    }
    levels
}

/// `PyramidUniforms`' size and field offsets, for the check against pyramid.wgsl.
#[cfg(test)]
pub(crate) fn uniforms_layout() -> (u32, Vec<(String, u32)>) {
    macro_rules! fields {
        ($($f:ident),*) => {
            vec![$((stringify!($f).to_string(), std::mem::offset_of!(PyramidUniforms, $f) as u32)),*]
        };
    }
    (
        std::mem::size_of::<PyramidUniforms>() as u32,
        fields!(
            pixel_scale,
            pixel_bias,
            far,
            hpr_scale,
            normal_scale,
            threshold,
            levels,
            coarse_level,
            s0,
            noise_scale,
            dense_scale,
            stored_normals,
            stored_level,
            pad2,
            light,
            view_rows,
            table
        ),
    )
}
