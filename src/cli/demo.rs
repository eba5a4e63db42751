use super::convert::print_summary;
use anyhow::Context;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;
use strata_converter::replace::{Folder, check_output};
use strata_converter::synth::{Scene, synth};
use strata_converter::{ConvertOptions, Sampling, convert};
use strata_viewer::app::{WindowOptions, run_window};
use strata_viewer::gpu::ProjectionPath;
use strata_viewer::headless::{RenderOptions, check_png_replaceable, render};
use strata_viewer::renderer::DEFAULT_GPU_CACHE;
use strata_viewer::{Settings, ViewerError};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Where to put the demo's files (default: a "strata-demo" folder in the system temp dir).
    #[arg(long)]
    dir: Option<PathBuf>,
    /// Points in the synthetic scene.
    #[arg(long, default_value = "2M", value_parser = super::synth::parse_count)]
    points: u64,
    /// Render a PNG instead of opening a window (the default where there is no display).
    #[arg(long)]
    png: bool,
}

/// Synthesizes a city, converts it, verifies it and shows it: in the viewer where there is a
/// display, else as a rendered PNG.
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let dir = a
        .dir
        .unwrap_or_else(|| std::env::temp_dir().join("strata-demo"));
    // Before anything is made, so that a refused run leaves no folder behind.
    anyhow::ensure!(a.points >= 1, "--points must be at least 1");
    std::fs::create_dir_all(&dir)
        .with_context(|| format!("{}: cannot create the demo's folder", dir.display()))?;
    let las = dir.join("city.laz");
    let dataset = dir.join("city.strata");
    let png = dir.join("city.png");
    check_demo_files(&las, &dataset, &png)?;
    println!("1/4 synthesizing {} points -> {}", a.points, las.display());
    synth(&las, a.points, Scene::City, 1, 0.0, true)?;
    println!("2/4 converting -> {}", dataset.display());
    let summary = convert(&ConvertOptions {
        inputs: vec![las],
        output: dataset.clone(),
        memory_limit: 1 << 30,
        threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        sampling: Sampling::Poisson,
        overwrite: true,
        resume: false,
        quiet: false,
        temp_dir: None,
    })?;
    print_summary(&summary);
    println!("3/4 verifying");
    let report = strata_format::verify_dataset(&dataset);
    if !report.is_ok() {
        for f in &report.faults {
            eprintln!("fault: {f}");
        }
        anyhow::bail!(
            "{}: the demo dataset failed verification",
            dataset.display()
        );
    }
    println!(
        "ok: {} points in {} nodes verified",
        report.points_checked, report.nodes_checked
    );
    let has_display = std::env::var_os("DISPLAY").is_some_and(|d| !d.is_empty())
        || std::env::var_os("WAYLAND_DISPLAY").is_some_and(|d| !d.is_empty());
    if has_display && !a.png {
        println!("4/4 opening the viewer (close the window to end the demo)");
        let opened = run_window(
            &dataset.to_string_lossy(),
            WindowOptions {
                settings: Settings::default(),
                gpu_cache_bytes: DEFAULT_GPU_CACHE,
                loader_threads: 4,
                projection: ProjectionPath::Auto,
                screenshot: None,
                size: (1400, 860),
                token: None,
                measurements: None,
                profile: None,
                points_writer: Some(super::view::write_profile_points),
            },
        );
        match opened {
            Ok(()) => return Ok(ExitCode::SUCCESS),
            // A display that is set but does not answer (a stale DISPLAY over ssh): the demo
            // still shows its result, as a picture.
            Err(ViewerError::Window(why)) => {
                eprintln!("warning: cannot open a window: {why}");
                println!("4/4 rendering {} instead", png.display());
            }
            Err(e) => return Err(e.into()),
        }
    } else if a.png {
        println!("4/4 rendering {}", png.display());
    } else {
        println!("4/4 no display: rendering {}", png.display());
    }
    let report = render(
        &dataset.to_string_lossy(),
        &RenderOptions {
            output: png.clone(),
            camera: None,
            width: 1280,
            height: 720,
            settings: Settings::default(),
            wait_complete: true,
            timeout: Duration::from_secs(60),
            path: None,
            frames: 1,
            fps: 0.0,
            stats: None,
            projection: ProjectionPath::Auto,
            gpu_cache_bytes: DEFAULT_GPU_CACHE,
            measurements: Default::default(),
            loader_threads: 4,
            token: None,
        },
    )?;
    let frame = report.frames.last();
    println!(
        "ok: {} with {} points drawn via {}; open it in the viewer with `strata view {}`",
        png.display(),
        frame.map_or(0, |f| f.points_drawn),
        report.adapter,
        dataset.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// The demo replaces its own files from an earlier run, and nothing else: checked before it
/// writes any (a user's city.laz in --dir was overwritten, then the run failed on city.png).
fn check_demo_files(las: &Path, dataset: &Path, png: &Path) -> anyhow::Result<()> {
    let refuse = |path: &Path, what: &str| {
        anyhow::anyhow!(
            "{}: exists and is not {what} an earlier demo wrote; remove it or give another --dir",
            path.display()
        )
    };
    if std::fs::symlink_metadata(las).is_ok() {
        // A LAS header's generating software, bytes 58 to 90: the synthesizer signs it.
        let mut head = [0u8; 90];
        let ours = std::fs::File::open(las)
            .and_then(|mut f| f.read_exact(&mut head))
            .is_ok()
            && head.starts_with(b"LASF")
            && head[58..].starts_with(b"strata ");
        if !ours {
            return Err(refuse(las, "the LAZ scene"));
        }
    }
    // The rule convert replaces an output by, applied before the scene is made.
    check_output(dataset, true, Folder::Dataset)?;
    check_png_replaceable(png)?;
    Ok(())
}
