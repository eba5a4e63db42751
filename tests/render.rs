//! Headless rendering on the software adapter (lavapipe): coverage, the point budget, the two
//! projection paths, corrupt nodes, fly-throughs, bad arguments, colouring by normal and by
//! curvature, the surfels, the filters, the triangulation, leaves sized by their measured
//! density, the demo, and the window under Xvfb.

#[path = "render/colours.rs"]
mod colours;
mod common;
#[path = "render/damaged.rs"]
mod damaged;
#[path = "render/demo.rs"]
mod demo;
#[path = "render/facing.rs"]
mod facing;
#[path = "render/filter_holes.rs"]
mod filter_holes;
#[path = "render/filter_shadows.rs"]
mod filter_shadows;
#[path = "render/filters.rs"]
mod filters;
#[path = "render/fly_through.rs"]
mod fly_through;
#[path = "render/footprint.rs"]
mod footprint;
#[path = "render/guard_band.rs"]
mod guard_band;
#[path = "render/leaf_density.rs"]
mod leaf_density;
#[path = "render/near.rs"]
mod near;
#[path = "render/notches.rs"]
mod notches;
#[path = "render/occlusion_edge.rs"]
mod occlusion_edge;
#[path = "render/paths.rs"]
mod paths;
#[path = "render/pyramid.rs"]
mod pyramid;
#[path = "render/slits.rs"]
mod slits;
#[path = "render/stored_normals.rs"]
mod stored_normals;
#[path = "render/surfels.rs"]
mod surfels;
#[path = "render/triangulate.rs"]
mod triangulate;

use common::{data, gpu_ok, gpu_run, read_png, s, strata};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use strata_viewer::StreamDataset;
use strata_viewer::headless::default_camera;

const BACKGROUND: [u8; 3] = [24, 26, 32];

/// Datasets built once per test binary, shared read-only by the tests.
fn fixtures() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = common::fresh_dir("render-fixtures");
        let autzen = dir.join("autzen.strata");
        common::run_ok(&[
            "convert",
            s(&data("autzen_trim.laz")),
            "-o",
            s(&autzen),
            "--quiet",
        ]);
        let bunny = dir.join("bunny.strata");
        common::run_ok(&[
            "convert",
            s(&data("bunny_range_scans_merged.ply")),
            "-o",
            s(&bunny),
            "--quiet",
        ]);
        let city_las = dir.join("city.las");
        common::run_ok(&[
            "synth",
            "--points",
            "400k",
            "-o",
            s(&city_las),
            "--seed",
            "3",
        ]);
        let city = dir.join("city.strata");
        common::run_ok(&["convert", s(&city_las), "-o", s(&city), "--quiet"]);
        dir
    })
}

fn stats(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).expect("stats written")).expect("stats JSON")
}

fn drawn(px: &[u8]) -> bool {
    px[..3] != BACKGROUND
}

/// The screen rectangle (x0, y0, x1, y1) that the dataset's bounds project to under the
/// default camera.
fn projected_bounds(dataset: &Path, w: u32, h: u32) -> (f32, f32, f32, f32) {
    let ds = StreamDataset::open_path(dataset).expect("dataset opens");
    let cam = default_camera(&ds, w, h);
    let (min, max) = ds.bounds();
    let vp = cam.projection(w as f32 / h as f32, 0.01, 1e7) * cam.view();
    let mut r = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
    for c in strata_viewer::camera::box_corners(min, max) {
        let p = vp.project_point3(c);
        let (x, y) = ((p.x * 0.5 + 0.5) * w as f32, (0.5 - p.y * 0.5) * h as f32);
        r = (r.0.min(x), r.1.min(y), r.2.max(x), r.3.max(y));
    }
    r
}

/// Renders the default view and checks that points cover a good part of where the dataset
/// projects and nothing outside it.
fn check_coverage(name: &str, min_fraction: f64) {
    let dir = fixtures();
    let dataset = dir.join(name);
    let out = dir.join(format!("{name}-coverage.png"));
    gpu_ok(&[
        "render",
        s(&dataset),
        "-o",
        s(&out),
        "--size",
        "320x240",
        "--pipeline",
        "points",
        "--wait-complete",
    ]);
    let (w, h, rgba) = read_png(&out);
    assert_eq!((w, h), (320, 240));
    let (x0, y0, x1, y1) = projected_bounds(&dataset, w, h);
    let (mut inside, mut inside_drawn, mut outside_drawn) = (0u64, 0u64, 0u64);
    for y in 0..h {
        for x in 0..w {
            let px = &rgba[((y * w + x) * 4) as usize..][..4];
            let (fx, fy) = (x as f32 + 0.5, y as f32 + 0.5);
            // Two pixels of slack for splats at the edge.
            if fx >= x0 - 2.0 && fx <= x1 + 2.0 && fy >= y0 - 2.0 && fy <= y1 + 2.0 {
                inside += 1;
                inside_drawn += drawn(px) as u64;
            } else {
                outside_drawn += drawn(px) as u64;
            }
        }
    }
    let fraction = inside_drawn as f64 / inside.max(1) as f64;
    assert_eq!(
        outside_drawn, 0,
        "{name}: points drawn outside the dataset's projection"
    );
    assert!(
        fraction >= min_fraction,
        "{name}: only {:.1}% of the projected bounds covered",
        fraction * 100.0
    );
}

#[test]
fn autzen_covers_its_projection() {
    check_coverage("autzen.strata", 0.25);
}

#[test]
fn bunny_covers_its_projection() {
    check_coverage("bunny.strata", 0.15);
}

fn render_stats(dataset: &Path, tag: &str, extra: &[&str]) -> (serde_json::Value, PathBuf) {
    let out = dataset.with_file_name(format!("{tag}.png"));
    let st = dataset.with_file_name(format!("{tag}.json"));
    let mut args = vec![
        "render",
        s(dataset),
        "-o",
        s(&out),
        "--stats",
        s(&st),
        "--wait-complete",
    ];
    args.extend_from_slice(extra);
    gpu_ok(&args);
    (stats(&st), out)
}

#[test]
fn budget_is_a_ceiling_and_a_smaller_budget_draws_fewer_points() {
    let city = fixtures().join("city.strata");
    let drawn_with = |budget: &str| {
        let (st, _) = render_stats(
            &city,
            &format!("budget-{budget}"),
            &["--budget", budget, "--size", "800x600"],
        );
        let frame = &st["frames"][0];
        let points = frame["points_drawn"].as_u64().expect("points_drawn");
        assert!(frame["complete"].as_bool().expect("complete"));
        for key in [
            "nodes_drawn",
            "frame_ms",
            "passes",
            "bytes_loaded",
            "nodes_failed",
        ] {
            assert!(!frame[key].is_null(), "stats lack {key}");
        }
        points
    };
    let small = drawn_with("100k");
    let large = drawn_with("1M");
    assert!(small <= 100_000, "{small} points drawn under a 100k budget");
    assert!(small > 0);
    assert!(small < large, "budget 100k drew {small}, 1M drew {large}");
    assert!(large <= 1_000_000);
}

#[test]
fn a_small_view_loads_only_what_it_can_show() {
    let city = fixtures().join("city.strata");
    let (tiny, _) = render_stats(&city, "tiny-view", &["--budget", "10M", "--size", "32x32"]);
    let (big, _) = render_stats(&city, "big-view", &["--budget", "10M", "--size", "800x600"]);
    let points = |v: &serde_json::Value| v["frames"][0]["points_drawn"].as_u64().unwrap_or(0);
    assert!(
        points(&tiny) * 4 < points(&big),
        "a 32x32 view drew {} points, an 800x600 view {}",
        points(&tiny),
        points(&big)
    );
}

/// A camera that looks away from the data loads and draws nothing, the root included (it was
/// loaded and charged to the budget).
#[test]
fn a_view_away_from_the_data_draws_no_node() {
    let city = fixtures().join("city.strata");
    let ds = StreamDataset::open_path(&city).expect("opens");
    let a = ds.anchor();
    let (min, max) = ds.bounds();
    let (lo, hi) = (a + min.as_dvec3(), a + max.as_dvec3());
    // Beyond the root's cube, which reaches past the data.
    let beyond = hi.x + 2.0 * (hi - lo).max_element();
    let eye = glam::DVec3::new(beyond, (lo.y + hi.y) / 2.0, (lo.z + hi.z) / 2.0);
    let camera = format!(
        "eye={},{},{};target={},{},{};fov=40",
        eye.x,
        eye.y,
        eye.z,
        eye.x + 100.0,
        eye.y,
        eye.z
    );
    let (st, _) = render_stats(&city, "away", &["--size", "160x120", "--camera", &camera]);
    let frame = &st["frames"][0];
    assert_eq!(frame["nodes_drawn"].as_u64(), Some(0), "{frame}");
    assert_eq!(frame["points_drawn"].as_u64(), Some(0), "{frame}");
    assert_eq!(frame["complete"].as_bool(), Some(true), "{frame}");
}

/// Of two images of the same points, the fraction of drawn pixels that `shaded` darkens, after
/// checking it is nowhere brighter than `plain` and draws the same pixels.
fn darkened_fraction(name: &str, plain: &Path, shaded: &Path) -> f64 {
    let (_, _, plain) = read_png(plain);
    let (_, _, shaded) = read_png(shaded);
    let (mut drawn_px, mut darker) = (0usize, 0usize);
    for (p, e) in plain.chunks_exact(4).zip(shaded.chunks_exact(4)) {
        assert_eq!(drawn(p), drawn(e), "{name}: EDL changed what is drawn");
        assert!(
            e[..3].iter().zip(&p[..3]).all(|(e, p)| e <= p),
            "{name}: EDL brightened {p:?} to {e:?}"
        );
        drawn_px += usize::from(drawn(p));
        darker += usize::from(e[..3] != p[..3]);
    }
    darker as f64 / drawn_px.max(1) as f64
}

#[test]
fn edl_darkens_only_when_asked_and_never_lightens() {
    let dataset = fixtures().join("autzen.strata");
    let render = |tag: &str, args: &[&str]| {
        let mut all = vec!["--size", "640x480"];
        all.extend_from_slice(args);
        render_stats(&dataset, tag, &all).1
    };
    let points = render("edl-off", &["--pipeline", "points"]);
    let edl = render("edl-on", &["--pipeline", "edl"]);
    let pyramid = render("pyramid-edl-off", &["--pipeline", "pyramid"]);
    let pyramid_edl = render(
        "pyramid-edl-on",
        &["--pipeline", "pyramid", "--pyramid-edl"],
    );
    // Every pixel with a nearer neighbour at the EDL radius darkens: on Autzen's sloping
    // ground, roofs and trees about 90 % of them on lavapipe, for both pipelines.
    for (name, plain, shaded) in [("edl", &points, &edl), ("pyramid", &pyramid, &pyramid_edl)] {
        let darker = darkened_fraction(name, plain, shaded);
        assert!(darker > 0.3, "{name}: EDL darkened {darker} of the pixels");
    }
}

#[test]
fn bad_arguments_get_one_clear_sentence() {
    let dataset = fixtures().join("autzen.strata");
    let out = fixtures().join("never.png");
    let cases: [(&[&str], &str); 7] = [
        (
            &["render", "/nonexistent/set.strata", "-o", s(&out)],
            "/nonexistent/set.strata",
        ),
        (
            &["render", s(&dataset), "-o", s(&out), "--camera", "eye=1,2"],
            "eye=1,2",
        ),
        (
            &["render", s(&dataset), "-o", s(&out), "--size", "10x"],
            "--size",
        ),
        (
            &["render", s(&dataset), "-o", s(&out), "--pipeline", "magic"],
            "magic",
        ),
        (
            &["render", s(&dataset), "-o", s(&out), "--budget", "10"],
            "--budget",
        ),
        (&["render", s(&dataset), "-o", s(&out), "--s0=-1"], "--s0"),
        (
            &[
                "render",
                s(&dataset),
                "-o",
                s(&out),
                "--pass-clock",
                "sundial",
            ],
            "sundial",
        ),
    ];
    for (args, needle) in cases {
        let o = gpu_run(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(
            err.contains(needle),
            "{args:?}: message {err:?} does not mention {needle}"
        );
        assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
        assert!(!out.exists(), "{args:?} left an image behind");
    }
}

#[test]
fn window_opens_under_xvfb_and_shows_the_panel() {
    if !common::have_xvfb() {
        return;
    }
    let dataset = fixtures().join("autzen.strata");
    let shot = fixtures().join("window.png");
    let backend = std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "vulkan".into());
    let o = std::process::Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1400x900x24"])
        .arg(env!("CARGO_BIN_EXE_strata"))
        .args([
            "view",
            s(&dataset),
            "--size",
            "1000x640",
            "--screenshot",
            s(&shot),
            "--screenshot-after",
            "20",
        ])
        .env("WGPU_BACKEND", backend)
        .output()
        .expect("xvfb-run runs");
    assert!(
        o.status.success(),
        "view failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let (w, h, rgba) = read_png(&shot);
    assert_eq!((w, h), (1000, 640));
    let px = |x: u32, y: u32| &rgba[((y * w + x) * 4) as usize..][..3];
    // The panel (left 280 px) holds text: many distinct light pixels on a dark panel.
    let panel_light = (0..h)
        .flat_map(|y| (0..270).map(move |x| (x, y)))
        .filter(|&(x, y)| px(x, y).iter().all(|&c| c > 150))
        .count();
    assert!(
        panel_light > 500,
        "the panel shows no text ({panel_light} light pixels)"
    );
    // The scene shows points beside it.
    let scene_drawn = (0..h)
        .flat_map(|y| (300..w).map(move |x| (x, y)))
        .filter(|&(x, y)| px(x, y) != BACKGROUND)
        .count();
    assert!(
        scene_drawn > 5000,
        "the scene shows {scene_drawn} drawn pixels"
    );
}

#[test]
fn a_small_gpu_cache_evicts_and_still_completes_every_frame() {
    let dataset = fixtures().join("city.strata");
    let ds = StreamDataset::open_path(&dataset).expect("opens");
    let a = ds.anchor();
    let (min, max) = ds.bounds();
    let (c, r) = ((min + max) * 0.5, (max - min).length());
    // Close views of opposite corners: each needs detail the other does not.
    let key = |x: f32, y: f32| {
        let t = glam::Vec3::new(
            min.x + (max.x - min.x) * x,
            min.y + (max.y - min.y) * y,
            c.z,
        );
        serde_json::json!({
            "eye": [a.x + (t.x - 0.05 * r) as f64, a.y + (t.y - 0.05 * r) as f64, a.z + (c.z + 0.08 * r) as f64],
            "target": [a.x + t.x as f64, a.y + t.y as f64, a.z + t.z as f64],
            "fov": 60.0
        })
    };
    let dir = fixtures().join("small-cache");
    std::fs::create_dir_all(&dir).expect("dir");
    let path = dir.join("path.json");
    let json =
        serde_json::json!({"keyframes": [key(0.15, 0.15), key(0.85, 0.85), key(0.15, 0.85)]});
    std::fs::write(&path, json.to_string()).expect("path");
    let st = dir.join("stats.json");
    let cache = 4u64 << 20;
    let out = gpu_ok(&[
        "render",
        s(&dataset),
        "-o",
        s(&dir.join("f.png")),
        "--path",
        s(&path),
        "--frames",
        "3",
        "--size",
        "400x300",
        "--budget",
        "1M",
        "--gpu-cache",
        "4MiB",
        "--wait-complete",
        "--stats",
        s(&st),
    ]);
    let v = stats(&st);
    let frames = v["frames"].as_array().expect("frames");
    assert_eq!(frames.len(), 3);
    let mut loaded_after_first = 0;
    for (i, f) in frames.iter().enumerate() {
        assert_eq!(f["complete"], true, "frame {i} incomplete: {f}");
        assert!(
            f["gpu_bytes"].as_u64().unwrap_or(u64::MAX) <= cache,
            "frame {i} over the cache: {f}"
        );
        assert!(f["points_drawn"].as_u64().unwrap_or(0) > 0);
        if i > 0 {
            loaded_after_first += f["bytes_loaded"].as_u64().unwrap_or(0);
        }
    }
    // The later views needed nodes again or anew: the cache evicted and reloaded.
    assert!(loaded_after_first > 0);
    // The budget (1M) was capped to what the cache holds: 4 MiB at 20 bytes a point; the
    // stats and a warning say so.
    for f in frames {
        let drawn_points = f["points_drawn"].as_u64().unwrap_or(u64::MAX);
        assert!(
            drawn_points * 20 <= cache,
            "{drawn_points} points drawn from a 4 MiB cache"
        );
        let budget = f["budget_drawn"].as_u64().unwrap_or(u64::MAX);
        assert!(budget * 20 <= cache && drawn_points <= budget, "{f}");
    }
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(
        said.contains("holds fewer points than the budget of 1000000"),
        "{said}"
    );
}

#[test]
fn render_replaces_only_what_it_wrote() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = fixtures().join("autzen.strata");
    // An input, and a dataset's metadata, aimed at by mistake: refused before any work.
    let las = dir.path().join("in.las");
    std::fs::write(&las, b"LASF, not an image").expect("write");
    let meta = dir.path().join("metadata.json");
    std::fs::copy(ds.join("metadata.json"), &meta).expect("copy");
    let png = dir.path().join("a.png");
    let st = dir.path().join("a.json");
    let missing = dir.path().join("missing").join("a.json");
    let fake = dir.path().join("fake.png");
    std::fs::write(&fake, b"not an image").expect("write");
    for (args, expect) in [
        (vec!["-o", s(&las)], "in.las: render writes PNG images"),
        (
            vec!["-o", s(&fake)],
            "fake.png: exists and is not a PNG image",
        ),
        (
            vec!["-o", s(&png), "--stats", s(&meta)],
            "metadata.json: exists and is not render statistics",
        ),
        // The statistics written over the image they describe, or the dataset they read.
        (
            vec!["-o", s(&png), "--stats", s(&ds.join("metadata.json"))],
            "metadata.json: exists and is not render statistics",
        ),
        (
            vec!["-o", s(&png), "--stats", s(&png)],
            "a.png: the --stats file would be written over",
        ),
        // Found unwritable only once the image was written.
        (
            vec!["-o", s(&png), "--stats", s(&missing)],
            "cannot write the --stats file",
        ),
        // PNG bytes under a JPEG's name.
        (
            vec!["-o", s(&dir.path().join("a.jpg"))],
            "a.jpg: render writes PNG images",
        ),
        // A finite number of seconds beyond what a duration holds panicked.
        (
            vec!["-o", s(&png), "--timeout", "1e300"],
            "--timeout 1e300 is not a number of seconds",
        ),
    ] {
        let mut all = vec!["render", s(&ds), "--size", "64x64"];
        all.extend(args);
        let o = common::run(&all);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(expect), "{err}");
    }
    assert_eq!(std::fs::read(&las).expect("read"), b"LASF, not an image");
    assert_eq!(
        std::fs::read(&meta).expect("read"),
        std::fs::read(ds.join("metadata.json")).expect("read")
    );
    assert!(!png.exists());
    // Its own image and statistics it replaces.
    for _ in 0..2 {
        gpu_ok(&[
            "render",
            s(&ds),
            "-o",
            s(&png),
            "--stats",
            s(&st),
            "--size",
            "64x64",
        ]);
    }
}
