use super::render::parse_size_wh;
use super::view_args::ViewArgs;
use std::path::PathBuf;
use std::process::ExitCode;
use strata_viewer::app::{WindowOptions, run_window};

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
            token: a.view.token.clone(),
        },
    )?;
    Ok(ExitCode::SUCCESS)
}
