//! Options shared by `strata view` and `strata render`.

use anyhow::Context;
use strata_viewer::gpu::ProjectionPath;
use strata_viewer::settings::{MAX_BUDGET, MIN_BUDGET, PassClock, SizeMode};
use strata_viewer::{ColourMode, Pipeline, Settings};

#[derive(Debug, clap::Args)]
pub struct ViewArgs {
    /// Points drawn per frame at most (100k to 100M; 5M, 800k, ...).
    #[arg(long, default_value = "5M", value_parser = super::synth::parse_count)]
    pub budget: u64,
    /// Render pipeline: points, edl or pyramid (hidden-point removal, pull-push fill and
    /// deferred shading, paper 003).
    #[arg(long, default_value = "edl")]
    pub pipeline: String,
    /// The pyramid pipeline's metric scale s0, in dataset units: about the point spacing
    /// (default: estimated from the nodes drawn each frame).
    #[arg(long)]
    pub s0: Option<f32>,
    /// Eye-dome lighting on top of the pyramid pipeline's shading.
    #[arg(long)]
    pub pyramid_edl: bool,
    /// Point size in pixels (or, with --attenuate, in multiples of the point spacing).
    #[arg(long, default_value_t = 2.0)]
    pub point_size: f32,
    /// Size points by their spacing in the world instead of in pixels.
    #[arg(long)]
    pub attenuate: bool,
    /// Colouring: rgb, intensity, classification or elevation.
    #[arg(long, default_value = "rgb")]
    pub colour: String,
    /// GPU memory for resident nodes.
    #[arg(long, default_value = "2GiB", value_parser = strata_converter::sys::parse_size)]
    pub gpu_cache: u64,
    /// Projection path: auto (64-bit atomics where available), int64 or int32.
    #[arg(long, default_value = "auto")]
    pub projection: String,
    /// Resolve and shade in separate passes instead of the fused one (to compare them).
    #[arg(long)]
    pub separate_passes: bool,
    /// Clock for the per-pass GPU times: auto (the wall clock on CPU adapters such as
    /// lavapipe, whose timestamps misplace work), timestamps, or wall (each pass submitted
    /// alone and waited for).
    #[arg(long, default_value = "auto")]
    pub pass_clock: String,
    /// Bearer token for a dataset served with `strata serve --token`.
    #[arg(long)]
    pub token: Option<String>,
    /// Loader threads fetching and decompressing nodes.
    #[arg(long, default_value_t = 4)]
    pub loaders: usize,
}

impl ViewArgs {
    pub fn settings(&self) -> anyhow::Result<Settings> {
        if !(MIN_BUDGET..=MAX_BUDGET).contains(&self.budget) {
            anyhow::bail!(
                "--budget {} is outside {MIN_BUDGET} to {MAX_BUDGET} points",
                self.budget
            );
        }
        if !(self.point_size.is_finite() && (0.1..=15.0).contains(&self.point_size)) {
            anyhow::bail!("--point-size {} is outside 0.1 to 15", self.point_size);
        }
        if let Some(s0) = self.s0.filter(|s| !(s.is_finite() && *s > 0.0)) {
            anyhow::bail!("--s0 {s0} is not a positive length");
        }
        Ok(Settings {
            budget: self.budget,
            s0: self.s0,
            pyramid_edl: self.pyramid_edl,
            pipeline: Pipeline::parse(&self.pipeline).context("--pipeline")?,
            point_size: self.point_size,
            size_mode: if self.attenuate {
                SizeMode::Attenuated
            } else {
                SizeMode::Fixed
            },
            colour: ColourMode::parse(&self.colour).context("--colour")?,
            fused_finish: !self.separate_passes,
            pass_clock: PassClock::parse(&self.pass_clock).context("--pass-clock")?,
            ..Settings::default()
        })
    }

    pub fn projection(&self) -> anyhow::Result<ProjectionPath> {
        match self.projection.as_str() {
            "auto" => Ok(ProjectionPath::Auto),
            "int64" => Ok(ProjectionPath::Int64),
            "int32" => Ok(ProjectionPath::Int32),
            other => anyhow::bail!("--projection {other:?} is not auto, int64 or int32"),
        }
    }
}
