//! The harness's outputs: quality.csv, the Markdown summary, the charts and the side-by-side
//! images.

use super::metrics::Metrics;
use anyhow::Context;
use plotters::prelude::*;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

#[derive(Debug, Clone)]
pub struct Row {
    pub scene: String,
    pub view: usize,
    pub pipeline: String,
    pub setting: String,
    pub density: f64,
    pub noise: f64,
    /// The light the pipeline shades with; `metrics.psnr`/`ssim` are against the reference lit
    /// the same way.
    pub lighting: &'static str,
    pub metrics: Metrics,
    /// PSNR and SSIM of the unlit colour against the mesh's albedo: comparable across
    /// pipelines whatever their lighting.
    pub albedo_psnr: f64,
    pub albedo_ssim: f64,
    pub gpu_ms: f64,
    pub stability: bool,
    /// Shadowed frames: the share of the scored pixels whose lit or shadowed state matches
    /// the mesh's, the shadows' intersection over union, and the share of the penumbra's
    /// pixels that are speckle (`shadows::shadow_scores`).
    pub shadow_match: Option<(f64, f64, f64)>,
}

impl Row {
    pub fn label(&self) -> String {
        format!("{} {}", self.pipeline, self.setting)
    }

    pub fn values(&self) -> [f64; VALUES] {
        let m = &self.metrics;
        [
            self.density,
            self.noise,
            m.psnr,
            m.ssim,
            m.depth_err,
            m.normal_err_deg,
            m.hole_rate,
            m.leak_rate,
            self.gpu_ms,
            self.albedo_psnr,
            self.albedo_ssim,
            m.silhouette_px,
        ]
    }
}

/// Numbers per row: density, noise, the shaded PSNR and SSIM, depth and normal error, holes,
/// leaks, GPU ms, the albedo PSNR and SSIM, the silhouette error.
const VALUES: usize = 12;

pub fn write_csv(path: &Path, rows: &[Row]) -> anyhow::Result<()> {
    let mut out = String::from(
        "scene,pipeline,setting,lighting,density,noise,psnr,ssim,psnr_albedo,ssim_albedo,depth_err,normal_err_deg,hole_rate,leak_rate,gpu_ms,silhouette_px\n",
    );
    for r in rows {
        let v = r.values();
        let _ = writeln!(
            out,
            "{}/view{},{},{},{},{:.4},{:.4},{:.3},{:.4},{:.3},{:.4},{:.5},{:.2},{:.4},{:.4},{:.3},{:.3}",
            r.scene,
            r.view,
            r.pipeline,
            r.setting,
            r.lighting,
            v[0],
            v[1],
            v[2],
            v[3],
            v[ALBEDO_PSNR],
            v[ALBEDO_SSIM],
            v[4],
            v[5],
            v[6],
            v[7],
            v[8],
            v[SILHOUETTE]
        );
    }
    std::fs::write(path, out).with_context(|| format!("{}", path.display()))
}

/// Transparency and shadows (paper 004): the filters' peeled layers against the mesh peeled
/// and blended the same way, and the shadows of every pipeline that casts them (the filters',
/// and the pyramid's through its pull-push) against the mesh's (lit or shadowed state per
/// pixel, and the image against the same picture with the mesh's shadows).
fn layers_and_shadows(rows: &[Row]) -> String {
    let picked: Vec<&Row> = rows
        .iter()
        .filter(|r| r.shadow_match.is_some() || r.setting.starts_with("layers="))
        .collect();
    if picked.is_empty() {
        return String::new();
    }
    let mut md = String::from(
        "\n## Transparency and shadows\n\n| scene | density | pipeline | setting | PSNR dB | SSIM | lit/shadowed state right | shadow IoU | penumbra speckle | GPU ms |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in picked {
        let (state, iou, speckle) = match r.shadow_match {
            Some((m, iou, s)) => (
                format!("{:.1} %", 100.0 * m),
                format!("{iou:.3}"),
                format!("{:.2} %", 100.0 * s),
            ),
            None => ("-".to_string(), "-".to_string(), "-".to_string()),
        };
        let _ = writeln!(
            md,
            "| {} | {:.3} | {} | {} | {:.2} | {:.3} | {state} | {iou} | {speckle} | {:.1} |",
            r.scene, r.density, r.pipeline, r.setting, r.metrics.psnr, r.metrics.ssim, r.gpu_ms
        );
    }
    md
}

/// The surfels' modes side by side (paper 001's claim: c-surfels at the silhouette fix the
/// outline at little cost): mean silhouette error, holes and GPU time per mode over every
/// frame, with the cost relative to all-planar.
fn surfel_modes(rows: &[Row]) -> String {
    let surfels: Vec<&Row> = rows.iter().filter(|r| r.pipeline == "surfels").collect();
    let means = group_means(&surfels, |r| r.setting.clone());
    let mode = |setting: &str| match setting {
        "mode=planar" => "planar",
        "mode=curved" => "curved",
        "curvature=0" => "hybrid, c-surfels bent by h alone",
        _ => "hybrid",
    };
    let Some(planar) = means.get("mode=planar") else {
        return String::new();
    };
    let mut md = String::from(
        "\n## Surfels: planar, curved, hybrid\n\n| mode | setting | silhouette px | holes | GPU ms | cost / planar |\n|---|---|---|---|---|---|\n",
    );
    for (setting, v) in &means {
        let _ = writeln!(
            md,
            "| {} | {setting} | {:.3} | {:.4} | {:.2} | {:.3} |",
            mode(setting),
            v[SILHOUETTE],
            v[HOLES],
            v[GPU_MS],
            v[GPU_MS] / planar[GPU_MS].max(1e-9)
        );
    }
    md
}

/// Means of the metrics over `rows`, grouped by `key`, in key order.
fn group_means<K: Ord>(rows: &[&Row], key: impl Fn(&Row) -> K) -> BTreeMap<K, [f64; VALUES]> {
    let mut sums: BTreeMap<K, ([f64; VALUES], usize)> = BTreeMap::new();
    for r in rows {
        let e = sums.entry(key(r)).or_insert(([0.0; VALUES], 0));
        for (s, v) in e.0.iter_mut().zip(r.values()) {
            *s += v;
        }
        e.1 += 1;
    }
    sums.into_iter()
        .map(|(k, (s, n))| (k, s.map(|v| v / n as f64)))
        .collect()
}

/// The pipelines' colours in every chart: a hue per pipeline (by name, so a new pipeline gets
/// one of its own), a shade per setting.
fn colour_of(label: &str) -> RGBColor {
    let (pipeline, setting) = label.split_once(' ').unwrap_or((label, ""));
    let base: [f64; 3] = match pipeline {
        "points" => [140.0, 140.0, 140.0],
        "edl" => [40.0, 120.0, 220.0],
        "pyramid" => [225.0, 70.0, 45.0],
        other => {
            const PALETTE: [[f64; 3]; 5] = [
                [40.0, 160.0, 90.0],
                [150.0, 70.0, 190.0],
                [230.0, 160.0, 30.0],
                [30.0, 170.0, 170.0],
                [200.0, 60.0, 140.0],
            ];
            let h = other
                .bytes()
                .fold(0usize, |h, b| h.wrapping_mul(31) + b as usize);
            PALETTE[h % PALETTE.len()]
        }
    };
    // Darker for larger points and larger parameters, lighter for smaller ones.
    let shade = match setting {
        s if s.contains("×0.5") => 1.35,
        s if s.contains('×') => 0.55,
        s if s.starts_with("2px") => 0.6,
        _ => 1.0,
    };
    let [r, g, b] = base.map(|c| (c * shade).clamp(0.0, 255.0) as u8);
    RGBColor(r, g, b)
}

fn plot_err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("drawing a chart failed: {e:?}")
}

/// Registers the chart font (egui's default sans, already a dependency of the viewer).
pub fn init_fonts() -> anyhow::Result<()> {
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        epaint_default_fonts::UBUNTU_LIGHT,
    )
    .map_err(|_| anyhow::anyhow!("the chart font is not a valid font"))
}

type Series = Vec<(String, Vec<(f64, f64)>)>;

/// Width of the strip beside each panel that holds its legend: inside the plot, a legend hid
/// the marks under it.
const LEGEND_W: u32 = 170;

/// A panel's legend: per series its mark and label, top-down.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    series: &Series,
) -> anyhow::Result<()> {
    for (i, (label, _)) in series.iter().enumerate() {
        let y = 60 + 22 * i as i32;
        area.draw(&Circle::new((10, y), 5, colour_of(label).filled()))
            .map_err(plot_err)?;
        let style = ("sans-serif", 14).into_font().color(&BLACK);
        area.draw(&Text::new(label.as_str(), (22, y - 7), style))
            .map_err(plot_err)?;
    }
    Ok(())
}

/// A chart of one or more panels, each a set of labelled series (lines, or single marks).
fn chart(
    path: &Path,
    title: &str,
    x_desc: &str,
    log_x: bool,
    panels: &[(&str, Series)],
) -> anyhow::Result<()> {
    let (w, h) = ((640 + LEGEND_W) * panels.len() as u32, 480u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let root = root.titled(title, ("sans-serif", 22)).map_err(plot_err)?;
        let areas = root.split_evenly((1, panels.len()));
        for (panel, (y_desc, series)) in areas.iter().zip(panels) {
            let (area, legend) = panel.split_horizontally(panel.dim_in_pixel().0 - LEGEND_W);
            draw_legend(&legend, series)?;
            let pts: Vec<(f64, f64)> = series.iter().flat_map(|s| s.1.clone()).collect();
            if pts.is_empty() {
                continue;
            }
            let fx = |v: f64| if log_x { v.max(1e-6).log10() } else { v };
            let (mut x0, mut x1) = pts.iter().fold((f64::MAX, f64::MIN), |(a, b), p| {
                (a.min(fx(p.0)), b.max(fx(p.0)))
            });
            let (mut y0, mut y1) = pts
                .iter()
                .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.1), b.max(p.1)));
            let (px, py) = (((x1 - x0) * 0.08).max(1e-3), ((y1 - y0) * 0.08).max(1e-3));
            (x0, x1, y0, y1) = (x0 - px, x1 + px, y0 - py, y1 + py);
            let mut c = ChartBuilder::on(&area)
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(56)
                .build_cartesian_2d(x0..x1, y0..y1)
                .map_err(plot_err)?;
            c.configure_mesh()
                .x_desc(if log_x {
                    format!("{x_desc} (log10)")
                } else {
                    x_desc.to_string()
                })
                .y_desc(*y_desc)
                .draw()
                .map_err(plot_err)?;
            for (label, points) in series {
                let colour = colour_of(label);
                let xy: Vec<(f64, f64)> = points.iter().map(|p| (fx(p.0), p.1)).collect();
                if xy.len() > 1 {
                    c.draw_series(LineSeries::new(xy.clone(), colour.stroke_width(2)))
                        .map_err(plot_err)?;
                }
                c.draw_series(xy.iter().map(|p| Circle::new(*p, 5, colour.filled())))
                    .map_err(plot_err)?;
            }
        }
        root.present().map_err(plot_err)?;
    }
    write_png_rgb(path, w, h, &buf)
}

fn write_png_rgb(path: &Path, w: u32, h: u32, rgb: &[u8]) -> anyhow::Result<()> {
    let file = std::fs::File::create(path).with_context(|| format!("{}", path.display()))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header()?.write_image_data(rgb)?;
    Ok(())
}

/// Images side by side (all the same size), RGBA, as one PNG.
pub fn side_by_side(path: &Path, w: u32, h: u32, images: &[&[u8]]) -> anyhow::Result<()> {
    let total = w * images.len() as u32;
    let mut rgb = vec![0u8; (total * h * 3) as usize];
    for (k, img) in images.iter().enumerate() {
        for y in 0..h as usize {
            for x in 0..w as usize {
                let s = (y * w as usize + x) * 4;
                let d = (y * total as usize + k * w as usize + x) * 3;
                rgb[d..d + 3].copy_from_slice(&img[s..s + 3]);
            }
        }
    }
    write_png_rgb(path, total, h, &rgb)
}

fn series_by_label(rows: &[&Row], x: impl Fn(&Row) -> f64, metric: usize) -> Series {
    let mut by_label: BTreeMap<String, Vec<&Row>> = BTreeMap::new();
    for r in rows {
        by_label.entry(r.label()).or_default().push(r);
    }
    by_label
        .into_iter()
        .map(|(label, rs)| {
            let means = group_means(&rs, |r| (x(r) * 1e6).round() as i64);
            let pts = means
                .into_iter()
                .map(|(k, v)| (k as f64 / 1e6, v[metric]))
                .collect();
            (label, pts)
        })
        .collect()
}

const PSNR: usize = 2;
const SSIM: usize = 3;
const HOLES: usize = 6;
const GPU_MS: usize = 8;
const ALBEDO_PSNR: usize = 9;
const ALBEDO_SSIM: usize = 10;
const SILHOUETTE: usize = 11;

pub fn charts(dir: &Path, rows: &[Row]) -> anyhow::Result<()> {
    let main: Vec<&Row> = rows.iter().filter(|r| !r.stability).collect();
    // Quality against time: one mark per pipeline and setting, means over the main scenes.
    let means = group_means(&main, Row::label);
    let marks = |metric: usize| -> Series {
        means
            .iter()
            .map(|(l, v)| (l.clone(), vec![(v[GPU_MS], v[metric])]))
            .collect()
    };
    chart(
        &dir.join("quality_vs_time.png"),
        "Quality against GPU time (means over bunny, spot and the bunny scans)",
        "GPU ms per frame",
        false,
        &[
            ("albedo PSNR (dB)", marks(ALBEDO_PSNR)),
            ("albedo SSIM", marks(ALBEDO_SSIM)),
        ],
    )?;
    let sampled: Vec<&Row> = main
        .iter()
        .copied()
        .filter(|r| r.scene != "bunny_scans" && r.noise == 0.0)
        .collect();
    chart(
        &dir.join("quality_vs_density.png"),
        "Quality against density (bunny and spot sampled, no noise)",
        "points per pixel",
        true,
        &[
            (
                "albedo PSNR (dB)",
                series_by_label(&sampled, |r| r.density, ALBEDO_PSNR),
            ),
            ("hole rate", series_by_label(&sampled, |r| r.density, HOLES)),
        ],
    )?;
    let min_density = main
        .iter()
        .filter(|r| r.scene != "bunny_scans")
        .map(|r| r.density)
        .fold(f64::MAX, f64::min);
    let noisy: Vec<&Row> = main
        .iter()
        .copied()
        .filter(|r| r.scene != "bunny_scans" && r.density > min_density)
        .collect();
    chart(
        &dir.join("quality_vs_noise.png"),
        "Quality against noise (bunny and spot sampled)",
        "noise sigma / bounding diagonal",
        false,
        &[
            (
                "albedo PSNR (dB)",
                series_by_label(&noisy, |r| r.noise, ALBEDO_PSNR),
            ),
            (
                "albedo SSIM",
                series_by_label(&noisy, |r| r.noise, ALBEDO_SSIM),
            ),
        ],
    )?;
    Ok(())
}

/// The Markdown summary: means per scene and pipeline, and the targets checked.
pub fn summary(rows: &[Row], conditions: &str) -> (String, bool) {
    let mut md = String::from("# Quality against speed\n\n");
    let _ = writeln!(md, "{conditions}\n");
    md.push_str(
        "Means over views, densities and noise levels. Shaded: the image against the mesh lit as \
         the pipeline lights (none: unlit albedo; eye-dome: the albedo darkened by the mesh's \
         depth with the pipeline's EDL; headlight: Blinn-Phong). Albedo: the unlit colour \
         against the mesh's albedo, comparable across pipelines.\n\n",
    );
    md.push_str("| scene | pipeline | setting | lighting | shaded PSNR dB | shaded SSIM | albedo PSNR dB | albedo SSIM | depth err | normal err ° | holes | leaks | silhouette px | GPU ms |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    let all: Vec<&Row> = rows.iter().collect();
    let lighting: BTreeMap<String, &str> = rows.iter().map(|r| (r.label(), r.lighting)).collect();
    for ((scene, label), v) in group_means(&all, |r| (r.scene.clone(), r.label())) {
        let (p, s) = label.split_once(' ').unwrap_or((&label, ""));
        let light = lighting.get(&label).copied().unwrap_or("");
        let _ = writeln!(
            md,
            "| {scene} | {p} | {s} | {light} | {:.2} | {:.3} | {:.2} | {:.3} | {:.4} | {:.1} | {:.3} | {:.3} | {:.2} | {:.1} |",
            v[PSNR],
            v[SSIM],
            v[ALBEDO_PSNR],
            v[ALBEDO_SSIM],
            v[4],
            v[5],
            v[HOLES],
            v[7],
            v[SILHOUETTE],
            v[GPU_MS]
        );
    }
    md.push_str(&surfel_modes(rows));
    md.push_str(&layers_and_shadows(rows));
    md.push_str("\n## Targets\n\n");
    let mut ok = true;
    for reconstruction in ["pyramid", "surfels", "filters"] {
        let (targets, met) = check_targets(rows, reconstruction);
        md.push_str(&targets);
        ok &= met;
    }
    let (targets, met) = super::triangulate_targets::check(rows);
    md.push_str(&targets);
    (md, ok && met)
}

/// The rows of the comparison scenes (not the stability sweeps) per frame: scene, view, and
/// density and noise in millionths.
pub type Frames<'a> = BTreeMap<(String, usize, i64, i64), Vec<&'a Row>>;

pub fn frames_of(rows: &[Row]) -> Frames<'_> {
    let mut frames: Frames = BTreeMap::new();
    for r in rows.iter().filter(|r| !r.stability) {
        let key = (
            r.scene.clone(),
            r.view,
            (r.density * 1e6) as i64,
            (r.noise * 1e6) as i64,
        );
        frames.entry(key).or_default().push(r);
    }
    frames
}

/// On the bunny scans and at every sampled density where `points 1px` leaves holes, `pyramid`
/// must have at most half its hole rate and an albedo PSNR and SSIM at least those of every `points`
/// and `edl` setting (the albedo: the shaded images are each against their own lighting).
/// Compared per frame (scene, view, density, noise).
fn check_targets(rows: &[Row], name: &str) -> (String, bool) {
    let frames = frames_of(rows);
    let mut out = String::new();
    let mut ok = true;
    let (mut checked, mut failed) = (0, 0);
    for ((scene, view, _, _), rs) in &frames {
        let find = |label: &str| rs.iter().find(|r| r.label() == label);
        let (Some(points), Some(pyramid)) = (find("points 1px"), find(&format!("{name} 1px")))
        else {
            continue;
        };
        if scene != "bunny_scans" && points.metrics.hole_rate < 0.01 {
            continue;
        }
        checked += 1;
        let rivals: Vec<&&Row> = rs
            .iter()
            .filter(|r| r.pipeline == "points" || r.pipeline == "edl")
            .collect();
        let pm = &pyramid.metrics;
        let holes_ok = pm.hole_rate <= 0.5 * points.metrics.hole_rate;
        // At least as high: where every pixel holds a point (dense scans at a small size) the
        // reconstruction has nothing to fill, and its colours are the points' own.
        let psnr_ok = rivals.iter().all(|r| pyramid.albedo_psnr >= r.albedo_psnr);
        let ssim_ok = rivals.iter().all(|r| pyramid.albedo_ssim >= r.albedo_ssim);
        if !(holes_ok && psnr_ok && ssim_ok) {
            failed += 1;
            ok = false;
            let _ = writeln!(
                out,
                "- MISSED {scene} view {view} density {:.3} noise {:.4}: {name} holes {:.3} vs points {:.3}, albedo PSNR {:.2} vs best rival {:.2}, albedo SSIM {:.3} vs {:.3}",
                points.density,
                points.noise,
                pm.hole_rate,
                points.metrics.hole_rate,
                pyramid.albedo_psnr,
                rivals
                    .iter()
                    .map(|r| r.albedo_psnr)
                    .fold(f64::MIN, f64::max),
                pyramid.albedo_ssim,
                rivals
                    .iter()
                    .map(|r| r.albedo_ssim)
                    .fold(f64::MIN, f64::max),
            );
        }
    }
    let _ = writeln!(
        out,
        "\n{name}: {} of {checked} frames meet the quality targets ({name} holes at most half of points 1px; albedo PSNR and SSIM at least those of every points and edl setting).\n",
        checked - failed
    );
    (out, ok)
}
