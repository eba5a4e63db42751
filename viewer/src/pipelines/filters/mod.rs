//! `filters` (paper 004, Dobrev, Rosenthal, Linsen): surfaces from the projected points by
//! image filters alone. The projection culls back faces by the normals; background pixels
//! inside the silhouette are filled from their nearest neighbour, pixels showing an occluded
//! surface from the farthest neighbour in front of them (3x3 masks, iterated), the layer is smoothed by the alleviated Gaussian, lit by
//! the shared light and anti-aliased by a Laplace filter on depth. Depth peeling with the
//! minimum layer distance d~ extracts further layers, each filtered the same way and blended
//! front to back with per-class opacities.

mod passes;
mod peel;
mod shade;
mod targets;

use super::params::{Auto, ParamSpec, ResolvedParams, Scale};
use super::shadows::{self, LIT_STREAM, param};
use super::{
    AlbedoResult, GuardBand, Lighting, Pipeline, PipelineFrame, PipelineInfo, PointStream,
    ViewFrame,
};
use crate::ViewerError;
use crate::gpu::GpuContext;
use crate::gpu::timing::Timer;
use crate::renderer::SurfacePixel;
use passes::{FiltersPasses, FrameSetup};
use shade::ShadeVariant;
use std::collections::BTreeMap;
use targets::{FiltersTargets, LayerCounts, counts_from};

pub use passes::{CLASSES, FiltersUniforms, MAX_ITERATIONS, MAX_LAYERS, Step};
pub(crate) use passes::{MASKS_WGSL, bind};
pub use shadows::DTILDE_SPACINGS;

/// `opacity.C`: the opacity factor of class C, one spec per ASPRS standard class.
macro_rules! class_opacities {
    ($($class:literal: $name:literal),* $(,)?) => {
        [$(ParamSpec {
            name: concat!("opacity.", $class),
            help: concat!("opacity factor of class ", $class, " (", $name, ")"),
            default: 1.0,
            min: 0.0,
            max: 1.0,
            scale: Scale::Linear,
            auto: None,
        }),*]
    };
}

/// The filters' own parameters.
const OWN_COUNT: usize = 6;
/// Parameters before the per-class opacities: the filters' own, then the light and shadows'.
const OWN: usize = OWN_COUNT + shadows::PARAMS.len();

static PARAMS: [ParamSpec; OWN + CLASSES] = {
    let own: [ParamSpec; OWN_COUNT] = [
        ParamSpec {
            name: "dtilde",
            help: "d~, the minimum distance between two surface layers, in dataset units (auto: a few point spacings)",
            default: 1.0,
            min: 1e-9,
            max: 1e9,
            scale: Scale::Log,
            auto: Some(Auto::DrawnSpacings(DTILDE_SPACINGS)),
        },
        param(
            "fill_iterations",
            "fill iterations at most per kind (background, occluded); they stop once nothing changes",
            16.0,
            0.0,
            MAX_ITERATIONS as f32,
            Scale::Integer,
        ),
        param(
            "antialias",
            "Laplace anti-aliasing on depth, at silhouettes or at all edges",
            1.0,
            0.0,
            2.0,
            Scale::Choice(&["off", "silhouettes", "edges"]),
        ),
        param(
            "layers",
            "surface layers peeled and blended front to back",
            1.0,
            1.0,
            MAX_LAYERS as f32,
            Scale::Integer,
        ),
        param(
            "opacity",
            "opacity of every layer's points",
            1.0,
            0.0,
            1.0,
            Scale::Linear,
        ),
        param(
            "splat",
            "points drawn at least this many stored radii across, so that sparse ones leave gaps the masks can close (0: one pixel each, as in the paper)",
            1.25,
            0.0,
            2.0,
            Scale::Linear,
        ),
    ];
    let classes = class_opacities![
        0: "created, never classified",
        1: "unclassified",
        2: "ground",
        3: "low vegetation",
        4: "medium vegetation",
        5: "high vegetation",
        6: "building",
        7: "low point (noise)",
        8: "reserved / model key-point",
        9: "water",
        10: "rail",
        11: "road surface",
        12: "reserved / overlap",
        13: "wire guard",
        14: "wire conductor",
        15: "transmission tower",
        16: "wire-structure connector",
        17: "bridge deck",
        18: "high noise",
    ];
    let mut all = [own[0]; OWN + CLASSES];
    let mut k = 0;
    while k < own.len() {
        all[k] = own[k];
        k += 1;
    }
    let mut l = 0;
    while l < shadows::PARAMS.len() {
        all[own.len() + l] = shadows::PARAMS[l];
        l += 1;
    }
    let mut c = 0;
    while c < classes.len() {
        all[OWN + c] = classes[c];
        c += 1;
    }
    all
};

pub static INFO: PipelineInfo = PipelineInfo {
    name: "filters",
    description: "image-space hole filling, smoothing and anti-aliasing; depth-peeled transparency",
    paper: Some("004_d47bc4d6e82cf0e9.txt (Dobrev, Rosenthal, Linsen)"),
    lighting: Lighting::Headlight,
    params: &PARAMS,
    streams: &[PointStream::Normals, PointStream::Radius, LIT_STREAM],
    // In the order they first run: the peel starts the second layer.
    passes: &[
        "shadows",
        "filters resolve",
        "fill",
        "filters shade",
        "peel",
    ],
    previous_frame: false,
    cull_back_faces: true,
    reads_colour_plane: false,
    reads_planes: false,
    screen_buffers: FiltersTargets::screen_buffers,
    uses_point_size: true,
    guard: GuardBand::Param {
        name: "fill_iterations",
        extra: 2,
    },
    create,
    shaders: |int64| {
        let mut all = passes::shaders(int64);
        all.extend(shadows::shaders());
        all
    },
};

/// What the pipeline says where it cannot cull: without normals, and with normals that may
/// face into a surface.
pub const NO_NORMALS: &str = "the dataset has no normals (convert with --normals): no back-face culling, normals estimated from the filled depth";
pub const NOT_OUTWARD: &str = "the dataset's normals are not known to face out of every surface (computed with --orient up or none, or pointing either way in this view; kept or --orient scanner normals are): no back-face culling";

/// The measures it reports.
pub const LAYERS_USED: &str = "layers_used";
pub const BACKGROUND_ITERATIONS: &str = "background_fill_iterations";
pub const OCCLUDED_ITERATIONS: &str = "occluded_fill_iterations";

struct Filters {
    passes: FiltersPasses,
    shadows: shadows::Shadows,
    targets: Option<FiltersTargets>,
    note: Option<&'static str>,
    counts: Option<LayerCounts>,
}

fn create(ctx: &GpuContext) -> Result<Box<dyn Pipeline>, ViewerError> {
    Ok(Box::new(Filters {
        passes: FiltersPasses::new(ctx)?,
        shadows: shadows::Shadows::new(&ctx.device)?,
        targets: None,
        note: None,
        counts: None,
    }))
}

fn measures(counts: Option<LayerCounts>) -> BTreeMap<&'static str, f32> {
    counts
        .map(|c| {
            BTreeMap::from([
                (LAYERS_USED, c.layers_used as f32),
                (BACKGROUND_ITERATIONS, c.background_iterations as f32),
                (OCCLUDED_ITERATIONS, c.occluded_iterations as f32),
            ])
        })
        .unwrap_or_default()
}

fn value(params: &ResolvedParams, name: &str) -> f32 {
    let default = PARAMS
        .iter()
        .find(|p| p.name == name)
        .map_or(0.0, |p| p.default);
    params.get_or(name, default)
}

/// The uniforms of one frame.
pub fn uniforms(view: &ViewFrame, params: &ResolvedParams, has_normals: bool) -> FiltersUniforms {
    let rays = view.pixel_rays();
    let light = match shadows::world_light(params) {
        Some(l) => [l.x, l.y, l.z, 1.0],
        None => [0.0; 4],
    };
    let mut class_opacity = [[1.0f32; 4]; 5];
    for c in 0..CLASSES {
        class_opacity[c / 4][c % 4] = value(params, PARAMS[OWN + c].name);
    }
    FiltersUniforms {
        eye: rays.eye,
        forward: rays.forward,
        right: rays.right,
        up: rays.up,
        light,
        class_opacity,
        dtilde: value(params, "dtilde"),
        normals: has_normals as u32,
        opacity: value(params, "opacity"),
        lit_scale: 0.0,
        pad0: 0.0,
        pad1: 0.0,
        pad2: 0.0,
        pad3: 0.0,
    }
}

/// The shade pass for a frame with these parameters and uniforms.
pub fn shade_variant(params: &ResolvedParams, u: &FiltersUniforms) -> ShadeVariant {
    ShadeVariant {
        antialias: value(params, "antialias") as u32,
        estimate_normals: u.normals == 0,
        phong: u.light[3] != 0.0 || u.lit_scale != 0.0,
    }
}

impl Pipeline for Filters {
    fn info(&self) -> &'static PipelineInfo {
        &INFO
    }

    fn uniforms(&self, params: &ResolvedParams, uniforms: &mut super::projection::FrameUniforms) {
        uniforms.footprint = value(params, "splat");
    }

    fn make_targets(&mut self, device: &wgpu::Device, screen: &super::projection::Screen) {
        self.targets = Some(FiltersTargets::new(device, screen.width, screen.height));
    }

    fn release_targets(&mut self) {
        self.targets = None;
        self.counts = None;
        self.shadows.reset();
    }

    fn extra_view(
        &self,
        params: &ResolvedParams,
        camera: &crate::Camera,
        bounds: [glam::Vec3; 2],
    ) -> Option<(crate::Camera, u64)> {
        shadows::extra_view(params, camera, bounds)
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
            .ok_or_else(|| ViewerError::Gpu("the filters' buffers were not made".into()))?;
        self.note = match (frame.has_normals, frame.back_faces_culled) {
            (false, _) => Some(NO_NORMALS),
            (true, false) => Some(NOT_OUTWARD),
            (true, true) => None,
        };
        let mut u = uniforms(frame.view, frame.params, frame.has_normals);
        let forward = glam::Vec3::from_slice(&u.forward[..3]);
        if let Some(shadow) = shadows::setup(frame, forward, u.dtilde) {
            u.lit_scale = self.shadows.encode(frame, encoder, &shadow, timer)?;
        }
        let setup = FrameSetup {
            layers: value(frame.params, "layers") as u32,
            fill_iterations: value(frame.params, "fill_iterations") as u32,
            cull: frame.back_faces_culled,
            shade: shade_variant(frame.params, &u),
        };
        self.passes
            .encode(frame, encoder, targets, &u, &setup, timer)
    }

    fn after_submit(&mut self) {
        if let Some(t) = &mut self.targets {
            t.counters_readback.after_submit();
        }
    }

    fn measures(&mut self) -> BTreeMap<&'static str, f32> {
        if let Some(bytes) = self
            .targets
            .as_mut()
            .and_then(|t| t.counters_readback.take())
        {
            self.counts = counts_from(&bytes);
        }
        measures(self.counts)
    }

    fn read_measures(&self, ctx: &GpuContext) -> Result<BTreeMap<&'static str, f32>, ViewerError> {
        match &self.targets {
            Some(t) => Ok(measures(counts_from(&t.read_counters(ctx)?))),
            None => Ok(BTreeMap::new()),
        }
    }

    fn note(&self) -> Option<&'static str> {
        self.note
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
mod tests;
