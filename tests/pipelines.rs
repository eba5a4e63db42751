//! The pipeline registry as a user meets it: `strata pipelines`, `--set` for every parameter,
//! and image sizes from 1x1 to past the adapter's limits with every pipeline, never a panic.

mod common;
#[path = "pipelines/passes.rs"]
mod passes;

use common::{gpu_run, s};
use std::path::{Path, PathBuf};
use std::process::Output;

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn dataset() -> PathBuf {
    common::converted("pipelines-fixture", "autzen_trim.laz", "autzen")
}

fn registry() -> Vec<serde_json::Value> {
    let o = common::run_ok(&["pipelines", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
    v.as_array().expect("a list").clone()
}

#[test]
fn pipelines_lists_every_pipeline_with_its_parameters() {
    let list = registry();
    let names: Vec<&str> = list.iter().filter_map(|p| p["name"].as_str()).collect();
    assert_eq!(
        names,
        [
            "points",
            "edl",
            "pyramid",
            "surfels",
            "filters",
            "triangulate"
        ]
    );
    let triangulate = &list[5];
    assert!(
        triangulate["paper"]
            .as_str()
            .is_some_and(|p| p.starts_with("002"))
    );
    let names_of = |p: &serde_json::Value| -> Vec<String> {
        p["params"]
            .as_array()
            .expect("params")
            .iter()
            .filter_map(|p| p["name"].as_str().map(str::to_string))
            .collect()
    };
    assert_eq!(
        names_of(triangulate),
        [
            "max_connection",
            "max_search_px",
            "stored_normals",
            "warmup"
        ]
    );
    assert_eq!(triangulate["params"][0]["default"], "auto");
    let filters = &list[4];
    assert!(
        filters["paper"]
            .as_str()
            .is_some_and(|p| p.starts_with("004"))
    );
    let filter_params: Vec<&str> = filters["params"]
        .as_array()
        .expect("params")
        .iter()
        .filter_map(|p| p["name"].as_str())
        .collect();
    for name in [
        "dtilde",
        "fill_iterations",
        "antialias",
        "layers",
        "opacity",
        "splat",
        "light.x",
        "opacity.6",
    ] {
        assert!(filter_params.contains(&name), "{name} in {filter_params:?}");
    }
    assert_eq!(filters["params"][0]["default"], "auto");
    // Modes are listed by name, in the order of their numbers.
    let param = |p: &serde_json::Value, name: &str| -> serde_json::Value {
        p["params"]
            .as_array()
            .and_then(|a| a.iter().find(|q| q["name"] == name).cloned())
            .unwrap_or_else(|| panic!("{name} is listed"))
    };
    let antialias = param(filters, "antialias");
    assert_eq!(antialias["scale"], "choice");
    assert_eq!(
        antialias["choices"],
        serde_json::json!(["off", "silhouettes", "edges"])
    );
    assert_eq!(
        param(filters, "shadows")["choices"],
        serde_json::json!(["off", "hard", "soft"])
    );
    assert_eq!(param(filters, "layers")["choices"], serde_json::json!([]));
    let surfels = &list[3];
    assert!(
        surfels["paper"]
            .as_str()
            .is_some_and(|p| p.starts_with("001"))
    );
    let surfel_params: Vec<&str> = surfels["params"]
        .as_array()
        .expect("params")
        .iter()
        .filter_map(|p| p["name"].as_str())
        .collect();
    assert_eq!(
        surfel_params,
        [
            "mode",
            "sides",
            "rings",
            "epsilon",
            "h",
            "curvature",
            "flat_px",
            "falloff",
            "depth_offset"
        ]
    );
    let pyramid = &list[2];
    assert!(
        pyramid["paper"]
            .as_str()
            .is_some_and(|p| p.starts_with("003"))
    );
    assert_eq!(pyramid["lighting"], "headlight Blinn-Phong");
    let params: Vec<&str> = pyramid["params"]
        .as_array()
        .expect("params")
        .iter()
        .filter_map(|p| p["name"].as_str())
        .collect();
    assert_eq!(
        params,
        [
            "s0",
            "edl",
            "edl_strength",
            "edl_radius",
            "stored_normals",
            // The filters' light and point shadows, carried through the pull-push.
            "light.x",
            "light.y",
            "light.z",
            "shadows",
            "shadow_samples",
            "light_size",
            "shadow_budget"
        ]
    );
    assert_eq!(pyramid["params"][0]["default"], "auto");
    assert!(
        pyramid["passes"]
            .as_array()
            .is_some_and(|p| p.iter().any(|n| n == "hpr"))
    );
    let plain = common::run_ok(&["pipelines"]);
    let plain = String::from_utf8_lossy(&plain.stdout);
    assert!(plain.contains("--set edl_strength=VALUE"), "{plain}");
}

#[test]
fn set_takes_any_parameter_and_names_a_wrong_one() {
    let ds = &dataset();
    let dir = ds.parent().expect("parent");
    let out = dir.join("set.png");
    let stats = dir.join("set.json");
    let o = gpu_run(&[
        "render",
        s(ds),
        "-o",
        s(&out),
        "--size",
        "64x48",
        "--pipeline",
        "edl",
        "--set",
        "edl_strength=2.5",
        "--set",
        "edl_radius=2",
        "--stats",
        s(&stats),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let st: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&stats).expect("stats")).expect("JSON");
    let frame = &st["frames"][0];
    assert_eq!(frame["pipeline"], "edl");
    assert_eq!(frame["params"]["edl_strength"].as_f64(), Some(2.5));
    assert_eq!(frame["params"]["edl_radius"].as_f64(), Some(2.0));

    for (args, names) in [
        (
            &["--pipeline", "edl", "--set", "glow=1"][..],
            &["glow", "edl_strength"][..],
        ),
        (
            &["--pipeline", "edl", "--set", "edl_strength=9"],
            &["edl_strength", "0.1", "4"],
        ),
        (
            &["--pipeline", "edl", "--set", "edl_radius=wide"],
            &["edl_radius"],
        ),
        (
            &["--pipeline", "edl", "--set", "edl_radius"],
            &["NAME=VALUE"],
        ),
        (
            &["--pipeline", "points", "--set", "s0=1"],
            &["points", "no parameters"],
        ),
        (&["--pipeline", "edl", "--s0", "1"], &["--s0", "s0"]),
        (&["--pipeline", "pyramid", "--s0=-1"], &["--s0", "s0"]),
        (
            &["--pipeline", "pyramid", "--set", "edl=0.5"],
            &["edl", "whole"],
        ),
        (
            &["--pipeline", "filters", "--set", "light=1,2"],
            &["light", "three numbers"],
        ),
        (
            &["--pipeline", "filters", "--set", "layers=9"],
            &["layers", "1", "8"],
        ),
        (
            &["--pipeline", "filters", "--set", "shadows=bright"],
            &["shadows", "off, hard or soft"],
        ),
    ] {
        let mut all = vec!["render", s(ds), "-o", s(&out), "--size", "64x48"];
        all.extend_from_slice(args);
        let o = gpu_run(&all);
        let t = text(&o);
        assert!(!o.status.success(), "{args:?} was accepted");
        assert!(!t.contains("panicked"), "{t}");
        assert_eq!(
            t.trim().lines().count(),
            1,
            "{args:?}: not one sentence: {t}"
        );
        for n in names {
            assert!(t.contains(n), "{args:?}: {t:?} does not name {n}");
        }
    }
    // The parameters a render with `args` records in its stats.
    let params_of = |args: &[&str]| -> serde_json::Value {
        let mut all = vec!["render", s(ds), "-o", s(&out), "--size", "64x48"];
        all.extend_from_slice(args);
        all.extend_from_slice(&["--stats", s(&stats)]);
        let o = gpu_run(&all);
        assert!(o.status.success(), "{}", text(&o));
        let st: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&stats).expect("stats")).expect("JSON");
        st["frames"][0]["params"].clone()
    };
    // Shorthands and automatic values.
    let params = params_of(&["--pipeline", "pyramid", "--pyramid-edl", "--set", "s0=auto"]);
    assert_eq!(params["edl"].as_f64(), Some(1.0));
    assert!(params["s0"].as_f64().is_some_and(|v| v > 0.0), "{params}");
    // A mode by its name, in any case, or by its number.
    let params = params_of(&[
        "--pipeline",
        "filters",
        "--set",
        "shadows=Hard",
        "--set",
        "antialias=edges",
        "--set",
        "layers=2",
    ]);
    assert_eq!(params["shadows"].as_f64(), Some(1.0), "{params}");
    assert_eq!(params["antialias"].as_f64(), Some(2.0), "{params}");
}

#[test]
fn every_size_with_every_pipeline_renders_or_is_refused_in_one_sentence() {
    let ds = &dataset();
    let dir = ds.parent().expect("parent");
    for p in registry() {
        let name = p["name"].as_str().expect("name");
        for size in ["1x1", "17x3", "8192x8192", "16384x16384"] {
            let out = dir.join(format!("size_{name}_{size}.png"));
            let _ = std::fs::remove_file(&out);
            let o = gpu_run(&[
                "render",
                s(ds),
                "-o",
                s(&out),
                "--size",
                size,
                "--pipeline",
                name,
                "--timeout",
                "5",
            ]);
            let t = text(&o);
            assert!(!t.contains("panicked"), "{name} {size}: {t}");
            if o.status.success() {
                assert!(out.exists(), "{name} {size}: no image");
            } else {
                // Refused before anything was drawn: the size, the limit, and no image.
                assert!(t.contains(size), "{name} {size}: {t}");
                assert!(
                    t.contains("MiB") || t.contains("side"),
                    "{name} {size}: {t}"
                );
                assert_eq!(t.trim().lines().count(), 1, "{name} {size}: {t}");
                assert!(!out.exists(), "{name} {size}: an image was left");
            }
        }
    }
    // Sizes no adapter renders are refused by the command line.
    for size in ["0x10", "16385x16", "axb"] {
        let o = gpu_run(&["render", s(ds), "-o", "x.png", "--size", size]);
        assert!(!o.status.success(), "{size}");
        assert!(!text(&o).contains("panicked"), "{}", text(&o));
    }
}

#[test]
fn the_software_adapter_refuses_8192_squared_with_the_limit() {
    // lavapipe binds at most 128 MiB of storage: an 8192x8192 frame (512 MiB of 64-bit keys)
    // cannot exist there. Where an adapter holds it, there is nothing to refuse.
    let ds = &dataset();
    let out = ds.parent().expect("parent").join("huge.png");
    let o = gpu_run(&["render", s(ds), "-o", s(&out), "--size", "8192x8192"]);
    if o.status.success() {
        eprintln!("this adapter holds an 8192x8192 frame; nothing to refuse");
        return;
    }
    let t = text(&o);
    assert!(t.contains("an image of 8192x8192 needs a"), "{t}");
    assert!(
        t.contains("the largest image of that shape it holds is"),
        "{t}"
    );
    assert!(!out.exists());
}

#[test]
fn a_frame_larger_than_the_adapter_holds_is_an_error_and_the_fitted_size_renders() {
    use std::sync::Arc;
    use strata_viewer::gpu::{GpuContext, ProjectionPath};
    use strata_viewer::headless::default_camera;
    use strata_viewer::pipelines::find;
    use strata_viewer::{Renderer, Settings, StreamDataset};
    let ds = Arc::new(StreamDataset::open_path(&dataset()).expect("dataset opens"));
    let ctx = Arc::new(GpuContext::new(ProjectionPath::Auto).expect("GPU adapter"));
    let mut r = Renderer::new(ctx, ds.clone(), 1 << 30, 2).expect("renderer");
    let settings = Settings {
        pipeline: find("points").expect("registered"),
        ..Settings::default()
    };
    let (w, h) = (8192, 6144);
    let camera = default_camera(&ds, w, h);
    let (fw, fh) = r.fit_size(&settings, w, h);
    if (fw, fh) == (w, h) {
        eprintln!("this adapter holds {w}x{h}; nothing to fit");
        return;
    }
    // What the window does: asked for more than fits, it renders at the fitted size.
    assert!(fw < w && fh < h && (fw as f64 / fh as f64 - 4.0 / 3.0).abs() < 0.01);
    let e = r
        .frame(&camera, w, h, &settings)
        .expect_err("too large a frame is refused");
    assert!(e.to_string().contains(&format!("{w}x{h}")), "{e}");
    let stats = r
        .frame(&camera, fw, fh, &settings)
        .expect("the fitted size renders");
    r.wait_gpu().expect("GPU");
    assert_eq!(r.read_image().expect("image").0, fw);
    // The renderer goes on after the refusal: the frame drew the scan.
    assert!(stats.frame > 1);
    // A pipeline drawn with a guard band fits with its band: the wider its band, the smaller
    // the view that fits, and the fitted size holds where a pixel more does not.
    let banded = |search_px: &str| {
        let mut s = Settings {
            pipeline: find("triangulate").expect("registered"),
            ..Settings::default()
        };
        s.params
            .set_text(s.pipeline, "max_search_px", search_px)
            .expect("a value in range");
        s
    };
    let (narrow, wide) = (banded("1"), banded("47"));
    let (nw, nh) = r.fit_size(&narrow, w, h);
    let (bw, bh) = r.fit_size(&wide, w, h);
    assert!(bw < nw && bh < nh, "{bw}x{bh} against {nw}x{nh}");
    r.check_size(&wide, bw, bh).expect("the fitted size fits");
    r.check_size(&wide, bw + 2, bh + 2)
        .expect_err("a larger size does not");
}

#[test]
fn every_parameter_takes_its_range_and_refuses_past_it() {
    let ds = &dataset();
    let dir = ds.parent().expect("parent");
    let stats = dir.join("range.json");
    let out = dir.join("range.png");
    for p in registry() {
        let name = p["name"].as_str().expect("name");
        for spec in p["params"].as_array().expect("params") {
            let param = spec["name"].as_str().expect("param name");
            let (min, max) = (
                spec["min"].as_f64().expect("min"),
                spec["max"].as_f64().expect("max"),
            );
            for v in [min, max] {
                let set = format!("{param}={v}");
                let args = [
                    "render",
                    s(ds),
                    "-o",
                    s(&out),
                    "--size",
                    "16x16",
                    "--pipeline",
                    name,
                    "--set",
                    &set,
                    "--stats",
                    s(&stats),
                ];
                let o = gpu_run(&args);
                assert!(o.status.success(), "{name} {set}: {}", text(&o));
                let st: serde_json::Value =
                    serde_json::from_slice(&std::fs::read(&stats).expect("stats")).expect("JSON");
                let got = st["frames"][0]["params"][param].as_f64().expect("echoed");
                assert!(
                    (got - v).abs() <= v.abs() * 1e-6,
                    "{name} {set}: stats say {got}"
                );
            }
            let below = if min > 0.0 { min / 2.0 } else { min - 1.0 };
            for bad in [
                below.to_string(),
                (max * 2.0 + 1.0).to_string(),
                "abc".into(),
            ] {
                let set = format!("{param}={bad}");
                let args = [
                    "render",
                    s(ds),
                    "-o",
                    s(&out),
                    "--pipeline",
                    name,
                    "--set",
                    &set,
                ];
                let o = gpu_run(&args);
                let t = text(&o);
                assert!(!o.status.success(), "{name} {set} was accepted");
                assert_eq!(t.trim().lines().count(), 1, "{name} {set}: {t}");
                assert!(
                    t.contains(param) && !t.contains("panicked"),
                    "{name} {set}: {t}"
                );
            }
        }
    }
}

#[test]
fn a_lost_device_is_reported_by_every_frame_after_it() {
    use std::sync::Arc;
    use strata_viewer::gpu::{GpuContext, ProjectionPath};
    use strata_viewer::headless::default_camera;
    use strata_viewer::{Renderer, Settings, StreamDataset};
    let ds = Arc::new(StreamDataset::open_path(&dataset()).expect("dataset opens"));
    let ctx = Arc::new(GpuContext::new(ProjectionPath::Auto).expect("GPU adapter"));
    let mut r = Renderer::new(ctx.clone(), ds.clone(), 1 << 28, 1).expect("renderer");
    let camera = default_camera(&ds, 64, 48);
    let settings = Settings::default();
    r.frame(&camera, 64, 48, &settings)
        .expect("a frame before the loss");
    ctx.mark_lost("a test");
    for _ in 0..3 {
        let e = r
            .frame(&camera, 64, 48, &settings)
            .expect_err("a lost device draws nothing");
        assert!(e.to_string().contains("lost"), "{e}");
    }
    assert!(r.wait_gpu().is_err());
}

/// `uses_point_size` says what the point size does: the pictures of the pipelines that declare
/// it change with the size, the others' stay the same to the byte (the quality harness
/// measures those at one size, and the window greys the size out for them).
#[test]
fn the_point_size_changes_the_pictures_of_the_pipelines_that_say_it_does() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dataset();
    for p in registry() {
        let name = p["name"].as_str().expect("name");
        let uses = p["uses_point_size"].as_bool().expect("uses_point_size");
        let image = |size: &str| {
            let out = dir.path().join(format!("{name}_{size}.png"));
            let args = ["render", s(&ds), "-o", s(&out), "--size", "160x120"];
            common::gpu_ok(&[&args[..], &["--pipeline", name, "--point-size", size]].concat());
            common::read_png(&out).2
        };
        let changed = image("1") != image("4");
        assert_eq!(
            changed, uses,
            "{name}: the point size changes its picture: {changed}"
        );
    }
}
