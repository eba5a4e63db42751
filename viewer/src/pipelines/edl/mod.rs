//! `edl`: eye-dome lighting, the shading most point cloud viewers default to: each pixel's
//! colour darkened by how far its eight neighbours at `edl_radius` lie in front of it (log
//! depth). `EDL_WGSL` is shared: the pyramid pipeline can put it on top of its own shading.

use super::params::{ParamSpec, ResolvedParams, Scale};
use super::projection::{FrameUniforms, FusedFinish, PlaneShading};
use super::shader::ShaderSource;
use super::{Lighting, Pipeline, PipelineFrame, PipelineInfo};
use crate::ViewerError;
use crate::gpu::GpuContext;
use crate::gpu::timing::Timer;

/// `edl_factor(id, d)`: the darkening of a drawn pixel; needs `pixel_depth(i)` from the pass.
pub const EDL_WGSL: &str = include_str!("edl.wgsl");
const SHADE_WGSL: &str = include_str!("shade.wgsl");

/// The eye-dome parameters, shared with pipelines that put EDL on top of their shading.
pub const STRENGTH: ParamSpec = ParamSpec {
    name: "edl_strength",
    help: "how strongly depth edges darken",
    default: 1.0,
    min: 0.1,
    max: 4.0,
    scale: Scale::Linear,
    auto: None,
};
pub const RADIUS: ParamSpec = ParamSpec {
    name: "edl_radius",
    help: "distance in pixels of the eight neighbours compared",
    default: 1.4,
    min: 1.0,
    max: 4.0,
    scale: Scale::Linear,
    auto: None,
};

pub static INFO: PipelineInfo = PipelineInfo {
    name: "edl",
    description: "eye-dome lighting: points darkened where their neighbours lie in front",
    paper: None,
    lighting: Lighting::EyeDome,
    params: &[STRENGTH, RADIUS],
    streams: &[],
    passes: &["finish+edl", "edl"],
    previous_frame: false,
    screen_buffers: super::no_screen_buffers,
    create,
    shaders,
};

fn shaders(int64: bool) -> Vec<ShaderSource> {
    let parts = [EDL_WGSL, SHADE_WGSL];
    let mut s = FusedFinish::shaders(int64, true, "edl finish", &parts);
    s.push(PlaneShading::shader("edl shade", &parts));
    s
}

struct Edl {
    fused: FusedFinish,
    shade: PlaneShading,
}

fn create(ctx: &GpuContext) -> Result<Box<dyn Pipeline>, ViewerError> {
    let parts = [EDL_WGSL, SHADE_WGSL];
    Ok(Box::new(Edl {
        fused: FusedFinish::new(ctx, "edl finish", &parts),
        shade: PlaneShading::new(ctx, "edl shade", &parts),
    }))
}

/// Sets the eye-dome uniforms from `params` (strength 0 turns it off).
pub fn set_uniforms(params: &ResolvedParams, on: bool, uniforms: &mut FrameUniforms) {
    uniforms.shading[0] = if on {
        params.get_or(STRENGTH.name, STRENGTH.default).max(1e-3)
    } else {
        0.0
    };
    uniforms.shading[1] = params.get_or(RADIUS.name, RADIUS.default);
}

impl Pipeline for Edl {
    fn info(&self) -> &'static PipelineInfo {
        &INFO
    }

    fn fused(&self, _: &ResolvedParams) -> Option<(&FusedFinish, &'static str)> {
        Some((&self.fused, "finish+edl"))
    }

    fn uniforms(&self, params: &ResolvedParams, uniforms: &mut FrameUniforms) {
        set_uniforms(params, true, uniforms);
    }

    fn encode(
        &mut self,
        frame: &PipelineFrame,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut Timer,
    ) -> Result<(), ViewerError> {
        self.shade
            .encode(&frame.ctx.device, encoder, frame.screen, "edl", timer);
        Ok(())
    }
}
