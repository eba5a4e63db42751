use super::render::parse_size_wh;
use super::view_args::ViewArgs;
use anyhow::Context;
use std::path::PathBuf;
use std::process::ExitCode;
use strata_viewer::StreamDataset;
use strata_viewer::app::{WindowOptions, run_window};
use strata_viewer::measure::Measurements;
use strata_viewer::profile::{Corridor, Profile};

/// The window's profile export to LAS, LAZ or PLY (the viewer crate writes no LAS itself).
pub(super) fn write_profile_points(
    ds: &StreamDataset,
    p: &Profile,
    out: &std::path::Path,
) -> Result<(), String> {
    super::profile::write_points(ds, p, out, true).map_err(|e| format!("{e:#}"))
}

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The dataset: a directory, or http://HOST:PORT/DATASET.
    dataset: String,
    /// Window size, WIDTHxHEIGHT.
    #[arg(long, default_value = "1400x860")]
    size: String,
    /// Save a PNG of the whole window after --screenshot-after frames, then close.
    #[arg(long)]
    screenshot: Option<PathBuf>,
    #[arg(long, default_value_t = 60, requires = "screenshot")]
    screenshot_after: u32,
    /// Show the measurements of a GeoJSON file (default: DATASET/measurements.geojson).
    #[arg(long, value_name = "FILE.geojson")]
    measurements: Option<PathBuf>,
    /// Open a height profile along "X,Y;X,Y[;...]" (dataset coordinates).
    #[arg(long, value_name = "LINE", requires = "profile_width")]
    profile: Option<String>,
    /// The profile corridor's width, in dataset units.
    #[arg(long, value_name = "W", requires = "profile")]
    profile_width: Option<f64>,
    #[command(flatten)]
    view: ViewArgs,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let size = parse_size_wh(&a.size)?;
    run_window(
        &a.dataset,
        WindowOptions {
            settings: a.view.settings()?,
            gpu_cache_bytes: a.view.gpu_cache,
            loader_threads: a.view.loaders,
            projection: a.view.projection()?,
            screenshot: a.screenshot.map(|p| (p, a.screenshot_after.max(1))),
            size,
            token: a.view.token()?,
            measurements: a
                .measurements
                .as_deref()
                .map(Measurements::load_existing)
                .transpose()?,
            profile: match (&a.profile, a.profile_width) {
                (Some(line), Some(w)) => Some(Corridor::parse(line, w).context("--profile")?),
                _ => None,
            },
            points_writer: Some(write_profile_points),
        },
    )?;
    Ok(ExitCode::SUCCESS)
}
