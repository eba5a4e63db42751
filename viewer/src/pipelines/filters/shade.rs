//! The shade pass compiled per mode: anti-aliasing, normals estimated or carried, headlight or
//! a world light. These are `override` constants of shade.wgsl, fixed when the pipeline is
//! made, not uniforms, so that each compiled pass holds only its own mode's code (see
//! `ShaderSource::constants`: on a software adapter a branch costs both its sides).

use super::passes::UNIFORMS_WGSL;
use crate::pipelines::LIGHTING_WGSL;
use crate::pipelines::projection::OCT16_WGSL;
use crate::pipelines::shader::{ShaderSource, Variants};

const SMOOTH_WGSL: &str = include_str!("smooth.wgsl");
const SHADE_WGSL: &str = include_str!("shade.wgsl");

/// The mode one shade pipeline is compiled for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ShadeVariant {
    /// The `antialias` parameter: 0 off, 1 silhouettes, 2 all edges (`ANTIALIAS_*`).
    pub antialias: u32,
    /// The points carry no normals: the shading estimates them from the filled depth. Where
    /// they do, a point the converter could give none (too few neighbours) faces the eye.
    pub estimate_normals: bool,
    /// Blinn-Phong from the world light with each point's lit share (a light fixed in the world,
    /// or shadows); else the headlight.
    pub phong: bool,
}

impl Default for ShadeVariant {
    /// The parameters' defaults on a dataset with normals.
    fn default() -> ShadeVariant {
        ShadeVariant {
            antialias: 1,
            estimate_normals: false,
            phong: false,
        }
    }
}

impl ShadeVariant {
    pub fn source(self) -> ShaderSource {
        ShaderSource::new(
            "filters shade",
            &[
                UNIFORMS_WGSL,
                OCT16_WGSL,
                LIGHTING_WGSL,
                SHADE_WGSL,
                SMOOTH_WGSL,
            ],
        )
        .with_constant("ANTIALIAS", self.antialias as f64)
        .with_constant("ESTIMATE_NORMALS", self.estimate_normals as u32 as f64)
        .with_constant("PHONG", self.phong as u32 as f64)
    }
}

/// The shade pipelines compiled so far, one per variant a frame asked for.
pub type ShadePipelines = Variants<ShadeVariant, wgpu::ComputePipeline>;
