//! `pyramid` (paper 003, Bouchiba, Deschaud, Goulette 2018): closed, shaded surfaces from the
//! projected points by a min-depth point pyramid, pyramidal hidden-point removal, pull-push
//! filling, multi-level normals and deferred headlight shading (`passes`).

mod lit;
mod passes;
mod stored;

mod hpr;
mod uniforms;
pub use hpr::HprShape;
pub use passes::{NOISE_BINS, depth_noise_from};
pub use uniforms::{
    COARSE_LEVEL, HPR_SCALE_S0, HPR_THRESHOLD, MAX_LEVELS, NORMAL_SCALE_S0, PyramidFrame,
};

use super::params::{Auto, ParamSpec, ResolvedParams, Scale};
use super::projection::FrameUniforms;
use super::shadows::{self, DTILDE_SPACINGS};
use super::{
    AlbedoResult, GuardBand, Lighting, Pipeline, PipelineFrame, PipelineInfo, PointStream, edl,
};
use crate::ViewerError;
use crate::gpu::GpuContext;
use crate::gpu::async_readback::AsyncReadback;
use crate::gpu::readback::read_buffer;
use crate::gpu::timing::Timer;
use crate::renderer::SurfacePixel;
use passes::{PyramidInputs, PyramidPasses, PyramidTargets};
use std::collections::BTreeMap;

/// The guard band of the pyramid: a hole's pixels take the pull-push's coarse levels and the
/// hidden-point removal's rings up to 16 pixels off (level 4), which cover the holes of a
/// surface whose points lie up to 16 pixels apart; sparser than that, the image is holes.
const PYRAMID_GUARD_PX: u32 = 16;

pub static INFO: PipelineInfo = PipelineInfo {
    name: "pyramid",
    description: "hidden-point removal, pull-push fill, pyramid normals, deferred shading",
    paper: Some("003_a7e57431d45858e9.txt (Bouchiba, Deschaud, Goulette 2018)"),
    lighting: Lighting::Headlight,
    params: &PARAMS,
    // Beyond the paper, which takes raw points: where the normals mark back faces, the
    // projection culls them, so that the far side of a thin shell is not taken for visible
    // through the near side's gaps (hidden-point removal cannot part two sheets a fraction of
    // a percent of the depth apart).
    streams: &[PointStream::Normals],
    passes: &[
        "shadows",
        "pyramid lit",
        "stored normals",
        "pyramid",
        "hpr",
        "noise",
        "pull",
        "push",
        "normals",
        "pyramid shade",
    ],
    previous_frame: false,
    cull_back_faces: true,
    reads_colour_plane: true,
    reads_planes: true,
    screen_buffers: PyramidPasses::screen_buffers,
    uses_point_size: true,
    guard: GuardBand::Px(PYRAMID_GUARD_PX),
    create,
    shaders: |_| {
        let mut all = passes::shaders();
        all.extend(lit::shaders());
        all.extend(stored::shaders());
        all.extend(shadows::shaders());
        all
    },
};

/// Its own parameters, then the light and shadows' (`shadows`: beyond the paper, the point
/// shadows of paper 004 carried through the pull-push).
const OWN: [ParamSpec; 5] = [
    ParamSpec {
        name: "s0",
        help: "the metric scale of the sampling, in dataset units: about the point spacing",
        default: 1.0,
        min: 1e-9,
        max: 1e9,
        scale: Scale::Log,
        auto: Some(Auto::DrawnSpacing),
    },
    ParamSpec {
        name: "edl",
        help: "eye-dome lighting on top of the shading",
        default: 0.0,
        min: 0.0,
        max: 1.0,
        scale: Scale::Toggle,
        auto: None,
    },
    edl::STRENGTH,
    edl::RADIUS,
    ParamSpec {
        name: "stored_normals",
        help: "shade with the dataset's normals where it has them, carried through the pull-push (off: the normals the paper estimates from the filled depth, as for a dataset without)",
        default: 1.0,
        min: 0.0,
        max: 1.0,
        scale: Scale::Toggle,
        auto: None,
    },
];

static PARAMS: [ParamSpec; OWN.len() + shadows::PARAMS.len()] = {
    let mut all = [OWN[0]; OWN.len() + shadows::PARAMS.len()];
    let mut k = 0;
    while k < all.len() {
        all[k] = if k < OWN.len() {
            OWN[k]
        } else {
            shadows::PARAMS[k - OWN.len()]
        };
        k += 1;
    }
    all
};

/// The measure the pipeline reports: the depth noise of the visible points, as a deviation in
/// dataset units (0: too few neighbouring points to tell).
pub const DEPTH_NOISE: &str = "depth_noise";

struct Pyramid {
    passes: PyramidPasses,
    targets: Option<PyramidTargets>,
    /// The depth noise on its way back for the stats.
    noise_readback: AsyncReadback,
    depth_noise: Option<f32>,
    device: wgpu::Device,
    shadows: shadows::Shadows,
    lit: lit::LitPass,
    stored: stored::StoredNormals,
}

fn create(ctx: &GpuContext) -> Result<Box<dyn Pipeline>, ViewerError> {
    Ok(Box::new(Pyramid {
        passes: PyramidPasses::new(
            &ctx.device,
            HprShape::for_device(ctx.adapter.get_info().device_type),
        )?,
        targets: None,
        noise_readback: AsyncReadback::new(&ctx.device, "depth noise readback", 4),
        depth_noise: None,
        device: ctx.device.clone(),
        shadows: shadows::Shadows::new(&ctx.device)?,
        lit: lit::LitPass::new(&ctx.device),
        stored: stored::StoredNormals::new(&ctx.device),
    }))
}

fn measures(depth_noise: Option<f32>) -> BTreeMap<&'static str, f32> {
    depth_noise.map(|v| (DEPTH_NOISE, v)).into_iter().collect()
}

impl Pipeline for Pyramid {
    fn info(&self) -> &'static PipelineInfo {
        &INFO
    }

    fn uniforms(&self, params: &ResolvedParams, uniforms: &mut FrameUniforms) {
        edl::set_uniforms(params, params.on("edl"), uniforms);
    }

    fn make_targets(&mut self, device: &wgpu::Device, screen: &super::projection::Screen) {
        self.targets = Some(self.passes.targets(device, screen.width, screen.height));
    }

    fn release_targets(&mut self) {
        self.targets = None;
        self.depth_noise = None;
        // A readback still on its way measured another picture.
        self.noise_readback = AsyncReadback::new(&self.device, "depth noise readback", 4);
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
            .as_ref()
            .ok_or_else(|| ViewerError::Gpu("the pyramid's buffers were not made".into()))?;
        let screen = frame.screen;
        // Without points there is no scale; any positive s0 leaves an empty frame empty.
        let s0 = frame.params.get_or("s0", 1.0);
        let forward = -frame.view.view.inverse().z_axis.truncate();
        // The shadows' d~ is the filters' automatic one: DTILDE_SPACINGS point spacings.
        let shadow = shadows::setup(frame, forward, DTILDE_SPACINGS as f32 * s0);
        let world = shadows::world_light(frame.params);
        let light = match world {
            Some(l) => frame
                .view
                .view
                .transform_vector3(l)
                .normalize_or_zero()
                .extend(1.0),
            None => glam::Vec4::new(0.0, 0.0, 0.0, shadow.is_some() as u32 as f32),
        };
        if let Some(setup) = &shadow {
            let lit_scale = self.shadows.encode(frame, encoder, setup, timer)?;
            // 0: no sample summed yet, every point lit (the resolved alpha is 1).
            if lit_scale > 0.0 {
                self.lit.encode(frame, encoder, lit_scale, timer)?;
            }
        }
        let stored_normals = frame.has_normals && frame.params.on("stored_normals");
        let rotation = glam::Mat3::from_mat4(frame.view.view);
        let row = |k: usize| rotation.row(k).extend(0.0).to_array();
        let pyramid_frame = PyramidFrame {
            s0,
            fov_y: frame.view.fov_y,
            far: frame.view.far,
            focal_px: frame.view.focal_px,
            light: light.to_array(),
            stored_normals,
            view_rows: [row(0), row(1), row(2)],
        };
        if stored_normals {
            self.stored.encode(frame, targets, encoder, timer)?;
        }
        self.passes.encode(
            &frame.ctx.device,
            &frame.ctx.queue,
            encoder,
            targets,
            &PyramidInputs {
                frame_uniforms: &screen.uniforms,
                depths: &screen.depths,
                colours: &screen.colours,
                output: &screen.output,
            },
            &pyramid_frame,
            timer,
        );
        targets.record_depth_noise(encoder, &mut self.noise_readback);
        Ok(())
    }

    fn after_submit(&mut self) {
        self.noise_readback.after_submit();
    }

    fn measures(&mut self) -> BTreeMap<&'static str, f32> {
        if let Some(bytes) = self.noise_readback.take() {
            self.depth_noise = depth_noise_from(&bytes);
        }
        measures(self.depth_noise)
    }

    fn read_measures(&self, ctx: &GpuContext) -> Result<BTreeMap<&'static str, f32>, ViewerError> {
        match &self.targets {
            Some(t) => Ok(measures(Some(t.read_depth_noise(ctx)?))),
            None => Ok(BTreeMap::new()),
        }
    }

    fn read_albedo(&self, ctx: &GpuContext) -> Option<AlbedoResult> {
        let t = self.targets.as_ref()?;
        let pixels = t.width as u64 * t.height as u64;
        let read = || -> AlbedoResult {
            let surface = read_buffer(ctx, &t.surface, pixels * 8)?;
            let colours = read_buffer(ctx, &t.fill_colour, pixels * 4)?;
            Ok(surface
                .chunks_exact(8)
                .zip(colours.chunks_exact(4))
                .map(|(s, c)| {
                    (u32::from_le_bytes([s[0], s[1], s[2], s[3]]) != u32::MAX)
                        .then_some([c[0], c[1], c[2]])
                })
                .collect())
        };
        Some(read())
    }

    fn read_surface(
        &self,
        ctx: &GpuContext,
    ) -> Option<Result<Vec<Option<SurfacePixel>>, ViewerError>> {
        let t = self.targets.as_ref()?;
        let pixels = t.width as u64 * t.height as u64;
        Some(read_buffer(ctx, &t.surface, pixels * 8).map(|data| {
            data.chunks_exact(8)
                .map(|b| {
                    let depth = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                    let normal = u32::from_le_bytes([b[4], b[5], b[6], b[7]]);
                    (depth != u32::MAX).then(|| SurfacePixel {
                        depth: f32::from_bits(depth),
                        normal: Some(decode_octahedral(normal)),
                    })
                })
                .collect()
        }))
    }
}

/// Inverse of `encode_normal` in pyramid.wgsl (two snorm16 octahedral coordinates).
fn decode_octahedral(e: u32) -> [f32; 3] {
    let snorm = |v: u32| ((v & 0xffff) as u16 as i16 as f32 / 32767.0).clamp(-1.0, 1.0);
    let (px, py) = (snorm(e), snorm(e >> 16));
    let mut n = glam::Vec3::new(px, py, 1.0 - px.abs() - py.abs());
    if n.z < 0.0 {
        let (x, y) = (n.x, n.y);
        n.x = (1.0 - y.abs()) * if x >= 0.0 { 1.0 } else { -1.0 };
        n.y = (1.0 - x.abs()) * if y >= 0.0 { 1.0 } else { -1.0 };
    }
    n.normalize_or_zero().to_array()
}

#[cfg(test)]
mod layout_tests {
    use super::uniforms::uniforms_layout;
    use super::{MAX_LEVELS, NOISE_BINS};
    use crate::pipelines::shader_tests::{module_named, wgsl_const, wgsl_layout};

    #[test]
    fn uniforms_and_constants_match_pyramid_wgsl() {
        let hpr = module_named("hpr");
        assert_eq!(
            wgsl_layout(&hpr, "Pyramid"),
            uniforms_layout(),
            "PyramidUniforms against Pyramid (pyramid.wgsl)"
        );
        assert_eq!(wgsl_const(&hpr, "MAX_LEVELS"), MAX_LEVELS as u64);
        assert_eq!(
            wgsl_const(&module_named("noise histogram"), "NOISE_BINS"),
            NOISE_BINS
        );
    }
}
