//! The quality-versus-speed harness: renders ground-truth meshes and point sets of them through
//! every pipeline under the same cameras, and writes quality.csv, a Markdown summary, charts and
//! side-by-side images.
//!
//! Options: `USAGE` below, or `--help`.

use anyhow::{Context, bail};
use glam::DVec3;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};
use strata_bench::convert_with_normals;
use strata_bench::quality::cli::{Args, USAGE, parse_args};
use strata_bench::quality::configs::{Config, configs};
use strata_bench::quality::mesh::y_up_to_z_up;
use strata_bench::quality::metrics::{Frame, albedo_scores, compare};
use strata_bench::quality::reference::{ReferenceImage, ReferenceRenderer, lit_as, reference_clip};
use strata_bench::quality::report::{Row, charts, init_fonts, side_by_side, summary, write_csv};
use strata_bench::quality::sample::{PointSet, load_scan, sample_mesh, thin_along_x, write_ply};
use strata_bench::quality::scenes::{CLAY, Points, Scene, View, scenes, user_scene};
use strata_bench::quality::shadows;
use strata_bench::quality::temporal::{self, Temporal};
use strata_viewer::gpu::{GpuContext, ProjectionPath};
use strata_viewer::pipelines::edl;
use strata_viewer::pipelines::params::ParamSpec;
use strata_viewer::settings::SizeMode;
use strata_viewer::{Camera, Renderer, Settings, StreamDataset};

const BUDGET: u64 = 20_000_000;
const MAX_POINTS: usize = 4_000_000;

fn main() -> anyhow::Result<()> {
    if strata_bench::answered_help(USAGE) {
        return Ok(());
    }
    let args = parse_args()?;
    std::fs::create_dir_all(args.out.join("images"))
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    init_fonts()?;
    let ctx = Arc::new(GpuContext::new(ProjectionPath::Auto)?);
    let work = tempfile::tempdir_in(&args.out).context("cannot make a work directory")?;
    let mut scenes = scenes(&args.data, args.quick)?;
    for m in &args.meshes {
        let scene = user_scene(m, args.quick)?;
        if scenes.iter().any(|s| s.name == scene.name) {
            bail!(
                "--mesh {}: a scene is already named {:?}; rename the file",
                m.path.display(),
                scene.name
            );
        }
        scenes.push(scene);
    }
    if !args.scenes.is_empty() {
        if let Some(unknown) = args
            .scenes
            .iter()
            .find(|n| !scenes.iter().any(|s| &s.name == *n))
        {
            let known: Vec<&str> = scenes.iter().map(|s| s.name.as_str()).collect();
            bail!(
                "--scenes: no scene is named {unknown:?} (there are {})",
                known.join(", ")
            );
        }
        scenes.retain(|s| args.scenes.contains(&s.name));
    }
    let started = Instant::now();
    let mut rows = Vec::new();
    let mut over_frames = Vec::new();
    for scene in &scenes {
        let focal = args.height as f32 * 0.5 / (scene.views[0].fov_deg.to_radians() * 0.5).tan();
        let (lo, hi) = scene.mesh.bounds();
        let diagonal = (hi - lo).length();
        let (densities, noises): (&[f64], &[f64]) = match (scene.stability, args.quick) {
            (false, false) => (&[4.0, 1.0, 0.25, 0.1, 0.02], &[0.0, 0.002, 0.005]),
            (false, true) => (&[1.0, 0.1], &[0.0]),
            (true, false) => (&[1.0, 0.1, 0.02], &[0.0, 0.005]),
            (true, true) => (&[0.25], &[0.0]),
        };
        let noises = match &args.noises {
            Some(levels) if !scene.stability => levels.as_slice(),
            _ => noises,
        };
        let sets: Vec<(f64, f64, PointSet)> = match &scene.points {
            Points::Scan(path) => {
                let scan = load_scan(path, y_up_to_z_up, CLAY)?;
                let density = scan.positions.len() as f64 / screen_area(scene, focal);
                vec![(density, 0.0, scan)]
            }
            Points::Sampled | Points::Gradient(_) => densities
                .iter()
                .flat_map(|&d| noises.iter().map(move |&n| (d, n)))
                .map(|(d, n)| {
                    let mut set = sample_mesh(
                        &scene.mesh,
                        scene.views[0].eye,
                        focal,
                        d,
                        n as f32 * diagonal,
                        7,
                        MAX_POINTS,
                    );
                    if let Points::Gradient(ratio) = scene.points {
                        set = thin_along_x(set, ratio, 11);
                    }
                    (d, n, set)
                })
                .collect(),
        };
        for (density, noise, set) in sets {
            eprintln!(
                "{}: density {density:.3}, noise {noise}, {} points",
                scene.name,
                set.positions.len()
            );
            let dataset = convert_points(work.path(), &set)?;
            let ds = Arc::new(StreamDataset::open_path(&dataset)?);
            let reference = ReferenceRenderer::new(&ctx, &scene.mesh, ds.anchor());
            let mut renderer = Renderer::new(ctx.clone(), ds.clone(), 1 << 30, 2)?;
            for (vi, view) in scene.views.iter().enumerate() {
                let camera = camera_of(view, ds.anchor());
                let frames = render_view(
                    scene,
                    &mut renderer,
                    &reference,
                    &ctx,
                    &camera,
                    &args,
                    scene.stability,
                )?;
                if noise == 0.0 {
                    let at = (scene.name.as_str(), vi, density);
                    let (renderer, ctx) = (&mut renderer, ctx.as_ref());
                    // The stability sweeps measure the jump only: no orbit, and only the
                    // pipelines that keep the previous frame.
                    let orbit = !scene.stability;
                    over_frames.extend(temporal_rows(
                        renderer, &reference, ctx, &camera, &args, at, orbit,
                    )?);
                }
                let mut images: Vec<Vec<u8>> = vec![frames.reference.rgba.clone()];
                for r in frames.results {
                    // The side-by-side images show every pipeline at its defaults.
                    if r.config.auto_factor.is_none() && r.config.fixed.is_empty() {
                        images.push(r.rgba);
                    }
                    rows.push(Row {
                        scene: scene.name.clone(),
                        view: vi,
                        pipeline: r.config.pipeline.name.into(),
                        lighting: r.config.lighting_name(),
                        setting: r.config.setting,
                        density,
                        noise,
                        metrics: r.metrics,
                        albedo_psnr: r.albedo_psnr,
                        albedo_ssim: r.albedo_ssim,
                        gpu_ms: r.gpu_ms,
                        stability: scene.stability,
                        shadow_match: r.shadow_match,
                    });
                }
                if vi == 0 && noise == 0.0 {
                    let name = format!("{}_d{density:.3}.png", scene.name);
                    // The reference, then every pipeline at its defaults with 1 and 2 px points.
                    let refs: Vec<&[u8]> = images.iter().map(Vec::as_slice).collect();
                    side_by_side(
                        &args.out.join("images").join(name),
                        args.width,
                        args.height,
                        &refs,
                    )?;
                }
            }
            drop(renderer);
            std::fs::remove_dir_all(&dataset).ok();
        }
    }
    let bad: Vec<&Row> = rows
        .iter()
        .filter(|r| r.values().iter().any(|v| !v.is_finite()))
        .collect();
    write_csv(&args.out.join("quality.csv"), &rows)?;
    charts(&args.out, &rows)?;
    let conditions = format!(
        "{} frames at {}x{} on {} ({} projection), budget {BUDGET} points, every point drawn (LOD detail 0); {:.0} s.",
        rows.len(),
        args.width,
        args.height,
        ctx.adapter_name,
        if ctx.int64_atomics { "int64" } else { "int32" },
        started.elapsed().as_secs_f64()
    );
    let (mut md, mut targets_met) = summary(&rows, &conditions);
    md.push_str(&temporal::markdown(&over_frames));
    if let Some(slow) = over_frames.iter().find(|t| {
        t.jump_frames
            .is_some_and(|f| f > temporal::TARGET_JUMP_FRAMES)
    }) {
        md.push_str(&format!(
            "\nMissed: {} needs {:?} frames after a jump on {} view {} (target {}).\n",
            slow.pipeline,
            slow.jump_frames,
            slow.scene,
            slow.view,
            temporal::TARGET_JUMP_FRAMES
        ));
        targets_met = false;
    }
    std::fs::write(args.out.join("summary.md"), &md)?;
    println!("{md}");
    println!(
        "wrote {} (quality.csv, summary.md, quality_vs_time.png, quality_vs_density.png, quality_vs_noise.png, images/)",
        args.out.display()
    );
    if !targets_met {
        println!("note: some frames miss the quality targets (listed above)");
    }
    if !bad.is_empty() {
        bail!("{} rows hold NaN or Inf, first: {:?}", bad.len(), bad[0]);
    }
    Ok(())
}

/// Draws frames until every node the view needs is resident with what `settings` needs.
fn load_all(
    renderer: &mut Renderer,
    camera: &Camera,
    w: u32,
    h: u32,
    settings: &Settings,
) -> anyhow::Result<()> {
    let start = Instant::now();
    loop {
        let stats = renderer.frame(camera, w, h, settings)?;
        renderer.wait_gpu()?;
        if stats.complete {
            return Ok(());
        }
        if start.elapsed() > Duration::from_secs(120) {
            bail!("the view did not finish loading in 120 s");
        }
        renderer.wait_for_loads(Duration::from_millis(50));
    }
}

/// The mesh's area in pixels as seen from the first view, facing the eye: the measure that
/// sampled densities are given in.
fn screen_area(scene: &Scene, focal: f32) -> f64 {
    let eye = scene.views[0].eye;
    scene
        .mesh
        .triangles
        .iter()
        .map(|t| {
            let c = scene.mesh.corners(*t);
            let centroid = (c[0] + c[1] + c[2]) / 3.0;
            let k = focal as f64 / (centroid - eye).length().max(1e-6) as f64;
            strata_bench::quality::mesh::triangle_area(c) as f64 * k * k
        })
        .sum()
}

fn camera_of(view: &View, anchor: DVec3) -> Camera {
    Camera {
        eye: (view.eye.as_dvec3() - anchor).as_vec3(),
        target: (view.target.as_dvec3() - anchor).as_vec3(),
        fov_y: view.fov_deg.to_radians(),
    }
}

fn convert_points(dir: &Path, set: &PointSet) -> anyhow::Result<PathBuf> {
    let ply = dir.join("points.ply");
    write_ply(&ply, set)?;
    let dataset = dir.join("points.strata");
    // With normals, as a user converts for the shaded pipelines: the sampled meshes' own
    // (kept), estimated for the scans.
    convert_with_normals(&ply, &dataset, 1 << 30)?;
    std::fs::remove_file(&ply).ok();
    Ok(dataset)
}

struct ViewFrames {
    reference: ReferenceImage,
    results: Vec<ConfigResult>,
}

/// One configuration's frame of a view: its image and scores.
struct ConfigResult {
    config: Config,
    rgba: Vec<u8>,
    metrics: strata_bench::quality::metrics::Metrics,
    albedo_psnr: f64,
    albedo_ssim: f64,
    gpu_ms: f64,
    shadow_match: Option<(f64, f64, f64)>,
}

fn render_view(
    scene: &Scene,
    renderer: &mut Renderer,
    reference: &ReferenceRenderer,
    ctx: &GpuContext,
    camera: &Camera,
    args: &Args,
    stability: bool,
) -> anyhow::Result<ViewFrames> {
    let (w, h) = (args.width, args.height);
    let base = Settings {
        budget: BUDGET,
        min_spacing_px: 0.0,
        upload_points_per_frame: None,
        ..Settings::default()
    };
    // Load everything the view needs.
    load_all(renderer, camera, w, h, &base)?;
    let aspect = w as f32 / h as f32;
    let (near, far) = reference_clip(renderer.dataset(), camera, aspect);
    let reference_image = reference.render(
        ctx,
        camera.view(),
        camera.projection(aspect, near, far),
        w,
        h,
        base.background,
    )?;
    let tan_y = (camera.fov_y * 0.5).tan();
    let tan_half = [tan_y * aspect, tan_y];
    // Each pipeline's automatic values at its defaults, for the sweeps around them.
    let mut automatic: std::collections::HashMap<(&str, &str), f32> = Default::default();
    let mut results = Vec::new();
    for config in configs(!args.quick && !stability) {
        let p = config.pipeline;
        let mut settings = Settings {
            pipeline: p,
            point_size: config.point_size,
            size_mode: SizeMode::Fixed,
            ..base.clone()
        };
        if let Some((name, f)) = config.auto_factor {
            let Some(value) = automatic.get(&(p.name, name)) else {
                continue;
            };
            // Kept within the parameter's range: a sweep never aborts the run.
            let spec = p.param(name)?;
            let swept = (value * f).clamp(spec.min, spec.max);
            settings.set_param(&format!("{name}={swept}"))?;
        }
        let peeled = config.peeled();
        if config.scene().is_some_and(|only| only != scene.name) {
            continue;
        }
        for (name, value) in config.fixed {
            settings.set_param(&format!("{name}={value}"))?;
        }
        // A pipeline that needs other per-point streams (normals, radii) has the nodes loaded
        // again with them.
        load_all(renderer, camera, w, h, &settings)?;
        // A pipeline that builds on the previous frame converges over frames of the view first.
        for _ in 0..p.warmup_frames(&settings.params) {
            renderer.frame(camera, w, h, &settings)?;
            renderer.wait_gpu()?;
        }
        // First with separate passes, which keep the resolved colour plane, for the albedo;
        // it also warms the pipeline up, so the timed frame is of a warm pipeline.
        let separate = Settings {
            fused_finish: false,
            ..settings.clone()
        };
        renderer.frame(camera, w, h, &separate)?;
        renderer.wait_gpu()?;
        let albedo: Vec<u8> = renderer
            .read_albedo()?
            .into_iter()
            .flat_map(|c| {
                let [r, g, b] = c.unwrap_or(base.background);
                [r, g, b, 255]
            })
            .collect();
        let stats = renderer.frame(camera, w, h, &settings)?;
        renderer.wait_gpu()?;
        if config.auto_factor.is_none() && config.fixed.is_empty() {
            for spec in p.params.iter().filter(|s| s.auto.is_some()) {
                if let Some(v) = stats.params.get(spec.name) {
                    automatic.entry((p.name, spec.name)).or_insert(*v);
                }
            }
        }
        let gpu_ms: f64 = renderer.pass_times().iter().map(|(_, ms)| ms).sum();
        let (_, _, rgba) = renderer.read_image()?;
        let surface = renderer
            .read_surface()?
            .into_iter()
            .map(|p| p.map(|p| (p.depth, p.normal.map(glam::Vec3::from_array))))
            .collect();
        let frame = Frame {
            width: w,
            height: h,
            rgba: &rgba,
            surface,
        };
        let param = |spec: &ParamSpec| stats.params.get(spec.name).copied().unwrap_or(spec.default);
        let mut shadow_match = None;
        let lit = match peeled {
            Some((layers, opacity)) => reference.render_peeled(
                ctx,
                camera.view(),
                camera.projection(aspect, near, far),
                w,
                h,
                base.background,
                layers,
                opacity,
            )?,
            // Lit from the configuration's light, with the mesh's own shadows (a ray per
            // pixel towards the light), and each pixel's lit or shadowed state scored.
            None if config.shadowed() => {
                // The same view without shadows: what a lit pixel of the frame looks like.
                let mut unshadowed = settings.clone();
                unshadowed.set_param("shadows=0")?;
                renderer.frame(camera, w, h, &unshadowed)?;
                renderer.wait_gpu()?;
                let (_, _, plain) = renderer.read_image()?;
                let lit_by_mesh = shadows::lit_by_mesh(
                    &scene.mesh,
                    renderer.dataset().anchor(),
                    camera.view(),
                    tan_half,
                    (w, h),
                    &reference_image.surface,
                    config.light(),
                );
                let region: Vec<bool> = reference_image
                    .surface
                    .iter()
                    .zip(&frame.surface)
                    .map(|(r, f)| r.is_some() && f.is_some())
                    .collect();
                let scores =
                    shadows::shadow_scores(&rgba, &plain, &albedo, &lit_by_mesh, &region, (w, h));
                shadow_match = Some((scores.state, scores.shadow_iou, scores.speckle));
                let directional = reference.render_lit(
                    ctx,
                    camera.view(),
                    camera.projection(aspect, near, far),
                    w,
                    h,
                    base.background,
                    config.light(),
                )?;
                shadows::shadowed_reference(
                    &directional.rgba,
                    &reference_image.albedo,
                    &lit_by_mesh,
                )
            }
            None => lit_as(
                &reference_image,
                p.lighting,
                (param(&edl::STRENGTH), param(&edl::RADIUS)),
            ),
        };
        let metrics = compare(&lit, &reference_image.surface, &frame, tan_half);
        let (albedo_psnr, albedo_ssim) = albedo_scores(
            &reference_image.albedo,
            &reference_image.surface,
            &frame,
            &albedo,
        );
        results.push(ConfigResult {
            config,
            rgba,
            metrics,
            albedo_psnr,
            albedo_ssim,
            gpu_ms,
            shadow_match,
        });
    }
    Ok(ViewFrames {
        reference: reference_image,
        results,
    })
}

/// Every pipeline's measures over frames at its defaults on one view: the frames after a jump
/// (pipelines that keep the previous frame) and, with `orbit`, the flicker of a slow orbit.
#[allow(clippy::too_many_arguments)]
fn temporal_rows(
    renderer: &mut Renderer,
    reference: &ReferenceRenderer,
    ctx: &GpuContext,
    camera: &Camera,
    args: &Args,
    (scene, view, density): (&str, usize, f64),
    orbit: bool,
) -> anyhow::Result<Vec<Temporal>> {
    let size = (args.width, args.height);
    let mut out = Vec::new();
    for &pipeline in strata_viewer::pipelines::REGISTRY {
        if !orbit && !pipeline.previous_frame {
            continue;
        }
        let settings = Settings {
            pipeline,
            budget: BUDGET,
            min_spacing_px: 0.0,
            upload_points_per_frame: None,
            point_size: 1.0,
            size_mode: SizeMode::Fixed,
            ..Settings::default()
        };
        load_all(renderer, camera, size.0, size.1, &settings)?;
        let jump_frames = if pipeline.previous_frame {
            Some(temporal::jump_frames(
                renderer, &settings, reference, ctx, camera, size,
            )?)
        } else {
            None
        };
        let flicker = if orbit {
            Some(temporal::orbit_flicker(
                renderer, &settings, reference, ctx, camera, size,
            )?)
        } else {
            None
        };
        out.push(Temporal {
            scene: scene.to_string(),
            view,
            density,
            pipeline: pipeline.name,
            jump_frames,
            flicker,
        });
    }
    Ok(out)
}
