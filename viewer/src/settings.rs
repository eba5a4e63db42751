//! What the user controls: budget, pipeline, point size, colouring. Shared by the panel and
//! the command line.

use crate::ViewerError;
pub use crate::gpu::timing::PassClock;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pipeline {
    Points,
    Edl,
    /// Paper 003: hidden-point removal, pull-push fill, pyramid normals, deferred shading.
    Pyramid,
}

impl Pipeline {
    pub const ALL: [Pipeline; 3] = [Pipeline::Points, Pipeline::Edl, Pipeline::Pyramid];

    pub fn name(self) -> &'static str {
        match self {
            Pipeline::Points => "points",
            Pipeline::Edl => "edl",
            Pipeline::Pyramid => "pyramid",
        }
    }

    pub fn parse(s: &str) -> Result<Pipeline, ViewerError> {
        Pipeline::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| {
                ViewerError::argument(s, "unknown pipeline (expected points, edl or pyramid)")
            })
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColourMode {
    Rgb,
    Intensity,
    Classification,
    Elevation,
}

impl ColourMode {
    pub const ALL: [ColourMode; 4] = [
        ColourMode::Rgb,
        ColourMode::Intensity,
        ColourMode::Classification,
        ColourMode::Elevation,
    ];

    pub fn name(self) -> &'static str {
        match self {
            ColourMode::Rgb => "rgb",
            ColourMode::Intensity => "intensity",
            ColourMode::Classification => "classification",
            ColourMode::Elevation => "elevation",
        }
    }

    pub fn parse(s: &str) -> Result<ColourMode, ViewerError> {
        ColourMode::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| {
                ViewerError::argument(
                    s,
                    "unknown colouring (expected rgb, intensity, classification or elevation)",
                )
            })
    }

    pub fn shader_code(self) -> u32 {
        self as u32
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SizeMode {
    /// Point size in pixels.
    Fixed,
    /// Point size as a multiple of the node's point spacing, so splats close up.
    Attenuated,
}

#[derive(Debug, Clone, Copy)]
pub struct Settings {
    pub budget: u64,
    pub pipeline: Pipeline,
    pub point_size: f32,
    pub size_mode: SizeMode,
    pub colour: ColourMode,
    pub edl_strength: f32,
    pub edl_radius: f32,
    /// Refinement stops where a node's point spacing projects below this many pixels.
    pub min_spacing_px: f32,
    pub background: [u8; 3],
    /// GPU uploads per frame are capped so frames stay even while streaming (None: no cap).
    pub upload_points_per_frame: Option<u64>,
    /// Resolve and shade in one pass where the frame allows (off: separate passes, to compare).
    pub fused_finish: bool,
    /// Use the two-pass 32-bit projection even on a device with 64-bit atomics.
    pub force_int32: bool,
    /// The pyramid pipeline's metric sampling scale s0 in dataset units; `None` takes it from
    /// the nodes drawn.
    pub s0: Option<f32>,
    /// Eye-dome lighting on top of the pyramid pipeline's shading.
    pub pyramid_edl: bool,
    /// The clock the per-pass GPU times are taken with.
    pub pass_clock: PassClock,
}

impl Default for Settings {
    fn default() -> Settings {
        Settings {
            budget: 5_000_000,
            pipeline: Pipeline::Edl,
            point_size: 2.0,
            size_mode: SizeMode::Fixed,
            colour: ColourMode::Rgb,
            edl_strength: 1.0,
            edl_radius: 1.4,
            min_spacing_px: 1.0,
            background: [24, 26, 32],
            upload_points_per_frame: Some(4_000_000),
            fused_finish: true,
            force_int32: false,
            s0: None,
            pyramid_edl: false,
            pass_clock: PassClock::Auto,
        }
    }
}

pub const MIN_BUDGET: u64 = 100_000;
pub const MAX_BUDGET: u64 = 100_000_000;
