//! Options shared by `strata view` and `strata render`.

use anyhow::Context;
use strata_viewer::gpu::ProjectionPath;
use strata_viewer::settings::{ClipBox, MAX_BUDGET, MIN_BUDGET, PassClock, SizeMode};
use strata_viewer::{ColourMode, Settings};

#[derive(Debug, clap::Args)]
pub struct ViewArgs {
    /// Points drawn per frame at most (100k to 100M; 5M, 800k, ...).
    #[arg(long, default_value = "5M", value_parser = super::synth::parse_count)]
    pub budget: u64,
    /// Render pipeline (`strata pipelines` lists them with their parameters).
    #[arg(long, default_value = strata_viewer::pipelines::DEFAULT_PIPELINE)]
    pub pipeline: String,
    /// A parameter of the chosen pipeline, NAME=VALUE (repeatable; `strata pipelines` lists
    /// them, with their ranges).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Shorthand for `--set s0=VALUE` (the pyramid pipeline's metric scale, in dataset units;
    /// default: the spacing of the nodes drawn).
    #[arg(long)]
    pub s0: Option<String>,
    /// Shorthand for `--set edl=1` (eye-dome lighting on top of the pyramid's shading).
    #[arg(long)]
    pub pyramid_edl: bool,
    /// Show only these classification codes (comma-separated, e.g. 2,6).
    #[arg(long, value_name = "CODES")]
    pub classes: Option<String>,
    /// Hide these classification codes (comma-separated, e.g. 7,18).
    #[arg(long, value_name = "CODES")]
    pub hide_classes: Option<String>,
    /// Draw only points whose attribute lies in a range: intensity, elevation or return_number,
    /// NAME=LOW..HIGH (repeatable; elevation in the dataset's coordinates).
    #[arg(long = "filter", value_name = "NAME=LOW..HIGH")]
    pub filter: Vec<String>,
    /// A clip box, "min=X,Y,Z;max=X,Y,Z" in the dataset's coordinates, keeping its inside (or,
    /// with ";outside", hiding it); repeatable, up to 4. Nodes outside are not loaded.
    #[arg(long = "clip", value_name = "BOX")]
    pub clip: Vec<String>,
    /// Point size in pixels, the width of the disc a point covers (default 3); or, with
    /// --attenuate, in multiples of the point spacing (default 2).
    #[arg(long)]
    pub point_size: Option<f32>,
    /// Size points by their spacing in the world instead of in pixels.
    #[arg(long)]
    pub attenuate: bool,
    /// Colouring: rgb, intensity, classification, elevation, or (datasets converted with
    /// --normals) normal (x red, y green, z blue) or curvature (surface variation).
    #[arg(long, visible_alias = "color", default_value = "rgb")]
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
    #[arg(long, conflicts_with = "token_file")]
    pub token: Option<String>,
    /// As --token, with the token read from FILE (kept out of `ps`).
    #[arg(long, value_name = "FILE")]
    pub token_file: Option<std::path::PathBuf>,
    /// Loader threads fetching and decompressing nodes (1 to 256).
    #[arg(long, default_value_t = 4,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=256))]
    pub loaders: usize,
}

impl ViewArgs {
    /// The token of --token or --token-file, checked as `serve` checks its own.
    pub fn token(&self) -> anyhow::Result<Option<String>> {
        super::token::token(self.token.as_deref(), self.token_file.as_deref())
    }

    pub fn settings(&self) -> anyhow::Result<Settings> {
        if !(MIN_BUDGET..=MAX_BUDGET).contains(&self.budget) {
            anyhow::bail!(
                "--budget {} is outside {MIN_BUDGET} to {MAX_BUDGET} points",
                self.budget
            );
        }
        let mode = if self.attenuate {
            SizeMode::Attenuated
        } else {
            SizeMode::Fixed
        };
        let point_size = self.point_size.unwrap_or(mode.default_size());
        if !(point_size.is_finite() && (0.1..=15.0).contains(&point_size)) {
            anyhow::bail!("--point-size {point_size} is outside 0.1 to 15");
        }
        let mut settings = Settings {
            budget: self.budget,
            point_size,
            size_mode: mode,
            colour: ColourMode::parse(&self.colour).context("--colour")?,
            fused_finish: !self.separate_passes,
            pass_clock: PassClock::parse(&self.pass_clock).context("--pass-clock")?,
            ..Settings::default()
        };
        settings
            .set_pipeline(&self.pipeline)
            .context("--pipeline")?;
        let shorthands = [
            self.s0.as_ref().map(|v| ("--s0", format!("s0={v}"))),
            self.pyramid_edl
                .then(|| ("--pyramid-edl", "edl=1".to_string())),
        ];
        for (flag, assignment) in shorthands.into_iter().flatten() {
            settings.set_param(&assignment).context(flag)?;
        }
        for assignment in &self.set {
            settings.set_param(assignment).context("--set")?;
        }
        let codes = |flag: &str, list: &str| -> anyhow::Result<Vec<u8>> {
            list.split(',')
                .map(|c| {
                    c.trim().parse::<u8>().map_err(|_| {
                        anyhow::anyhow!(
                            "{flag} {list:?}: {c:?} is not a classification code (0 to 255)"
                        )
                    })
                })
                .collect()
        };
        if let Some(list) = &self.classes {
            settings
                .filter
                .set_classes(&codes("--classes", list)?, true);
        }
        if let Some(list) = &self.hide_classes {
            settings
                .filter
                .set_classes(&codes("--hide-classes", list)?, false);
        }
        for range in &self.filter {
            settings.filter.set_range(range).context("--filter")?;
        }
        for spec in &self.clip {
            let clip = ClipBox::parse(spec).context("--clip")?;
            settings.filter.add_clip(clip).context("--clip")?;
        }
        Ok(settings)
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
