//! `strata pick`: the stored point under a pixel of a view, as the window picks it on a click.

use super::camera_args::CameraArgs;
use super::render::parse_size_wh;
use super::view_args::ViewArgs;
use anyhow::Context;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;
use strata_viewer::headless::{RenderOptions, pick};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The dataset: a directory, or http://HOST:PORT/DATASET.
    dataset: String,
    #[command(flatten)]
    camera: CameraArgs,
    /// The view's size, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x720")]
    size: String,
    /// The pixel, X,Y from the top left.
    #[arg(long)]
    pixel: String,
    /// How far from the pixel, in pixels, a point may lie.
    #[arg(long, default_value_t = 8)]
    radius: u32,
    /// Seconds to wait for the view's detail.
    #[arg(long, default_value_t = 30.0)]
    timeout: f64,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    view: ViewArgs,
}

fn parse_pixel(s: &str) -> anyhow::Result<(u32, u32)> {
    s.split_once(',')
        .and_then(|(x, y)| Some((x.trim().parse().ok()?, y.trim().parse().ok()?)))
        .with_context(|| format!("--pixel {s:?} is not X,Y in whole pixels"))
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let (width, height) = parse_size_wh(&a.size)?;
    let pixel = parse_pixel(&a.pixel)?;
    if !(a.timeout.is_finite() && a.timeout >= 0.0) {
        anyhow::bail!("--timeout {} is not a number of seconds", a.timeout);
    }
    let opts = RenderOptions {
        output: PathBuf::new(),
        camera: a.camera.spec(&a.dataset)?,
        width,
        height,
        settings: a.view.settings()?,
        wait_complete: true,
        timeout: Duration::from_secs_f64(a.timeout),
        path: None,
        frames: 1,
        fps: 0.0,
        stats: None,
        projection: a.view.projection()?,
        gpu_cache_bytes: a.view.gpu_cache,
        loader_threads: a.view.loaders,
        token: a.view.token.clone(),
    };
    let Some(point) = pick(&a.dataset, &opts, pixel, a.radius)? else {
        eprintln!(
            "no point within {} pixels of {},{}",
            a.radius, pixel.0, pixel.1
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
