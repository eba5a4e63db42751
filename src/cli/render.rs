use super::camera_args::CameraArgs;
use super::view_args::ViewArgs;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;
use strata_format::DatasetFile;
use strata_viewer::headless::{FPS_RANGE, RenderOptions, check_png_replaceable, render};
use strata_viewer::measure::Measurements;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The dataset: a directory, or http://HOST:PORT/DATASET.
    dataset: String,
    /// The PNG to write (a fly-through writes NAME_0000.png, NAME_0001.png, ...).
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    camera: CameraArgs,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x720")]
    size: String,
    /// Render once every node the budget allows is resident (every frame of a fly-through).
    #[arg(long)]
    wait_complete: bool,
    /// Seconds a single image waits for detail; with --wait-complete, seconds without any
    /// progress (a server gone away) before the image is written with what there is. A read
    /// over HTTP that has no answer within it (at least 1 s), retries included, fails.
    #[arg(long, default_value_t = 30.0)]
    timeout: f64,
    /// A fly-through: {"keyframes": [{"eye": [x,y,z], "target": [x,y,z], "fov": deg,
    /// "seconds": from the keyframe before (default 3)}, ...]}; the window's bookmarks.json is one.
    /// Its keyframes are the views: a --camera, --camera-file or --bookmark beside it would be
    /// ignored, so it is refused.
    #[arg(long, conflicts_with_all = ["camera", "camera_file", "bookmark"])]
    path: Option<PathBuf>,
    /// Frames of the fly-through, spread over the keyframes' times (default: the times at
    /// --fps). At least 1: the default, not 0, stands for "from the times".
    #[arg(long, requires = "path", value_parser = clap::value_parser!(u32).range(1..))]
    frames: Option<u32>,
    /// Pace of a fly-through that does not wait for completeness (frames per second, 0.1 to
    /// 1000; 0: unpaced).
    #[arg(long, default_value_t = 30.0, value_parser = parse_fps)]
    fps: f32,
    /// Write per-frame statistics as JSON.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Draw the measurements of a GeoJSON file over the image (the window saves
    /// DATASET/measurements.geojson; `strata measure` writes them too).
    #[arg(long, value_name = "FILE.geojson")]
    measurements: Option<PathBuf>,
    #[command(flatten)]
    view: ViewArgs,
}

/// `--timeout` as a duration: a number of seconds, not negative, within what a duration holds
/// (a finite 1e300 panicked converting).
pub fn timeout_of(seconds: f64) -> anyhow::Result<Duration> {
    match Duration::try_from_secs_f64(seconds) {
        Ok(d) => Ok(d),
        Err(_) => anyhow::bail!(
            "--timeout {seconds:e} is not a number of seconds from 0 to {:e}",
            Duration::MAX.as_secs_f64()
        ),
    }
}

/// --fps: 0 (unpaced) or a pace in `FPS_RANGE`; refused even where no fly-through uses it,
/// as a mistyped option should be.
fn parse_fps(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(f) if f == 0.0 || FPS_RANGE.contains(&f) => Ok(f),
        _ => Err(format!(
            "{s:?} is not 0 (unpaced) or a pace from {} to {} frames per second",
            FPS_RANGE.start(),
            FPS_RANGE.end()
        )),
    }
}

pub fn parse_size_wh(s: &str) -> anyhow::Result<(u32, u32)> {
    let parsed = s
        .split_once(['x', 'X'])
        .and_then(|(w, h)| Some((w.trim().parse::<u32>().ok()?, h.trim().parse::<u32>().ok()?)));
    match parsed {
        Some((w, h)) if (1..=16384).contains(&w) && (1..=16384).contains(&h) => Ok((w, h)),
        _ => anyhow::bail!("--size {s:?} is not WIDTHxHEIGHT with sides from 1 to 16384"),
    }
}

/// Refuses to write over an existing `path` unless it holds what this command writes there
/// (`ours` of its first bytes): `--stats` aimed by mistake at a dataset's file or an input
/// must not destroy it.
fn check_replaceable(path: &Path, what: &str, ours: impl Fn(&[u8]) -> bool) -> anyhow::Result<()> {
    let Ok(meta) = std::fs::symlink_metadata(path) else {
        return Ok(());
    };
    let mut head = Vec::new();
    if meta.is_file() {
        std::fs::File::open(path)
            .and_then(|f| f.take(4096).read_to_end(&mut head))
            .map_err(|e| anyhow::anyhow!("{}: cannot read ({e})", path.display()))?;
    }
    if !(meta.is_file() && ours(&head)) {
        anyhow::bail!(
            "{}: exists and is not {what}; render replaces only what it wrote itself, so remove \
             it yourself or choose another name",
            path.display()
        );
    }
    Ok(())
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    // PNG bytes under another name (x.jpg) would be taken for what the name says.
    if !a
        .output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
    {
        anyhow::bail!(
            "{}: render writes PNG images; give the output a .png name",
            a.output.display()
        );
    }
    // Checked again by the renderer with the frames' names; here before the dataset opens.
    check_png_replaceable(&a.output)?;
    if let Some(stats) = &a.stats {
        check_replaceable(stats, "render statistics", |b| {
            b.starts_with(b"{") && b.windows(9).any(|w| w == b"\"adapter\"")
        })?;
    }
    // Before the images are written, not after; and not over the image (the renderer checks a
    // fly-through's frames too, once it knows how many).
    // Neither the image nor the dataset read (a local one) may be written over.
    let mut taken = vec![a.output.clone()];
    if !a.dataset.contains("://") {
        let dir = Path::new(&a.dataset);
        taken.extend(
            [
                DatasetFile::Metadata,
                DatasetFile::Hierarchy,
                DatasetFile::Octree,
            ]
            .map(|f| dir.join(f.name())),
        );
    }
    super::check_stats_path(&a.stats, None, &taken, &[])?;
    let (width, height) = parse_size_wh(&a.size)?;
    let timeout = timeout_of(a.timeout)?;
    // 0: from the path's times at --fps.
    let frames = match (a.path.is_some(), a.frames) {
        (true, None) => 0,
        (_, f) => f.unwrap_or(1),
    };
    let opts = RenderOptions {
        output: a.output,
        camera: a.camera.spec(&a.dataset)?,
        width,
        height,
        settings: a.view.settings()?,
        wait_complete: a.wait_complete,
        timeout,
        path: a.path,
        frames,
        fps: a.fps,
        stats: a.stats,
        projection: a.view.projection()?,
        gpu_cache_bytes: a.view.gpu_cache,
        loader_threads: a.view.loaders,
        token: a.view.token()?,
        measurements: match &a.measurements {
            Some(f) => Measurements::load_existing(f)?,
            None => Measurements::default(),
        },
    };
    let report = render(&a.dataset, &opts)?;
    let last = report.frames.last();
    println!(
        "{} image(s) via {} ({} projection): {} points in {} nodes",
        report.images.len(),
        report.adapter,
        report.projection,
        last.map_or(0, |f| f.points_drawn),
        last.map_or(0, |f| f.nodes_drawn),
    );
    if let Some(e) = &report.fetch_error {
        eprintln!("warning: {e}");
    }
    if let Some(f) = last.filter(|f| f.budget_drawn < report.budget) {
        eprintln!(
            "warning: the GPU cache (--gpu-cache) holds fewer points than the budget of {}: \
             each frame drew at most {}",
            report.budget, f.budget_drawn
        );
    }
    if let Some(f) = last.filter(|f| !f.complete) {
        eprintln!(
            "warning: the image was written with {} wanted node(s) missing ({} unavailable)",
            f.nodes_missing, f.nodes_unavailable
        );
    }
    Ok(ExitCode::SUCCESS)
}
