//! `edl`: eye-dome lighting, the shading most point cloud viewers default to: each pixel's
//! colour darkened by how far its eight neighbours at `edl_radius` lie in front of it (log
//! depth). `EDL_WGSL` is shared: the pyramid pipeline can put it on top of its own shading.

use super::params::{ParamSpec, ResolvedParams, Scale};
use super::pixel_shading::PixelShading;
use super::projection::FrameUniforms;
use super::{GuardBand, Lighting, PipelineInfo};

/// `edl_factor(id, d)`: the darkening of a drawn pixel; needs `pixel_depth(i)` from the pass.
pub const EDL_WGSL: &str = include_str!("edl.wgsl");

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
    help: "distance in pixels of the eight neighbours compared, each taken at the pixel nearest its direction (as Potree's nearest-filtered lookups do): the image changes where a neighbour moves to another pixel",
    default: 1.4,
    min: 1.0,
    max: 4.0,
    scale: Scale::Linear,
    auto: None,
};

static SHADING: PixelShading = PixelShading {
    info: &INFO,
    parts: &[EDL_WGSL, include_str!("shade.wgsl")],
    labels: ("edl finish", "edl shade"),
    passes: ("finish+edl", "edl"),
    uniforms: |params, uniforms| set_uniforms(params, true, uniforms),
};

pub static INFO: PipelineInfo = PipelineInfo {
    name: "edl",
    description: "eye-dome lighting: points darkened where their neighbours lie in front",
    paper: None,
    lighting: Lighting::EyeDome,
    params: &[STRENGTH, RADIUS],
    streams: &[],
    passes: &[SHADING.passes.0, SHADING.passes.1],
    previous_frame: false,
    cull_back_faces: false,
    reads_colour_plane: true,
    reads_planes: true,
    screen_buffers: super::no_screen_buffers,
    uses_point_size: true,
    guard: GuardBand::None,
    create: |ctx| Ok(SHADING.create(ctx)),
    shaders: |int64| SHADING.shaders(int64),
};

/// Sets the eye-dome uniforms from `params` (strength 0 turns it off).
pub fn set_uniforms(params: &ResolvedParams, on: bool, uniforms: &mut FrameUniforms) {
    uniforms.shading[0] = if on {
        params.get_or(STRENGTH.name, STRENGTH.default).max(1e-3)
    } else {
        0.0
    };
    uniforms.shading[1] = params.get_or(RADIUS.name, RADIUS.default);
}
