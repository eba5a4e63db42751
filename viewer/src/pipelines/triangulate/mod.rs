//! `triangulate` (paper 002, Preiner and Wimmer 2012): closed surfaces from positions and
//! colours alone (and shaded with the dataset's normals where it has them). Each frame projects the points one pixel each, culled against the previous
//! frame's reconstructed depth reprojected into this view (a culled point draws no fan but
//! stays a neighbour, gather.wgsl); every point finds its nearest
//! neighbour in each of eight screen sectors within its world-space search radius (one pass of
//! 64-bit keys, or two: distance, then id), estimates a normal from the fan of those neighbours and rasterizes the
//! fan, colours and normals summed and normalised, depth by minimum; each point's search radius
//! is kept beside its arena and adapted from the distances at which neighbours took it.
//! Where the dataset has normals, they shade in place of the fans' (`stored_normals`); where
//! they tell a surface's sides apart, the search joins no two points on opposite sides
//! (search.wgsl), and the fans of the points facing away blend apart, shown only where the
//! front faces' fans leave a pixel empty (raster.wgsl).
//!
//! Raster path: a compute rasterizer with fixed-point atomic sums (raster.wgsl), as the
//! projection and the surfels are: the sums do not depend on the order triangles arrive in, and
//! the depth minimum and the colour sums need no blendable float targets (which the GL backend
//! lacks for 32-bit floats).

mod passes;
mod targets;

use super::params::{Auto, ParamSpec, ResolvedParams, Scale};
use super::projection::FrameUniforms;
use super::{
    AlbedoResult, GuardBand, Lighting, Pipeline, PipelineFrame, PipelineInfo, PointStream,
    ViewFrame,
};
use crate::ViewerError;
use crate::gpu::GpuContext;
use crate::gpu::timing::Timer;
use crate::renderer::SurfacePixel;
use passes::{RADIUS_STREAM, TriangulatePasses};
use std::collections::BTreeMap;
use targets::{Counts, TriangulateTargets, counts_from};

pub use passes::TriangulateUniforms;

/// `max_connection` left automatic, in point spacings of the nodes drawn (`lod::drawn_spacing`,
/// measured from the points: one over the root of their density). Scattered at random, a 45°
/// sector round a point holds none within r with probability exp(-π r² / 8 s²): 1 in 500 at
/// four spacings, 1 in 20 000 at five. Seen at a grazing angle a screen sector spans a thinner
/// wedge of the surface, and four left 0.4 % of a plane seen at 85° open; six closed it but
/// bridged the gaps of sparse curved shapes (the bunny at 0.1 points a pixel lost 1.4 dB).
pub const CONNECTION_SPACINGS: u32 = 5;

/// Node spacings a point's connections may span where `max_connection` is automatic and its
/// node is coarser than the median (far away, or standing for children not drawn): within a
/// node, points lie at least a spacing apart and a sector's nearest within two.
pub const NODE_SPACINGS: f32 = 2.0;

static PARAMS: [ParamSpec; 4] = [
    ParamSpec {
        name: "max_connection",
        help: "the largest search radius, in dataset units; never under three pixels at the point (auto: five spacings of the points drawn, measured from them, and two of the point's own node)",
        default: 1.0,
        min: 1e-9,
        max: 1e9,
        scale: Scale::Log,
        auto: Some(Auto::DrawnSpacings(CONNECTION_SPACINGS)),
    },
    ParamSpec {
        name: "max_search_px",
        help: "the largest search splat, in pixels either side of a point",
        default: 24.0,
        min: 1.0,
        // A triangle spans at most two splats: 2 x 47 + 2 = MAX_TRIANGLE_PX (uniforms.wgsl).
        max: 47.0,
        scale: Scale::Integer,
        auto: None,
    },
    ParamSpec {
        name: "stored_normals",
        help: "shade with the dataset's normals where it has them (off: with the normals of each point's fan, the paper's, as for a dataset without)",
        default: 1.0,
        min: 0.0,
        max: 1.0,
        scale: Scale::Toggle,
        auto: None,
    },
    ParamSpec {
        name: "warmup",
        help: "frames of the same view rendered before a still image is taken (headless)",
        default: 8.0,
        min: 0.0,
        max: 64.0,
        scale: Scale::Integer,
        auto: None,
    },
];

pub static INFO: PipelineInfo = PipelineInfo {
    name: "triangulate",
    description: "screen-space triangulation of the points' sector neighbours, temporally coherent",
    paper: Some("002_d515157fc103e054.txt (Preiner, Wimmer 2012)"),
    lighting: Lighting::Headlight,
    params: &PARAMS,
    streams: &[RADIUS_STREAM, PointStream::Normals],
    passes: &[
        "reproject",
        "triangulate gather",
        "search",
        "search distances",
        "search ids",
        "normals",
        "triangulate",
        "radii",
        "triangulate shade",
        "holes",
    ],
    previous_frame: true,
    cull_back_faces: false,
    reads_colour_plane: true,
    reads_planes: true,
    screen_buffers: TriangulateTargets::screen_buffers,
    uses_point_size: false,
    guard: GuardBand::Param {
        name: "max_search_px",
        extra: 1,
    },
    create,
    shaders: passes::shaders,
};

/// The measures it reports.
pub const HOLE_RATE: &str = "hole_rate";
pub const TRIANGLES: &str = "triangles";
pub const CULLED: &str = "culled_points";

struct Triangulate {
    passes: TriangulatePasses,
    targets: Option<TriangulateTargets>,
    counts: Option<Counts>,
    /// The device has 64-bit atomics: the sector search is one pass.
    int64: bool,
    /// And 64-bit atomic adds: the blend sums are 64-bit.
    sums64: bool,
}

fn create(ctx: &GpuContext) -> Result<Box<dyn Pipeline>, ViewerError> {
    Ok(Box::new(Triangulate {
        passes: TriangulatePasses::new(ctx)?,
        targets: None,
        counts: None,
        int64: ctx.int64_atomics,
        sums64: ctx.int64_sums,
    }))
}

fn value(params: &ResolvedParams, name: &str) -> f32 {
    let default = PARAMS
        .iter()
        .find(|p| p.name == name)
        .map_or(0.0, |p| p.default);
    params.get_or(name, default)
}

fn measures(counts: Option<Counts>) -> BTreeMap<&'static str, f32> {
    counts
        .map(|c| {
            BTreeMap::from([
                (HOLE_RATE, c.hole_rate()),
                (TRIANGLES, c.triangles as f32),
                (CULLED, c.culled as f32),
            ])
        })
        .unwrap_or_default()
}

/// The uniforms of one frame; `previous`: the view of the frame whose depth is kept;
/// `has_normals`: the dataset stores normals.
pub fn uniforms(
    view: &ViewFrame,
    previous: Option<&ViewFrame>,
    params: &ResolvedParams,
    has_normals: bool,
) -> TriangulateUniforms {
    let rays = view.pixel_rays();
    let prev = previous.map(ViewFrame::pixel_rays).unwrap_or(rays);
    let max_connection = value(params, "max_connection");
    TriangulateUniforms {
        eye: rays.eye,
        forward: rays.forward,
        right: rays.right,
        up: rays.up,
        prev_eye: prev.eye,
        prev_forward: prev.forward,
        prev_right: prev.right,
        prev_up: prev.up,
        max_connection,
        spacing_factor: if params.is_auto("max_connection") {
            NODE_SPACINGS
        } else {
            0.0
        },
        previous: previous.is_some() as u32,
        max_search_px: value(params, "max_search_px") as u32,
        stored_normals: (has_normals && value(params, "stored_normals") != 0.0) as u32,
        pad0: 0,
        pad1: 0,
        pad2: 0,
    }
}

impl Pipeline for Triangulate {
    fn info(&self) -> &'static PipelineInfo {
        &INFO
    }

    fn uniforms(&self, _: &ResolvedParams, uniforms: &mut FrameUniforms) {
        // The paper projects every point to one pixel.
        uniforms.point_size = 1.0;
        uniforms.size_mode = 0;
    }

    fn make_targets(&mut self, device: &wgpu::Device, screen: &super::projection::Screen) {
        self.targets = Some(TriangulateTargets::new(
            device,
            screen.width,
            screen.height,
            self.int64,
            self.sums64,
        ));
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
            .ok_or_else(|| ViewerError::Gpu("the triangulation's buffers were not made".into()))?;
        let u = uniforms(
            frame.view,
            frame.previous.as_ref(),
            frame.params,
            frame.has_normals,
        );
        self.passes.encode(frame, encoder, targets, &u, timer)?;
        Ok(())
    }

    fn kept_depth(&self) -> Option<&wgpu::Buffer> {
        self.targets.as_ref().map(|t| &t.reconstructed)
    }

    fn after_submit(&mut self) {
        if let Some(t) = &mut self.targets {
            t.counts_readback.after_submit();
        }
    }

    fn measures(&mut self) -> BTreeMap<&'static str, f32> {
        if let Some(bytes) = self.targets.as_mut().and_then(|t| t.counts_readback.take()) {
            self.counts = counts_from(&bytes);
        }
        measures(self.counts)
    }

    fn read_measures(&self, ctx: &GpuContext) -> Result<BTreeMap<&'static str, f32>, ViewerError> {
        match &self.targets {
            Some(t) => Ok(measures(Some(t.read_counts(ctx)?))),
            None => Ok(BTreeMap::new()),
        }
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

#[cfg(test)]
mod holes_tests;
#[cfg(test)]
mod sector_tests;
#[cfg(test)]
mod sums_tests;
#[cfg(test)]
mod tests;
