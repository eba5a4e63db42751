//! `strata pick`: the stored point under a pixel of a view, as the window picks it on a click.

use super::camera_args::CameraArgs;
use super::render::parse_size_wh;
use super::view_args::ViewArgs;
use anyhow::Context;
use std::path::PathBuf;
use std::process::ExitCode;
use strata_viewer::headless::{RenderOptions, pick};

/// The view a pick is made in: dataset, camera, size, settings; shared with `strata measure`.
#[derive(Debug, clap::Args)]
pub struct PickView {
    /// The dataset: a directory, or http://HOST:PORT/DATASET.
    pub dataset: String,
    #[command(flatten)]
    camera: CameraArgs,
    /// The view's size, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x720")]
    size: String,
    /// How far from the pixel, in pixels, a point may lie.
    #[arg(long, default_value_t = 8)]
    pub radius: u32,
    /// Seconds to wait for the view's detail; a read over HTTP that has no answer within it
    /// (at least 1 s), retries included, fails.
    #[arg(long, default_value_t = 30.0)]
    timeout: f64,
    #[command(flatten)]
    view: ViewArgs,
}

impl PickView {
    /// The options of the view the pixels are picked in.
    pub fn options(&self) -> anyhow::Result<RenderOptions> {
        let (width, height) = parse_size_wh(&self.size)?;
        let timeout = super::render::timeout_of(self.timeout)?;
        Ok(RenderOptions {
            output: PathBuf::new(),
            camera: self.camera.spec(&self.dataset)?,
            width,
            height,
            settings: self.view.settings()?,
            wait_complete: true,
            timeout,
            path: None,
            frames: 1,
            fps: 0.0,
            stats: None,
            projection: self.view.projection()?,
            gpu_cache_bytes: self.view.gpu_cache,
            loader_threads: self.view.loaders,
            token: self.view.token()?,
            measurements: Default::default(),
        })
    }
}

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub(crate) at: PickView,
    /// The pixel, X,Y from the top left.
    #[arg(long)]
    pixel: String,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

pub fn parse_pixel(s: &str) -> anyhow::Result<(u32, u32)> {
    s.split_once(',')
        .and_then(|(x, y)| Some((x.trim().parse().ok()?, y.trim().parse().ok()?)))
        .with_context(|| format!("--pixel {s:?} is not X,Y in whole pixels"))
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let pixel = parse_pixel(&a.pixel)?;
    let opts = a.at.options()?;
    let Some(point) = pick(&a.at.dataset, &opts, pixel, a.at.radius)? else {
        eprintln!(
            "no point within {} pixels of {},{}",
            a.at.radius, pixel.0, pixel.1
        );
        return Ok(ExitCode::from(3));
    };
    if a.json {
        println!("{}", serde_json::to_string_pretty(&point)?);
    } else {
        for line in point.lines() {
            println!("{line}");
        }
    }
    Ok(ExitCode::SUCCESS)
}
