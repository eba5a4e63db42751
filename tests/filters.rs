//! Filters by class and by attribute range, applied in the projection: hidden points are absent
//! from the image in every pipeline, and what is drawn (and picked) passes the filters.

mod common;

use common::{data, gpu_ok, gpu_run, read_png, s};
use std::path::PathBuf;

const BACKGROUND: [u8; 3] = [24, 26, 32];
/// `class_colour(2)` of colour.wgsl, as the output stores it.
const GROUND: [u8; 3] = [161, 115, 69];

fn dataset() -> PathBuf {
    common::converted("filters-fixture", "autzen_trim.laz", "autzen")
}

fn classified(extra: &[&str]) -> Vec<[u8; 3]> {
    let ds = &dataset();
    let out = ds.with_file_name(format!("classes{}.png", extra.join("_").replace(',', "-")));
    let mut args = vec![
        "render",
        s(ds),
        "-o",
        s(&out),
        "--size",
        "320x240",
        "--pipeline",
        "points",
        "--colour",
        "classification",
        "--wait-complete",
    ];
    args.extend_from_slice(extra);
    gpu_ok(&args);
    let (_, _, rgba) = read_png(&out);
    rgba.chunks_exact(4)
        .map(|p| [p[0], p[1], p[2]])
        .filter(|p| *p != BACKGROUND)
        .collect()
}

#[test]
fn a_class_shown_alone_or_hidden_is_all_or_nothing_of_the_image() {
    let all = classified(&[]);
    let ground_in_all = all.iter().filter(|p| **p == GROUND).count();
    assert!(
        ground_in_all > 1000 && ground_in_all < all.len(),
        "{ground_in_all} of {}",
        all.len()
    );
    let only = classified(&["--classes", "2"]);
    assert!(only.len() > 1000);
    assert!(
        only.iter().all(|p| *p == GROUND),
        "--classes 2 drew other classes"
    );
    let hidden = classified(&["--hide-classes", "2"]);
    assert!(hidden.len() > 1000, "hiding ground hid everything");
    assert!(
        hidden.iter().all(|p| *p != GROUND),
        "--hide-classes 2 drew ground"
    );
}

fn pick(pipeline: &str, pixel: &str, filters: &[&str]) -> Option<serde_json::Value> {
    let ds = dataset();
    let mut args = vec![
        "pick",
        s(&ds),
        "--size",
        "320x240",
        "--pixel",
        pixel,
        "--pipeline",
        pipeline,
        "--json",
        "--radius",
        "12",
    ];
    args.extend_from_slice(filters);
    let o = gpu_run(&args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("panicked"), "{err}");
    (o.status.code() == Some(0)).then(|| serde_json::from_slice(&o.stdout).expect("JSON"))
}

fn attribute(p: &serde_json::Value, name: &str) -> f64 {
    p["attributes"]
        .as_array()
        .expect("attributes")
        .iter()
        .find(|a| a["name"] == name)
        .and_then(|a| a["values"][0].as_f64())
        .unwrap_or(f64::NAN)
}

#[test]
fn every_pipeline_draws_only_what_passes_the_filters() {
    let filters = [
        "--hide-classes",
        "2",
        "--filter",
        "elevation=430..470",
        "--filter",
        "intensity=0..400",
        "--filter",
        "return_number=1..1",
    ];
    for pipeline in ["points", "edl", "pyramid"] {
        let mut picked = 0;
        for pixel in ["160,120", "120,110", "200,130", "100,130", "220,100"] {
            let Some(p) = pick(pipeline, pixel, &filters) else {
                continue;
            };
            let z = p["position"][2].as_f64().expect("z");
            assert!((430.0..=470.0).contains(&z), "{pipeline} {pixel}: z {z}");
            assert_ne!(attribute(&p, "classification"), 2.0, "{pipeline} {pixel}");
            assert!(attribute(&p, "intensity") <= 400.0, "{pipeline} {pixel}");
            assert_eq!(attribute(&p, "return_number"), 1.0, "{pipeline} {pixel}");
            picked += 1;
        }
        assert!(picked >= 2, "{pipeline}: only {picked} pixels had a point");
    }
}

#[test]
fn a_wrong_filter_is_refused_in_one_sentence() {
    let ds = &dataset();
    for (args, names) in [
        (
            &["--filter", "gps=1..2"][..],
            &["\"gps\"", "elevation, intensity", "gps_time"][..],
        ),
        (&["--filter", "elevation=9..1"], &["elevation", "LOW..HIGH"]),
        (
            &["--filter", "return_number=0.5..2"],
            &["return_number", "whole"],
        ),
        (&["--classes", "2,x"], &["--classes", "\"x\""]),
        (&["--hide-classes", "300"], &["--hide-classes", "0 to 255"]),
    ] {
        let mut all = vec!["render", s(ds), "-o", "unused.png"];
        all.extend_from_slice(args);
        let o = gpu_run(&all);
        let t = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} was accepted");
        assert_eq!(t.trim().lines().count(), 1, "{args:?}: {t}");
        for n in names {
            assert!(t.contains(n), "{args:?}: {t:?} does not name {n}");
        }
    }
}

fn render_stats(extra: &[&str], tag: &str) -> serde_json::Value {
    let ds = &dataset();
    let out = ds.with_file_name(format!("{tag}.png"));
    let stats = ds.with_file_name(format!("{tag}.json"));
    let mut args = vec![
        "render",
        s(ds),
        "-o",
        s(&out),
        "--size",
        "320x240",
        "--wait-complete",
        "--stats",
        s(&stats),
        "--budget",
        "100k",
    ];
    args.extend_from_slice(extra);
    gpu_ok(&args);
    serde_json::from_slice(&std::fs::read(&stats).expect("stats")).expect("JSON")
}

#[test]
fn a_clip_box_keeps_only_its_inside_and_bounds_the_nodes_loaded() {
    // A box around the middle of autzen (636001..637179, 848935..849498).
    let (x0, x1, y0, y1) = (636400.0, 636800.0, 849100.0, 849350.0);
    let clip = format!("min={x0},{y0},0;max={x1},{y1},1000");
    let mut picked = 0;
    for pixel in ["160,120", "140,115", "180,125", "150,130", "170,110"] {
        let Some(p) = pick("pyramid", pixel, &["--clip", &clip]) else {
            continue;
        };
        let (x, y) = (
            p["position"][0].as_f64().expect("x"),
            p["position"][1].as_f64().expect("y"),
        );
        assert!(
            (x0 - 0.01..=x1 + 0.01).contains(&x) && (y0 - 0.01..=y1 + 0.01).contains(&y),
            "{pixel}: {x},{y} is outside the clip box"
        );
        picked += 1;
    }
    assert!(picked >= 2, "only {picked} pixels had a point");
    // Hiding the same box: no pick lands inside it.
    let outside = format!("{clip};outside");
    for pixel in ["160,120", "140,115", "180,125"] {
        if let Some(p) = pick("points", pixel, &["--clip", &outside]) {
            let (x, y) = (
                p["position"][0].as_f64().expect("x"),
                p["position"][1].as_f64().expect("y"),
            );
            assert!(
                !((x0 + 0.01..=x1 - 0.01).contains(&x) && (y0 + 0.01..=y1 - 0.01).contains(&y)),
                "{pixel}: {x},{y} lies inside the hidden box"
            );
        }
    }
    // Nodes that hold nothing the box keeps are not loaded, under the same budget.
    let full = render_stats(&[], "noclip");
    let clipped = render_stats(&["--clip", &clip], "clip");
    let nodes = |v: &serde_json::Value| v["frames"][0]["nodes_resident"].as_u64().unwrap_or(0);
    let bytes = |v: &serde_json::Value| v["frames"][0]["bytes_loaded_total"].as_u64().unwrap_or(0);
    assert!(nodes(&clipped) >= 1);
    assert!(
        nodes(&clipped) < nodes(&full),
        "{} of {} nodes",
        nodes(&clipped),
        nodes(&full)
    );
    assert!(bytes(&clipped) < bytes(&full));
    // A wrong box is refused in one sentence.
    let o = gpu_run(&[
        "render",
        s(&dataset()),
        "-o",
        "x.png",
        "--clip",
        "min=1,2,3;max=0,0,0",
    ]);
    let t = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && t.contains("--clip") && t.trim().lines().count() == 1,
        "{t}"
    );
}

#[test]
fn the_conversion_records_the_points_of_every_class() {
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dataset().join("metadata.json")).expect("metadata"))
            .expect("JSON");
    let mut want = std::collections::BTreeMap::<String, u64>::new();
    for (_, a) in common::las_points(&data("autzen_trim.laz")).0 {
        *want.entry(a[3].to_string()).or_default() += 1;
    }
    let got: std::collections::BTreeMap<String, u64> = meta["classes"]
        .as_object()
        .expect("classes in the metadata")
        .iter()
        .map(|(k, v)| (k.clone(), v.as_u64().expect("a count")))
        .collect();
    assert_eq!(got, want);
    let info = common::run_ok(&["info", s(&dataset())]);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(text.contains("ground"), "{text}");
}

fn drawn(extra: &[&str], tag: &str) -> u64 {
    render_stats(extra, tag)["frames"][0]["points_drawn"]
        .as_u64()
        .expect("points_drawn")
}

#[test]
fn points_drawn_counts_what_the_filters_let_through_gps_time_included() {
    let all = drawn(&[], "count-all");
    let ground = drawn(&["--classes", "2"], "count-ground");
    let rest = drawn(&["--hide-classes", "2"], "count-rest");
    assert!(ground > 0 && rest > 0, "{ground} + {rest}");
    assert_eq!(ground + rest, all, "ground and the rest are not all drawn");
    assert_eq!(
        drawn(
            &["--hide-classes", "2", "--projection", "int32"],
            "count-rest32"
        ),
        rest
    );

    // GPS time, which the GPU does not hold: two ranges that split the stored times between
    // two of them draw all points between them, and picks inside a range are in it.
    let dir = tempfile::tempdir().expect("tempdir");
    let exported = dir.path().join("all.las");
    common::run_ok(&["export", s(&dataset()), "-o", s(&exported)]);
    let mut times: Vec<f64> = common::las_points(&exported)
        .0
        .iter()
        .map(|(_, a)| f64::from_bits(a[12] as u64))
        .collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    let mid = times.len() / 2;
    let (first, last) = (times[0], times[times.len() - 1]);
    let early = format!("gps_time={first}..{}", times[mid]);
    let late = format!("gps_time={}..{last}", times[mid + 1]);
    let (a, b) = (
        drawn(&["--filter", &early], "count-early"),
        drawn(&["--filter", &late], "count-late"),
    );
    assert!(a > 0 && b > 0, "{a} + {b}");
    assert_eq!(
        a + b,
        all,
        "the two halves of the GPS times do not make all"
    );
    for pipeline in ["points", "pyramid"] {
        let mut picked = 0;
        for pixel in ["160,120", "120,110", "200,130", "100,130"] {
            if let Some(p) = pick(pipeline, pixel, &["--filter", &late]) {
                let t = attribute(&p, "gps_time");
                assert!(t >= times[mid + 1] && t <= last, "{pipeline} {pixel}: {t}");
                picked += 1;
            }
        }
        assert!(picked >= 2, "{pipeline}: only {picked} picks");
    }
}

#[test]
fn changing_an_attribute_range_mid_session_draws_and_counts_the_new_one() {
    use std::sync::Arc;
    use std::time::Duration;
    use strata_viewer::gpu::{GpuContext, ProjectionPath};
    use strata_viewer::headless::default_camera;
    use strata_viewer::{Renderer, Settings, StreamDataset};
    let ds = Arc::new(StreamDataset::open_path(&dataset()).expect("dataset opens"));
    let ctx = Arc::new(GpuContext::new(ProjectionPath::Auto).expect("GPU adapter"));
    let mut r = Renderer::new(ctx, ds.clone(), 1 << 28, 2).expect("renderer");
    let camera = default_camera(&ds, 320, 240);
    let settings = |range: &str| {
        let mut s = Settings {
            budget: 100_000,
            ..Settings::default()
        };
        s.filter.set_range(range).expect("a range");
        s
    };
    // The points drawn once every node is resident again and the count has come back.
    let settle = |r: &mut Renderer, s: &Settings| -> u64 {
        let mut last = None;
        for _ in 0..400 {
            let stats = r.frame(&camera, 320, 240, s).expect("frame");
            r.wait_gpu().expect("GPU");
            let counted = r.counted_points_drawn();
            if let Some(n) = counted
                && stats.complete
                && counted == last
            {
                return n;
            }
            last = counted;
            r.wait_for_loads(Duration::from_millis(10));
        }
        panic!("the frame did not settle");
    };
    let early = "gps_time=0..245383";
    let late = "gps_time=245383.000001..1e12";
    // One frame with the first range sends its nodes loading; switched while they are in
    // flight, they must not be drawn: the second range's nodes load and are counted.
    r.frame(&camera, 320, 240, &settings(early)).expect("frame");
    let b = settle(&mut r, &settings(late));
    // Switched with every node resident: they load again.
    let a = settle(&mut r, &settings(early));
    let back = settle(&mut r, &settings(late));
    assert_eq!(back, b, "the second range again counts differently");
    assert!(a > 0 && b > 0, "{a} and {b}");
    assert_eq!(a, drawn(&["--filter", early], "count-mid-early"));
    assert_eq!(b, drawn(&["--filter", late], "count-mid-late"));
}
