//! The render pipelines. Each is a module of its own (Rust and WGSL side by side) and one line
//! of `REGISTRY`; the renderer knows them only through `PipelineInfo` and `Pipeline`. Every
//! pipeline starts from the shared projection (`projection`): clear, project, and either a
//! fused finish with the pipeline's shading or the resolved depth and colour planes that the
//! pipeline's own passes read.

#[cfg(test)]
mod box_walk_tests;
#[cfg(test)]
mod dispatch_tests_support;
pub mod params;
mod pixel_shading;
pub mod projection;
pub mod shader;
#[cfg(test)]
mod shader_tests;
pub mod shadows;
pub mod surface;

use crate::ViewerError;
use crate::gpu::GpuContext;
use crate::gpu::timing::Timer;
use crate::renderer::SurfacePixel;
use params::{ParamSpec, ResolvedParams};
use projection::{FusedFinish, Screen};
use shader::ShaderSource;
use std::collections::BTreeMap;

/// Declares each pipeline's module (`NAME/mod.rs`, which defines `INFO`) and lists it in
/// `REGISTRY`, so that a pipeline is added by one line.
macro_rules! registry {
    ($($name:ident),* $(,)?) => {
        $(pub mod $name;)*

        /// Every pipeline, in the order the panel and `strata pipelines` list them.
        pub static REGISTRY: &[&PipelineInfo] = &[$(&$name::INFO),*];
    };
}

// The registry: the one place a pipeline is added. `cargo fmt` does not reach modules declared
// inside a macro: format a pipeline's files with `rustfmt --edition 2024
// viewer/src/pipelines/*/mod.rs`.
registry! {
    points,
    edl,
    pyramid,
    surfels,
    filters,
    triangulate,
}

/// The shared headlight Blinn-Phong (`headlight(albedo, n, v)`), so that two pipelines and the
/// quality harness's reference meshes shade the same surface the same way.
pub const LIGHTING_WGSL: &str = include_str!("lighting.wgsl");

/// A thread's walk over a pixel box in one loop (`box_pixels`, `box_next`).
pub const BOX_WALK_WGSL: &str = include_str!("box_walk.wgsl");

/// The pipeline a viewer starts with.
pub const DEFAULT_PIPELINE: &str = "edl";

/// The light a pipeline shades with, so that the quality harness scores its shaded image
/// against a reference lit the same way.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lighting {
    /// The points' own colours, unlit.
    None,
    /// Eye-dome lighting: colours darkened by depth differences to the neighbours.
    EyeDome,
    /// Blinn-Phong with the light at the eye (`lighting.wgsl`).
    Headlight,
}

impl Lighting {
    pub fn name(self) -> &'static str {
        match self {
            Lighting::None => "none",
            Lighting::EyeDome => "eye-dome",
            Lighting::Headlight => "headlight Blinn-Phong",
        }
    }
}

/// Per-point data a pipeline needs beyond position and colour. The node cache uploads a
/// stream only while a pipeline that asks for it is active.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PointStream {
    Normals,
    Radius,
    /// A value per point that the pipeline writes and reads again next frame, named so that
    /// two pipelines' values of one size are never taken for each other.
    Kept {
        name: &'static str,
        bytes: u32,
    },
}

impl PointStream {
    /// GPU bytes a point of this stream takes: normals as two unorm16 (SPEC.md's `oct16`, 0
    /// for none), the radius to draw as an f32, a kept value as declared (`streams.rs`).
    pub fn bytes_per_point(self) -> u64 {
        match self {
            PointStream::Normals | PointStream::Radius => 4,
            PointStream::Kept { bytes, .. } => bytes as u64,
        }
    }
}

/// How far a pipeline reaches beyond the view (`PipelineInfo::guard`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GuardBand {
    /// A pixel depends on its own point alone, or on neighbours a pixel or two off, whose
    /// absence at the edge shows no band.
    None,
    /// A fixed number of pixels.
    Px(u32),
    /// The value of parameter `name` (pixels, or iterations that each reach a pixel further),
    /// rounded up, plus `extra`.
    Param { name: &'static str, extra: u32 },
}

impl GuardBand {
    /// The widest band drawn, whatever the parameters ask.
    pub const MAX_PX: u32 = 64;

    /// The band in words, for `strata pipelines`; `None` without one.
    pub fn describe(&self) -> Option<String> {
        let what = match self {
            GuardBand::None => return None,
            GuardBand::Px(px) => format!("{px} pixels"),
            GuardBand::Param { name, extra } => format!("{name} + {extra} pixels"),
        };
        Some(format!(
            "draws {what} beyond each edge of the view (at most {}), for what reaches into it",
            GuardBand::MAX_PX
        ))
    }
}

/// What a pipeline declares; `strata pipelines` prints it.
pub struct PipelineInfo {
    pub name: &'static str,
    pub description: &'static str,
    /// The paper it implements (a file under shared/papers), where it has one.
    pub paper: Option<&'static str>,
    pub lighting: Lighting,
    pub params: &'static [ParamSpec],
    pub streams: &'static [PointStream],
    /// Its timed passes in the order they run, after the projection's.
    pub passes: &'static [&'static str],
    /// It reads the previous frame's view-projection and depth (temporal coherence).
    pub previous_frame: bool,
    /// The projection skips points whose normal faces away from the eye, where the dataset's
    /// normals mark back faces (the pipeline then declares the Normals stream).
    pub cull_back_faces: bool,
    /// It reads the colour plane the projection resolves (each pixel's point coloured by the
    /// colouring mode); a pipeline that fetches its points' attributes itself leaves the
    /// projection's per-arena resolve pass out.
    pub reads_colour_plane: bool,
    /// It reads the projection's depth and index planes, which a device with 64-bit atomics
    /// unpacks from the keys for it; a pipeline that draws from the node arenas alone leaves
    /// that pass out (picking reads the keys).
    pub reads_planes: bool,
    /// The buffers its `make_targets` creates for a `width` x `height` screen, for the check
    /// against the adapter's limits before anything is created or compiled.
    pub screen_buffers: fn(width: u32, height: u32) -> Vec<ScreenBuffer>,
    /// Its picture follows the point size (`Settings::point_size`): the projection's splats.
    /// A pipeline that sizes its own (surfels) or joins single pixels (triangulate) does not,
    /// and the window greys the size out for it.
    pub uses_point_size: bool,
    /// How far, in pixels, what it draws at a pixel reaches from points outside the view:
    /// the frame is drawn that much wider on every side and the view cut out of it.
    pub guard: GuardBand,
    /// Compiles its GPU passes.
    pub create: fn(&GpuContext) -> Result<Box<dyn Pipeline>, ViewerError>,
    /// Every shader module it compiles, composed as it compiles them (for validation without
    /// a GPU); `int64`: the device has 64-bit atomics.
    pub shaders: fn(int64: bool) -> Vec<ShaderSource>,
}

impl PipelineInfo {
    /// Frames of one view a still image waits for: a pipeline that keeps the previous frame
    /// converges over frames and declares how many in its parameter `warmup`.
    pub fn warmup_frames(&self, values: &params::ParamValues) -> u32 {
        match self.previous_frame {
            true => self.set_or_default(values, "warmup").unwrap_or(0.0) as u32,
            false => 0,
        }
    }

    /// Pixels of the guard band around the view (`GuardBand`), at most `GuardBand::MAX_PX`.
    pub fn guard_px(&self, values: &params::ParamValues) -> u32 {
        let px = match self.guard {
            GuardBand::None => 0,
            GuardBand::Px(px) => px,
            GuardBand::Param { name, extra } => {
                (self.set_or_default(values, name).unwrap_or(0.0).ceil() as u32)
                    .saturating_add(extra)
            }
        };
        px.min(GuardBand::MAX_PX)
    }

    /// The value `values` give parameter `name`, its default where automatic; `None` where
    /// the pipeline has no such parameter.
    fn set_or_default(&self, values: &params::ParamValues, name: &str) -> Option<f32> {
        let spec = self.params.iter().find(|p| p.name == name)?;
        Some(match values.get(self, spec) {
            params::ParamValue::Value(v) => v,
            params::ParamValue::Auto => spec.default,
        })
    }

    /// The parameter `name`; the error lists the ones there are.
    pub fn param(&self, name: &str) -> Result<&'static ParamSpec, ViewerError> {
        self.params.iter().find(|p| p.name == name).ok_or_else(|| {
            let known: Vec<&str> = self.params.iter().map(|p| p.name).collect();
            let what = if known.is_empty() {
                format!("the {} pipeline has no parameters", self.name)
            } else {
                format!(
                    "the {} pipeline has no such parameter (it has {})",
                    self.name,
                    known.join(", ")
                )
            };
            ViewerError::argument(name, what)
        })
    }
}

/// The registered pipeline `name`.
pub fn find(name: &str) -> Result<&'static PipelineInfo, ViewerError> {
    REGISTRY
        .iter()
        .copied()
        .find(|p| p.name == name)
        .ok_or_else(|| {
            let names: Vec<&str> = REGISTRY.iter().map(|p| p.name).collect();
            ViewerError::argument(
                name,
                format!("unknown pipeline (expected {})", names.join(", ")),
            )
        })
}

/// `screen_buffers` of a pipeline that makes none.
pub fn no_screen_buffers(_: u32, _: u32) -> Vec<ScreenBuffer> {
    Vec::new()
}

/// The most times one pass runs in a frame under its name (a depth-peeling pipeline's passes
/// run once per layer).
pub const MAX_PASS_REPEATS: u32 = 8;

/// The most passes one frame times: the projection's and the longest pipeline's, each run up
/// to `MAX_PASS_REPEATS` times.
pub fn max_timed_passes() -> u32 {
    let longest = REGISTRY.iter().map(|p| p.passes.len()).max().unwrap_or(0);
    MAX_PASS_REPEATS * (projection::PASSES.len() + longest) as u32
}

/// The view of one frame, for the pipeline's passes.
#[derive(Debug, Clone, Copy)]
pub struct ViewFrame {
    /// World to view (x right, y up, looking down -z).
    pub view: glam::Mat4,
    pub view_proj: glam::Mat4,
    pub fov_y: f32,
    pub near: f32,
    pub far: f32,
    pub focal_px: f32,
    /// Width over height of the image.
    pub aspect: f32,
}

/// The eye and a pixel's ray in world space: the ray through normalised device coordinates
/// (x, y) is forward + x * right + y * up, scaled so that the point at linear depth d on it is
/// eye + d * ray (the projection's clip.w). As the `Surfels` and `Filters` uniforms hold it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelRays {
    pub eye: [f32; 4],
    pub forward: [f32; 4],
    pub right: [f32; 4],
    pub up: [f32; 4],
}

impl ViewFrame {
    pub fn pixel_rays(&self) -> PixelRays {
        let world = self.view.inverse();
        let tan_y = (self.fov_y * 0.5).tan();
        let tan_x = tan_y * self.aspect;
        let v4 = |v: glam::Vec3| [v.x, v.y, v.z, 0.0];
        PixelRays {
            eye: world.w_axis.to_array(),
            forward: v4(-world.z_axis.truncate()),
            right: v4(world.x_axis.truncate() * tan_x),
            up: v4(world.y_axis.truncate() * tan_y),
        }
    }
}

/// What a pipeline's passes read and write in one frame.
pub struct PipelineFrame<'a> {
    pub ctx: &'a GpuContext,
    pub screen: &'a Screen,
    /// The resident points, with the streams the pipeline declared beside each arena.
    pub cache: &'a crate::gpu::NodeCache,
    /// The ranges of points drawn this frame, per arena.
    pub arenas: &'a [projection::ArenaDraw],
    /// The drawn ranges and those of the pipeline's `extra_view` (the same as `arenas`
    /// without one).
    pub casters: &'a [projection::ArenaDraw],
    pub params: &'a ResolvedParams,
    pub view: &'a ViewFrame,
    /// The view of the previous frame, whose depth `Screen::previous_depths` holds, for
    /// pipelines that declare `previous_frame` (`None` on their first frame and after a resize).
    pub previous: Option<ViewFrame>,
    /// The projection took the 64-bit path: `screen.keys` holds this frame's keys (unpacked
    /// into the depth and index planes only for a pipeline that `reads_planes`).
    pub int64: bool,
    /// The dataset stores normals (else the `Normals` stream holds none).
    pub has_normals: bool,
    /// Its normals face the outside of the surfaces (`StreamDataset::normals_face_outward`).
    pub normals_outward: bool,
    /// Its normals point out of every surface, so that one facing away from the eye marks a
    /// back face (`StreamDataset::normals_mark_back_faces`).
    pub normals_mark_back_faces: bool,
    /// The projection culled back faces (the pipeline declared `cull_back_faces` and the
    /// dataset's normals mark them: `StreamDataset::normals_mark_back_faces`).
    pub back_faces_culled: bool,
    /// The dataset's `StreamDataset::curvature_scale`, where it has one.
    pub curvature_scale: Option<f32>,
    /// The dataset's bounds, relative to the anchor.
    pub bounds: [glam::Vec3; 2],
    /// Changes whenever the point filters or clip boxes do (for what a pipeline keeps between
    /// frames that depends on which points are shown).
    pub filters_key: u64,
}

/// Per pixel, the unlit colour of the surface shown (`None`: background).
pub type AlbedoResult = Result<Vec<Option<[u8; 3]>>, ViewerError>;

/// A buffer a pipeline allocates per screen, for checking a size against the adapter's limits
/// before anything is created.
#[derive(Debug, Clone, Copy)]
pub struct ScreenBuffer {
    pub label: &'static str,
    pub bytes: u64,
}

/// A pipeline's compiled passes and per-screen buffers.
pub trait Pipeline {
    fn info(&self) -> &'static PipelineInfo;

    /// The pass that resolves and shades at once for frames within the fused pass's arenas,
    /// and its name; `None` where the pipeline needs the resolved planes.
    fn fused(&self, params: &ResolvedParams) -> Option<(&FusedFinish, &'static str)> {
        let _ = params;
        None
    }

    /// Sets the frame uniforms the pipeline's shading reads (eye-dome lighting).
    fn uniforms(&self, params: &ResolvedParams, uniforms: &mut projection::FrameUniforms) {
        let _ = (params, uniforms);
    }

    /// Creates the per-screen buffers for `screen`'s size (after the size was checked).
    fn make_targets(&mut self, device: &wgpu::Device, screen: &Screen) {
        let _ = (device, screen);
    }

    /// Frees the per-screen buffers: another pipeline was chosen.
    fn release_targets(&mut self) {}

    /// Another view whose nodes the passes need beside the camera's (the light's: shadow
    /// casters outside the camera's view), as a camera and a point budget of its own; its
    /// nodes reach the passes as `PipelineFrame::casters`. `bounds`: the dataset's, relative
    /// to the anchor.
    fn extra_view(
        &self,
        params: &ResolvedParams,
        camera: &crate::Camera,
        bounds: [glam::Vec3; 2],
    ) -> Option<(crate::Camera, u64)> {
        let _ = (params, camera, bounds);
        None
    }

    /// Encodes the passes after the projection resolved the depth and colour planes; they
    /// write `screen.output`.
    fn encode(
        &mut self,
        frame: &PipelineFrame,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut Timer,
    ) -> Result<(), ViewerError>;

    /// The depth plane the next frame gets as `Screen::previous_depths` (pipelines that
    /// declare `previous_frame` and reconstruct their own surface); `None`: the projection's.
    fn kept_depth(&self) -> Option<&wgpu::Buffer> {
        None
    }

    /// What the pipeline has to say about the last frame (the panel and the stats show it):
    /// a fallback it took, a stream the dataset lacks.
    fn note(&self) -> Option<&'static str> {
        None
    }

    /// After the frame was submitted: start mapping readbacks.
    fn after_submit(&mut self) {}

    /// What the pipeline measured that has arrived so far, without waiting (the window).
    fn measures(&mut self) -> BTreeMap<&'static str, f32> {
        BTreeMap::new()
    }

    /// What the pipeline measured in the last frame, waiting for the GPU (headless).
    fn read_measures(&self, ctx: &GpuContext) -> Result<BTreeMap<&'static str, f32>, ViewerError> {
        let _ = ctx;
        Ok(BTreeMap::new())
    }

    /// The unlit colour of the surface the last frame shows, per pixel (`None`: background),
    /// where the pipeline reconstructs its own surface; `None`: the resolved colour plane is it
    /// (a pipeline that declares no `reads_colour_plane` has none, and must give its own).
    fn read_albedo(&self, ctx: &GpuContext) -> Option<AlbedoResult> {
        let _ = ctx;
        None
    }

    /// The surface of the last frame where the pipeline reconstructs one (depth and normal per
    /// pixel); `None`: the projection's nearest points are the surface.
    fn read_surface(
        &self,
        ctx: &GpuContext,
    ) -> Option<Result<Vec<Option<SurfacePixel>>, ViewerError>> {
        let _ = ctx;
        None
    }
}
