//! `filters` (paper 004, Dobrev, Rosenthal, Linsen): surfaces from the projected points by
//! image filters alone. The projection culls back faces by the normals; background pixels
//! inside the silhouette and pixels showing an occluded surface are filled from their nearest
//! neighbour (3x3 masks, iterated), the layer is smoothed by the alleviated Gaussian, lit by
//! the shared light and anti-aliased by a Laplace filter on depth. Depth peeling with the
//! minimum layer distance d~ extracts further layers, each filtered the same way and blended
//! front to back with per-class opacities.

mod passes;
mod peel;
mod shadow;
mod targets;

use super::params::{Auto, ParamSpec, ResolvedParams, Scale};
use super::{AlbedoResult, Lighting, Pipeline, PipelineFrame, PipelineInfo, PointStream, ViewFrame};
use crate::ViewerError;
use crate::gpu::GpuContext;
use crate::gpu::timing::Timer;
use crate::renderer::SurfacePixel;
use passes::{FiltersPasses, FrameSetup};
use std::collections::BTreeMap;
use targets::{FiltersTargets, LayerCounts, counts_from};

pub use passes::{CLASSES, FiltersUniforms, MAX_ITERATIONS, MAX_LAYERS, Step};

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

const fn param(name: &'static str, help: &'static str, default: f32, min: f32, max: f32, scale: Scale) -> ParamSpec {
    ParamSpec {
        name,
        help,
        default,
        min,
        max,
        scale,
        auto: None,
    }
}

/// d~ left automatic, in point spacings of the nodes drawn: the depth noise of real scans
/// exceeds one spacing, and at one spacing the occluded fill keeps trading noisy depths between
/// neighbours (16 iterations on the bunny scans against 7 at four spacings).
pub const DTILDE_SPACINGS: u32 = 4;

/// Parameters before the per-class opacities.
const OWN: usize = 12;

static PARAMS: [ParamSpec; OWN + CLASSES] = {
    let own = [
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
            "Laplace anti-aliasing on depth: 0 off, 1 silhouettes, 2 all edges",
            1.0,
            0.0,
            2.0,
            Scale::Integer,
        ),
        param(
            "layers",
            "surface layers peeled and blended front to back",
            1.0,
            1.0,
            MAX_LAYERS as f32,
            Scale::Integer,
        ),
        param("opacity", "opacity of every layer's points", 1.0, 0.0, 1.0, Scale::Linear),
        param(
            "light.x",
            "direction towards a light fixed in the world, x (0,0,0: the headlight; light=X,Y,Z takes any length)",
            0.0,
            -1.0,
            1.0,
            Scale::Linear,
        ),
        param("light.y", "direction towards the light, y", 0.0, -1.0, 1.0, Scale::Linear),
        param("light.z", "direction towards the light, z", 0.0, -1.0, 1.0, Scale::Linear),
        param(
            "shadows",
            "point shadow textures: 0 off, 1 hard (a point light), 2 soft (an area light)",
            0.0,
            0.0,
            2.0,
            Scale::Integer,
        ),
        param(
            "shadow_samples",
            "light samples of soft shadows (Monte-Carlo over the area light)",
            16.0,
            1.0,
            64.0,
            Scale::Integer,
        ),
        param(
            "light_size",
            "the area light's angular diameter, degrees (soft shadows)",
            5.0,
            0.0,
            45.0,
            Scale::Linear,
        ),
        param(
            "shadow_budget",
            "points the light's own view loads for casters outside the camera's view",
            2e6,
            1e5,
            1e8,
            Scale::Log,
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
    let mut c = 0;
    while c < classes.len() {
        all[own.len() + c] = classes[c];
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
    streams: &[PointStream::Normals, shadow::LIT_STREAM],
    // In the order they first run: the peel starts the second layer.
    passes: &[
        "shadows",
        "filters resolve",
        "fill",
        "smooth",
        "filters shade",
        "peel",
    ],
    previous_frame: false,
    cull_back_faces: true,
    screen_buffers: FiltersTargets::screen_buffers,
    create,
    shaders: |int64| {
        let mut all = passes::shaders(int64);
        all.extend(shadow::shaders());
        all
    },
};

/// What the pipeline says where it cannot cull: without normals, and with normals that may
/// face into a surface.
pub const NO_NORMALS: &str = "the dataset has no normals (convert with --normals): no back-face culling, normals estimated from the filled depth";
pub const NOT_OUTWARD: &str = "the dataset's normals are not known to face out of every surface (computed with --orient up or none; kept or --orient scanner normals are): no back-face culling";

/// The unit direction towards a light fixed in the world, `None` for the headlight.
fn world_light(params: &ResolvedParams) -> Option<glam::Vec3> {
    glam::Vec3::new(
        value(params, "light.x"),
        value(params, "light.y"),
        value(params, "light.z"),
    )
    .try_normalize()
}

/// `shadows`: off, hard, soft.
const SHADOWS_OFF: u32 = 0;
const SHADOWS_HARD: u32 = 1;

/// The measures it reports.
pub const LAYERS_USED: &str = "layers_used";
pub const BACKGROUND_ITERATIONS: &str = "background_fill_iterations";
pub const OCCLUDED_ITERATIONS: &str = "occluded_fill_iterations";

struct Filters {
    passes: FiltersPasses,
    shadows: shadow::Shadows,
    targets: Option<FiltersTargets>,
    note: Option<&'static str>,
    counts: Option<LayerCounts>,
}

fn create(ctx: &GpuContext) -> Result<Box<dyn Pipeline>, ViewerError> {
    Ok(Box::new(Filters {
        passes: FiltersPasses::new(ctx)?,
        shadows: shadow::Shadows::new(&ctx.device)?,
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
    let default = PARAMS.iter().find(|p| p.name == name).map_or(0.0, |p| p.default);
    params.get_or(name, default)
}

/// The uniforms of one frame.
pub fn uniforms(view: &ViewFrame, params: &ResolvedParams, has_normals: bool) -> FiltersUniforms {
    let rays = view.pixel_rays();
    let light = match world_light(params) {
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
        antialias: value(params, "antialias") as u32,
        normals: has_normals as u32,
        opacity: value(params, "opacity"),
        lit_scale: 0.0,
        pad0: 0.0,
        pad1: 0.0,
        pad2: 0.0,
    }
}

impl Pipeline for Filters {
    fn info(&self) -> &'static PipelineInfo {
        &INFO
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
        if value(params, "shadows") as u32 == SHADOWS_OFF {
            return None;
        }
        let forward = (camera.target - camera.eye).normalize_or(glam::Vec3::NEG_Z);
        let light = world_light(params).unwrap_or(-forward);
        Some((
            shadow::light_camera(light, bounds),
            value(params, "shadow_budget") as u64,
        ))
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
        let setup = FrameSetup {
            layers: value(frame.params, "layers") as u32,
            fill_iterations: value(frame.params, "fill_iterations") as u32,
            cull: frame.back_faces_culled,
        };
        let mut u = uniforms(frame.view, frame.params, frame.has_normals);
        let mode = value(frame.params, "shadows") as u32;
        if mode != SHADOWS_OFF {
            // With the headlight the light comes from the eye: shadows hide behind their casters.
            let light = world_light(frame.params)
                .unwrap_or(-glam::Vec3::from_slice(&u.forward[..3]));
            let setup = shadow::ShadowSetup {
                samples: if mode == SHADOWS_HARD {
                    1
                } else {
                    value(frame.params, "shadow_samples") as u32
                },
                light,
                light_size: value(frame.params, "light_size").to_radians(),
                dtilde: u.dtilde,
                normals: frame.has_normals,
                bounds: frame.bounds,
            };
            u.lit_scale = self.shadows.encode(frame, encoder, &setup, timer)?;
        }
        self.passes.encode(frame, encoder, targets, &u, &setup, timer)
    }

    fn after_submit(&mut self) {
        if let Some(t) = &mut self.targets {
            t.counters_readback.after_submit();
        }
    }

    fn measures(&mut self) -> BTreeMap<&'static str, f32> {
        if let Some(bytes) = self.targets.as_mut().and_then(|t| t.counters_readback.take()) {
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
