//! `surfels` (paper 001, Luz, Velho, Carvalho 2005): every drawn point becomes a surface
//! element oriented by its normal and scaled by its radius: a planar n-gon, or near the
//! silhouette a curved c-surfel; surfels within z_o of the front surface are blended with a
//! Gaussian alpha and normalised, then lit by the shared headlight.
//!
//! Raster path: a compute rasterizer, as the projection is. Each surfel's thread ray casts the
//! pixels of its screen box against the exact n-gon or c-surfel (its mesh of rings as cone
//! frusta), and the blend sums are fixed-point atomics, so the picture does not depend on
//! the order surfels arrive in (the paper sorts its points for that reason) and the passes
//! read the node arenas and streams as they are, on every adapter the projection runs on.

mod passes;

use super::params::{ParamSpec, ResolvedParams, Scale};
use super::{
    AlbedoResult, GuardBand, Lighting, Pipeline, PipelineFrame, PipelineInfo, PointStream,
};
use crate::ViewerError;
use crate::gpu::GpuContext;
use crate::gpu::timing::Timer;
use crate::renderer::SurfacePixel;
use passes::{SurfelPasses, SurfelTargets};
use std::collections::BTreeMap;

pub use passes::SurfelUniforms;

pub static INFO: PipelineInfo = PipelineInfo {
    name: "surfels",
    description: "planar and curved surfels oriented by the normals, Gaussian blending",
    paper: Some("001_4dff551e29326432.txt (Luz, Velho, Carvalho 2005)"),
    lighting: Lighting::Headlight,
    params: &[
        ParamSpec {
            name: "mode",
            help: "planar surfels, curved c-surfels, or hybrid: c-surfels near the silhouette",
            default: 2.0,
            min: 0.0,
            max: 2.0,
            scale: Scale::Choice(&["planar", "curved", "hybrid"]),
            auto: None,
        },
        ParamSpec {
            name: "sides",
            help: "corners of a planar surfel (and of each ring of a c-surfel)",
            default: 6.0,
            min: 3.0,
            max: 32.0,
            scale: Scale::Integer,
            auto: None,
        },
        ParamSpec {
            name: "rings",
            help: "rings of the c-surfel's mesh (rings x sides polygons; the paper's 24 is 4 x 6)",
            default: 4.0,
            min: 1.0,
            max: 16.0,
            scale: Scale::Integer,
            auto: None,
        },
        ParamSpec {
            name: "epsilon",
            help: "degrees either side of 90 between view and normal where hybrid draws c-surfels",
            default: 10.0,
            min: 0.0,
            max: 20.0,
            scale: Scale::Linear,
            auto: None,
        },
        ParamSpec {
            name: "h",
            help: "the c-surfel's curvature constant h of phi(r) = 1 - exp(-(r^2/h^2)^2), radius units",
            default: 1.0,
            min: 0.2,
            max: 4.0,
            scale: Scale::Linear,
            auto: None,
        },
        ParamSpec {
            name: "curvature",
            help: "1: each c-surfel bends as far as its point's curvature (from the surface variation of --normals) asks, at most as far as h; 0: every one as far as h, as in the paper",
            default: 1.0,
            min: 0.0,
            max: 1.0,
            scale: Scale::Integer,
            auto: None,
        },
        ParamSpec {
            name: "flat_px",
            help: "c-surfels whose rim drops no further than this off their plane on the screen, in pixels, are drawn planar, at a planar one's cost (0: only flat ones)",
            default: 0.0,
            min: 0.0,
            max: 2.0,
            scale: Scale::Linear,
            auto: None,
        },
        ParamSpec {
            name: "falloff",
            help: "the Gaussian alpha's fall-off d (texture units: the rim lies at 1/2)",
            default: 0.3,
            min: 0.05,
            max: 2.0,
            scale: Scale::Log,
            auto: None,
        },
        ParamSpec {
            name: "depth_offset",
            help: "z_o, the depth behind the front surface whose surfels blend, in radii",
            default: 1.0,
            min: 0.0,
            max: 8.0,
            scale: Scale::Linear,
            auto: None,
        },
    ],
    streams: &[PointStream::Normals, PointStream::Radius],
    passes: &["surfel depth", "surfel blend", "surfel shade"],
    previous_frame: false,
    cull_back_faces: false,
    reads_colour_plane: false,
    reads_planes: false,
    screen_buffers: SurfelPasses::screen_buffers,
    uses_point_size: false,
    guard: GuardBand::None,
    create,
    shaders: |_| passes::shaders(passes::DEFAULT_SIDES),
};

/// What the pipeline says of a dataset without normals, in the panel and the stats.
pub const NO_NORMALS: &str = "the dataset has no normals (convert with --normals): surfels are discs facing the eye, sized by the node spacing, unlit";

/// The measures it reports: surfels drawn, and the share of them drawn curved.
pub const SURFELS: &str = "surfels";
pub const CURVED_SHARE: &str = "curved_share";

struct Surfels {
    passes: SurfelPasses,
    targets: Option<SurfelTargets>,
    /// The last frame's dataset had no normals.
    without_normals: bool,
    /// The last counts that arrived (planar, curved).
    counts: Option<[u32; 2]>,
}

fn create(ctx: &GpuContext) -> Result<Box<dyn Pipeline>, ViewerError> {
    Ok(Box::new(Surfels {
        passes: SurfelPasses::new(ctx)?,
        targets: None,
        without_normals: false,
        counts: None,
    }))
}

fn measures(counts: Option<[u32; 2]>) -> BTreeMap<&'static str, f32> {
    let Some([planar, curved]) = counts else {
        return BTreeMap::new();
    };
    let total = planar as f32 + curved as f32;
    BTreeMap::from([
        (SURFELS, total),
        (
            CURVED_SHARE,
            if total > 0.0 {
                curved as f32 / total
            } else {
                0.0
            },
        ),
    ])
}

impl Pipeline for Surfels {
    fn info(&self) -> &'static PipelineInfo {
        &INFO
    }

    fn make_targets(&mut self, device: &wgpu::Device, screen: &super::projection::Screen) {
        self.targets = Some(SurfelTargets::new(device, screen.width, screen.height));
    }

    fn release_targets(&mut self) {
        self.targets = None;
        self.counts = None;
    }

    fn encode(
        &mut self,
        frame: &PipelineFrame,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut Timer,
    ) -> Result<(), ViewerError> {
        let targets = self
            .targets
            .as_mut()
            .ok_or_else(|| ViewerError::Gpu("the surfels' buffers were not made".into()))?;
        self.without_normals = !frame.has_normals;
        let normals = match (frame.has_normals, frame.normals_outward) {
            (false, _) => passes::Normals::None,
            (true, true) => passes::Normals::Outward,
            (true, false) => passes::Normals::FacingEye,
        };
        let uniforms = SurfelUniforms::new(
            frame.view,
            frame.params,
            normals,
            frame.curvature_scale,
            frame.normals_mark_back_faces,
        );
        let sides = param(frame.params, "sides") as u32;
        self.passes
            .encode(frame, encoder, targets, &uniforms, sides, timer)
    }

    fn after_submit(&mut self) {
        if let Some(t) = &mut self.targets {
            t.counts_readback.after_submit();
        }
    }

    fn measures(&mut self) -> BTreeMap<&'static str, f32> {
        if let Some(bytes) = self.targets.as_mut().and_then(|t| t.counts_readback.take()) {
            self.counts = passes::counts_from(&bytes);
        }
        measures(self.counts)
    }

    fn read_measures(&self, ctx: &GpuContext) -> Result<BTreeMap<&'static str, f32>, ViewerError> {
        match &self.targets {
            Some(t) => Ok(measures(Some(t.read_counts(ctx)?))),
            None => Ok(BTreeMap::new()),
        }
    }

    fn note(&self) -> Option<&'static str> {
        self.without_normals.then_some(NO_NORMALS)
    }

    fn read_albedo(&self, ctx: &GpuContext) -> Option<AlbedoResult> {
        self.targets.as_ref().map(|t| t.read_albedo(ctx))
    }

    fn read_surface(
        &self,
        ctx: &GpuContext,
    ) -> Option<Result<Vec<Option<SurfacePixel>>, ViewerError>> {
        self.targets.as_ref().map(|t| t.read_surface(ctx))
    }
}

/// The parameters as the passes read them.
fn param(params: &ResolvedParams, name: &str) -> f32 {
    let default = INFO
        .params
        .iter()
        .find(|p| p.name == name)
        .map_or(0.0, |p| p.default);
    params.get_or(name, default)
}

#[cfg(test)]
mod intersect_tests;
#[cfg(test)]
mod tests;
