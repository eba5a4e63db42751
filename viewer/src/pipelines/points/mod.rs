//! `points`: the raw projection, each pixel the colour of its nearest point (sized in pixels or
//! by the point spacing). The baseline every chart compares against.

use super::pixel_shading::PixelShading;
use super::{GuardBand, Lighting, PipelineInfo};

static SHADING: PixelShading = PixelShading {
    info: &INFO,
    parts: &[include_str!("shade.wgsl")],
    labels: ("points finish", "points shade"),
    passes: ("finish", "shade"),
    uniforms: |_, _| {},
};

pub static INFO: PipelineInfo = PipelineInfo {
    name: "points",
    description: "the raw projection: each pixel shows its nearest point's colour",
    paper: None,
    lighting: Lighting::None,
    params: &[],
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
