//! `points`: the raw projection, each pixel the colour of its nearest point (sized in pixels or
//! by the point spacing). The baseline every chart compares against.

use super::projection::{FusedFinish, PlaneShading};
use super::shader::ShaderSource;
use super::{Lighting, Pipeline, PipelineFrame, PipelineInfo, params::ResolvedParams};
use crate::ViewerError;
use crate::gpu::GpuContext;
use crate::gpu::timing::Timer;

const SHADE_WGSL: &str = include_str!("shade.wgsl");

pub static INFO: PipelineInfo = PipelineInfo {
    name: "points",
    description: "the raw projection: each pixel shows its nearest point's colour",
    paper: None,
    lighting: Lighting::None,
    params: &[],
    streams: &[],
    passes: &["finish", "shade"],
    previous_frame: false,
    screen_buffers: super::no_screen_buffers,
    create,
    shaders,
};

fn shaders(int64: bool) -> Vec<ShaderSource> {
    let mut s = FusedFinish::shaders(int64, true, "points finish", &[SHADE_WGSL]);
    s.push(PlaneShading::shader("points shade", &[SHADE_WGSL]));
    s
}

struct Points {
    fused: FusedFinish,
    shade: PlaneShading,
}

fn create(ctx: &GpuContext) -> Result<Box<dyn Pipeline>, ViewerError> {
    Ok(Box::new(Points {
        fused: FusedFinish::new(ctx, "points finish", &[SHADE_WGSL]),
        shade: PlaneShading::new(ctx, "points shade", &[SHADE_WGSL]),
    }))
}

impl Pipeline for Points {
    fn info(&self) -> &'static PipelineInfo {
        &INFO
    }

    fn fused(&self, _: &ResolvedParams) -> Option<(&FusedFinish, &'static str)> {
        Some((&self.fused, "finish"))
    }

    fn encode(
        &mut self,
        frame: &PipelineFrame,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut Timer,
    ) -> Result<(), ViewerError> {
        self.shade
            .encode(&frame.ctx.device, encoder, frame.screen, "shade", timer);
        Ok(())
    }
}
