//! A pipeline that is only a shading of each pixel's nearest point (`points`, `edl`): the fused
//! finish where the frame allows, else one pass over the resolved planes, both composed with the
//! pipeline's WGSL `shade_pixel`.

use super::params::ResolvedParams;
use super::projection::{FrameUniforms, FusedFinish, PlaneShading};
use super::shader::ShaderSource;
use super::{Pipeline, PipelineFrame, PipelineInfo};
use crate::ViewerError;
use crate::gpu::GpuContext;
use crate::gpu::timing::Timer;

/// What such a pipeline is made of.
pub struct PixelShading {
    pub info: &'static PipelineInfo,
    /// The WGSL defining `shade_pixel`, and what it needs.
    pub parts: &'static [&'static str],
    /// Module labels: the fused finish, the separate shading pass.
    pub labels: (&'static str, &'static str),
    /// Timed pass names: the fused finish, the separate shading pass.
    pub passes: (&'static str, &'static str),
    /// Sets the frame uniforms its shading reads.
    pub uniforms: fn(&ResolvedParams, &mut FrameUniforms),
}

impl PixelShading {
    /// Every module it compiles.
    pub fn shaders(&self, int64: bool) -> Vec<ShaderSource> {
        let mut s = FusedFinish::shaders(int64, true, self.labels.0, self.parts);
        s.push(PlaneShading::shader(self.labels.1, self.parts));
        s
    }

    pub fn create(&'static self, ctx: &GpuContext) -> Box<dyn Pipeline> {
        Box::new(Compiled {
            spec: self,
            fused: FusedFinish::new(ctx, self.labels.0, self.parts),
            shade: PlaneShading::new(ctx, self.labels.1, self.parts),
        })
    }
}

struct Compiled {
    spec: &'static PixelShading,
    fused: FusedFinish,
    shade: PlaneShading,
}

impl Pipeline for Compiled {
    fn info(&self) -> &'static PipelineInfo {
        self.spec.info
    }

    fn fused(&self, _: &ResolvedParams) -> Option<(&FusedFinish, &'static str)> {
        Some((&self.fused, self.spec.passes.0))
    }

    fn uniforms(&self, params: &ResolvedParams, uniforms: &mut FrameUniforms) {
        (self.spec.uniforms)(params, uniforms);
    }

    fn encode(
        &mut self,
        frame: &PipelineFrame,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut Timer,
    ) -> Result<(), ViewerError> {
        let name = self.spec.passes.1;
        self.shade
            .encode(&frame.ctx.device, encoder, frame.screen, name, timer);
        Ok(())
    }
}
