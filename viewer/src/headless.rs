//! `strata render`: the viewer's frame loop without a window, writing PNGs and statistics.

use crate::camera::Camera;
use crate::gpu::{GpuContext, ProjectionPath};
use crate::measure::Measurements;
use crate::overlay::{Canvas, ScreenProjector, draw_measurements};
use crate::pick::PickedPoint;
use crate::renderer::{FrameStats, Renderer};
use crate::settings::Settings;
use crate::{HttpOptions, StreamDataset, ViewerError};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

pub struct RenderOptions {
    pub output: PathBuf,
    pub camera: Option<String>,
    pub width: u32,
    pub height: u32,
    pub settings: Settings,
    /// Each image waits until every node the budget allows is resident.
    pub wait_complete: bool,
    /// A single image without `wait_complete` waits at most this long for detail.
    pub timeout: Duration,
    pub path: Option<PathBuf>,
    /// Frames of a fly-through; 0: one each 1 / `fps` of the keyframes' seconds.
    pub frames: u32,
    /// Frame pacing of a fly-through that does not wait for completeness.
    pub fps: f32,
    pub stats: Option<PathBuf>,
    pub projection: ProjectionPath,
    pub gpu_cache_bytes: u64,
    pub loader_threads: usize,
    pub token: Option<String>,
    /// Measurements drawn over each image.
    pub measurements: Measurements,
}

#[derive(Debug, Serialize)]
pub struct RenderReport {
    pub dataset: String,
    pub adapter: String,
    pub projection: &'static str,
    pub width: u32,
    pub height: u32,
    pub budget: u64,
    pub pipeline: &'static str,
    pub open_ms: f64,
    pub time_to_first_image_ms: Option<f64>,
    pub images: Vec<String>,
    pub frames: Vec<FrameStats>,
    /// The frames of each still's view rendered before it, for pipelines that converge over
    /// frames (`PipelineInfo::warmup_frames`), in order.
    pub warmup: Vec<FrameStats>,
    pub errors: Vec<String>,
    /// The last fetch that found no server, when some did.
    pub fetch_error: Option<String>,
}

pub const DEFAULT_FOV_DEG: f32 = 50.0;

/// The paces, in frames per second, of a fly-through that does not wait for completeness (0,
/// outside the range, stands for unpaced): a frame at least every ten seconds, a viewer's
/// slowest useful pace, so that a run is bounded by its frames.
pub const FPS_RANGE: std::ops::RangeInclusive<f32> = 0.1..=1000.0;

/// The whole dataset in view, for a view of `width` x `height`.
pub fn default_camera(ds: &StreamDataset, width: u32, height: u32) -> Camera {
    let (min, max) = ds.bounds();
    let aspect = width as f32 / height.max(1) as f32;
    Camera::fit(min, max, DEFAULT_FOV_DEG.to_radians(), aspect)
}

/// Opens the dataset (a directory or an http:// URL) and the GPU, renders, writes images and
/// statistics. A node or hierarchy page of the views that could not be loaded fails it, and
/// no image is kept.
pub fn render(location: &str, opts: &RenderOptions) -> Result<RenderReport, ViewerError> {
    let t0 = Instant::now();
    let ds = Arc::new(StreamDataset::open(location, http_options(opts))?);
    // Before the GPU is opened: a colouring or a filter the dataset cannot give is refused at
    // once.
    ds.check_colour(opts.settings.colour)?;
    ds.check_filter(&opts.settings.filter)?;
    let ctx = Arc::new(GpuContext::new(opts.projection)?);
    render_with(ds, ctx, opts, t0)
}

/// The reads of a dataset over HTTP give up within `--timeout` (the time without progress a
/// command waits), so that a server gone silent fails the command then; at least a second,
/// as `--timeout 0` asks not to wait for detail, not to read nothing.
fn http_options(opts: &RenderOptions) -> HttpOptions {
    HttpOptions {
        token: opts.token.clone(),
        give_up_after: Some(opts.timeout.max(Duration::from_secs(1))),
        ..HttpOptions::default()
    }
}

pub fn render_with(
    ds: Arc<StreamDataset>,
    ctx: Arc<GpuContext>,
    opts: &RenderOptions,
    t0: Instant,
) -> Result<RenderReport, ViewerError> {
    ds.check_colour(opts.settings.colour)?;
    let cameras = crate::flight::cameras(&ds, opts)?;
    // Before anything is drawn: the named image, or a fly-through's frames beside it; none
    // of them the --stats file, which would be written over the image it describes.
    let images: Vec<PathBuf> = if cameras.len() > 1 {
        (0..cameras.len())
            .map(|i| numbered(&opts.output, i))
            .collect()
    } else {
        vec![opts.output.clone()]
    };
    let stats = opts
        .stats
        .as_deref()
        .and_then(|s| std::path::absolute(s).ok());
    for image in &images {
        check_png_replaceable(image)?;
        if stats.is_some() && std::path::absolute(image).ok() == stats {
            return Err(ViewerError::output(
                image,
                "is both an image this render writes and its --stats file; give --stats another name",
            ));
        }
    }
    let mut renderer = Renderer::new(
        ctx.clone(),
        ds.clone(),
        opts.gpu_cache_bytes,
        opts.loader_threads,
    )?;
    // Before anything is loaded or drawn: a size the adapter cannot hold is refused at once.
    renderer.check_size(&opts.settings, opts.width, opts.height)?;
    let open_ms = t0.elapsed().as_secs_f64() * 1e3;
    let mut report = RenderReport {
        dataset: ds.location(),
        adapter: ctx.adapter_name.clone(),
        projection: if ctx.int64_atomics { "int64" } else { "int32" },
        width: opts.width,
        height: opts.height,
        budget: opts.settings.budget,
        pipeline: opts.settings.pipeline.name,
        open_ms,
        time_to_first_image_ms: None,
        images: Vec::new(),
        frames: Vec::new(),
        warmup: Vec::new(),
        errors: Vec::new(),
        fetch_error: None,
    };
    let fly_through = cameras.len() > 1;
    // A fly-through that fails part way removes every frame of its sequence (each one checked
    // above as an image it may replace): with some frames new and the rest left from an
    // earlier run, the sequence would look complete.
    let mut draw_all = |report: &mut RenderReport| -> Result<(), ViewerError> {
        for (i, camera) in cameras.iter().enumerate() {
            let frame_start = Instant::now();
            let mut last_progress = Instant::now();
            let mut drawn_before = 0;
            let stats = loop {
                let mut stats = renderer.frame(camera, opts.width, opts.height, &opts.settings)?;
                renderer.wait_gpu()?;
                stats.passes = renderer.pass_times();
                stats.points_drawn = renderer
                    .counted_points_drawn()
                    .unwrap_or(stats.points_drawn);
                stats.frame_ms = frame_start.elapsed().as_secs_f64() * 1e3;
                if report.time_to_first_image_ms.is_none() && stats.points_drawn > 0 {
                    report.time_to_first_image_ms = Some(t0.elapsed().as_secs_f64() * 1e3);
                }
                if stats.bytes_loaded > 0 || stats.points_drawn != drawn_before {
                    last_progress = Instant::now();
                }
                drawn_before = stats.points_drawn;
                if stats.points_drawn == 0 {
                    root_fits(&ds, opts, &stats)?;
                }
                // Waiting for completeness ends early only when nothing arrives for `timeout`
                // (a server that went away): the image shows what there is.
                let done = if opts.wait_complete {
                    stats.complete || last_progress.elapsed() > opts.timeout
                } else if fly_through {
                    true
                } else {
                    stats.complete || frame_start.elapsed() > opts.timeout
                };
                if done {
                    break stats;
                }
                renderer.wait_for_loads(Duration::from_millis(20));
            };
            // One more frame after the last load so the timestamps describe the final picture; a
            // pipeline that builds on the previous frame converges over `warmup` more of the same
            // view first (each one's measures are kept, so that convergence can be read).
            let stats = if opts.wait_complete || !fly_through {
                let warmup = opts.settings.pipeline.warmup_frames(&opts.settings.params);
                for _ in 0..warmup {
                    let s = renderer.frame(camera, opts.width, opts.height, &opts.settings)?;
                    renderer.wait_gpu()?;
                    let points_drawn = renderer.counted_points_drawn().unwrap_or(s.points_drawn);
                    report.warmup.push(FrameStats {
                        points_drawn,
                        measures: renderer.read_measures()?,
                        passes: renderer.pass_times(),
                        ..s
                    });
                }
                let mut s = renderer.frame(camera, opts.width, opts.height, &opts.settings)?;
                renderer.wait_gpu()?;
                s.passes = renderer.pass_times();
                s.points_drawn = renderer.counted_points_drawn().unwrap_or(s.points_drawn);
                s.bytes_loaded += stats.bytes_loaded;
                s
            } else {
                stats
            };
            let stats = FrameStats {
                measures: renderer.read_measures()?,
                ..stats
            };
            let out = if fly_through {
                numbered(&opts.output, i)
            } else {
                opts.output.clone()
            };
            let (w, h, mut rgba) = renderer.read_image()?;
            if !opts.measurements.items.is_empty() {
                let proj = ScreenProjector::new(&ds, camera, w, h);
                let mut canvas = Canvas {
                    rgba: &mut rgba,
                    width: w,
                    height: h,
                };
                draw_measurements(&mut canvas, &proj, &opts.measurements);
            }
            write_png(&out, w, h, &rgba)?;
            report.images.push(out.display().to_string());
            report.frames.push(stats);
            if fly_through && !opts.wait_complete && opts.fps > 0.0 {
                let period = Duration::from_secs_f32(1.0 / opts.fps);
                if let Some(rest) = period.checked_sub(frame_start.elapsed()) {
                    std::thread::sleep(rest);
                }
            }
        }
        Ok(())
    };
    if let Err(e) = draw_all(&mut report) {
        if fly_through {
            for image in &images {
                let _ = std::fs::remove_file(image);
            }
        }
        return Err(e);
    }
    report.errors = renderer.errors().to_vec();
    report.fetch_error = renderer.last_fetch_error().map(str::to_string);
    if let Some(path) = &opts.stats {
        let json = serde_json::to_string_pretty(&report)
            .map_err(|e| ViewerError::output(path, format!("cannot encode statistics: {e}")))?;
        write_atomic(path, json.as_bytes())?;
    }
    // A node or hierarchy page that could not be loaded is a fault of the dataset (or of the
    // GPU cache's size), not a wait cut short: the images would show holes where its points
    // belong, so none is kept. The statistics, written above, list every error.
    if let Some(first) = report.errors.first() {
        let last = report.frames.last();
        let (nodes, pages) = last.map_or((0, 0), |f| (f.nodes_failed, f.pages_failed));
        let failed =
            format!("{nodes} node(s) and {pages} hierarchy page(s) could not be loaded ({first})");
        let kept: Vec<String> = report
            .images
            .iter()
            .filter_map(|image| Some(format!("{image} ({})", std::fs::remove_file(image).err()?)))
            .collect();
        let what = match (kept.is_empty(), report.dataset.contains("://")) {
            (false, _) => format!(
                "{failed}, and these incomplete images could not be removed: {}",
                kept.join(", ")
            ),
            (true, true) => format!("{failed}, so no image was kept"),
            (true, false) => {
                format!("{failed}, so no image was kept; `strata verify` checks the whole dataset")
            }
        };
        return Err(ViewerError::source(report.dataset, what));
    }
    Ok(report)
}

/// Draws the view of `opts` (its camera, size and settings) until every node it calls for is
/// resident, then picks the stored point nearest `pixel` within `radius` pixels, as the window
/// does on a click.
pub fn pick(
    location: &str,
    opts: &RenderOptions,
    pixel: (u32, u32),
    radius: u32,
) -> Result<Option<PickedPoint>, ViewerError> {
    Ok(pick_all(location, opts, &[pixel], radius)?.pop().flatten())
}

/// As [`pick`], for several pixels of the same view; `None` where only background is near.
pub fn pick_all(
    location: &str,
    opts: &RenderOptions,
    pixels: &[(u32, u32)],
    radius: u32,
) -> Result<Vec<Option<PickedPoint>>, ViewerError> {
    let ds = Arc::new(StreamDataset::open(location, http_options(opts))?);
    ds.check_filter(&opts.settings.filter)?;
    let ctx = Arc::new(GpuContext::new(opts.projection)?);
    let camera = match &opts.camera {
        Some(spec) => Camera::parse(
            spec,
            ds.anchor(),
            default_camera(&ds, opts.width, opts.height),
        )?,
        None => default_camera(&ds, opts.width, opts.height),
    };
    if let Some(&(x, y)) = pixels
        .iter()
        .find(|(x, y)| *x >= opts.width || *y >= opts.height)
    {
        return Err(ViewerError::argument(
            format!("{x},{y}"),
            format!(
                "the pixel lies outside the {}x{} view",
                opts.width, opts.height
            ),
        ));
    }
    let mut renderer = Renderer::new(ctx, ds.clone(), opts.gpu_cache_bytes, opts.loader_threads)?;
    renderer.check_size(&opts.settings, opts.width, opts.height)?;
    let start = Instant::now();
    loop {
        let stats = renderer.frame(&camera, opts.width, opts.height, &opts.settings)?;
        renderer.wait_gpu()?;
        if stats.points_drawn == 0 {
            nothing_drawn(&ds, opts, &stats, start.elapsed() > opts.timeout)?;
        }
        if stats.complete || start.elapsed() > opts.timeout {
            break;
        }
        renderer.wait_for_loads(Duration::from_millis(20));
    }
    // Under a node that could not be loaded, the nearest point drawn is another node's, or
    // background: an answer that looks right and is not.
    if let Some(first) = renderer.errors().first() {
        return Err(ViewerError::source(
            ds.location(),
            format!(
                "{} node(s) or page(s) of the view could not be loaded, so a pick could name the wrong point ({first})",
                renderer.errors().len()
            ),
        ));
    }
    pixels
        .iter()
        .map(|&(x, y)| renderer.pick(x, y, radius))
        .collect()
}

/// Why a view that drew no point cannot be picked from, where the answer "only background"
/// would be wrong: the budget is below the root node's points, so nothing can be drawn, or
/// the time ran out before anything was. A complete view of nothing (the data lies outside
/// it) is background.
fn nothing_drawn(
    ds: &StreamDataset,
    opts: &RenderOptions,
    stats: &FrameStats,
    timed_out: bool,
) -> Result<(), ViewerError> {
    root_fits(ds, opts, stats)?;
    if timed_out && !stats.complete {
        return Err(ViewerError::argument(
            format!("--timeout {}", opts.timeout.as_secs_f64()),
            "nothing was drawn before the time ran out",
        ));
    }
    Ok(())
}

/// Refuses a view whose point budget (as drawn: `--gpu-cache` may hold fewer) is below the
/// root node's points: nothing can be drawn in it, and an empty image would look like a view
/// of nothing.
fn root_fits(
    ds: &StreamDataset,
    opts: &RenderOptions,
    stats: &FrameStats,
) -> Result<(), ViewerError> {
    let root = ds.root_points();
    let budget = stats.budget_drawn;
    if root <= budget {
        return Ok(());
    }
    let (arg, limit) = if budget < opts.settings.budget {
        (
            "--gpu-cache".to_owned(),
            format!("the {budget} points the GPU cache holds"),
        )
    } else {
        (format!("--budget {budget}"), "the point budget".to_owned())
    };
    Err(ViewerError::argument(
        arg,
        format!(
            "nothing is drawn: the dataset's root node alone holds {root} points, more than {limit}"
        ),
    ))
}

/// Refuses `path` where something other than a PNG image is there already: an image this
/// renders (`-o`, or a fly-through's frame beside it) replaces only an image, never a
/// dataset's file or an input named by mistake.
pub fn check_png_replaceable(path: &Path) -> Result<(), ViewerError> {
    let Ok(meta) = std::fs::symlink_metadata(path) else {
        return Ok(());
    };
    let mut magic = [0u8; 8];
    let read = meta.is_file().then(|| {
        std::fs::File::open(path).and_then(|mut f| std::io::Read::read_exact(&mut f, &mut magic))
    });
    match read {
        Some(Ok(())) if magic == *b"\x89PNG\r\n\x1a\n" => Ok(()),
        Some(Err(e)) if e.kind() != std::io::ErrorKind::UnexpectedEof => Err(ViewerError::output(
            path,
            format!("exists and cannot be read ({e}); render replaces only PNG images"),
        )),
        _ => Err(ViewerError::output(
            path,
            "exists and is not a PNG image; render replaces only what it wrote itself, so \
             remove it yourself or choose another name",
        )),
    }
}

fn numbered(path: &Path, i: usize) -> PathBuf {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| "frame".into());
    path.with_file_name(format!("{stem}_{i:04}.png"))
}

/// Writes a PNG through a temporary name, so a failed write leaves no image that looks valid.
pub fn write_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<(), ViewerError> {
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, width, height);
        enc.set_color(png::ColorType::Rgba);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc
            .write_header()
            .map_err(|e| ViewerError::output(path, format!("cannot encode PNG ({e})")))?;
        w.write_image_data(rgba)
            .map_err(|e| ViewerError::output(path, format!("cannot encode PNG ({e})")))?;
    }
    write_atomic(path, &bytes)
}

/// Writes `bytes` through a temporary name, so a failed write leaves the old file (or none).
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ViewerError> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".part");
    let tmp = PathBuf::from(tmp);
    std::fs::write(&tmp, bytes).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        ViewerError::output(path, format!("cannot write ({e})"))
    })?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        ViewerError::output(path, format!("cannot write ({e})"))
    })
}
