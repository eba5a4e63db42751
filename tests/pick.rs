//! `strata pick`: the point under a pixel is the exact stored point of the surface the image shows.

mod common;

use common::{gpu_run, las_points, s};
use std::path::Path;

fn picked(dataset: &Path, pixel: &str, pipeline: &str) -> Option<serde_json::Value> {
    let o = gpu_run(&[
        "pick",
        s(dataset),
        "--size",
        "320x240",
        "--pixel",
        pixel,
        "--pipeline",
        pipeline,
        "--json",
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    match o.status.code() {
        Some(0) => Some(serde_json::from_slice(&o.stdout).expect("pick JSON")),
        Some(3) => None,
        other => panic!("strata pick {pixel}: exit {other:?}: {stderr}"),
    }
}

#[test]
fn a_picked_point_is_a_stored_point_with_every_attribute() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = common::converted("pick-fixture", "autzen_trim.laz", "autzen");
    let exported = dir.path().join("all.las");
    common::run_ok(&["export", s(&dataset), "-o", s(&exported)]);
    let (points, scale) = las_points(&exported);
    let mut checked = 0;
    for pixel in ["160,120", "80,120", "240,120", "160,100", "200,140"] {
        let Some(p) = picked(&dataset, pixel, "points") else {
            continue;
        };
        let pos: Vec<f64> = (0..3)
            .map(|i| p["position"][i].as_f64().expect("coordinate"))
            .collect();
        let q: [i64; 3] = std::array::from_fn(|i| (pos[i] / scale[i]).round() as i64);
        // Full precision: the printed coordinates are the stored integers times the scale.
        for i in 0..3 {
            assert!(
                (pos[i] - q[i] as f64 * scale[i]).abs() < scale[i] * 1e-3,
                "{pixel}: {pos:?}"
            );
        }
        let attr = |name: &str| {
            p["attributes"]
                .as_array()
                .expect("attributes")
                .iter()
                .find(|a| a["name"] == name)
                .and_then(|a| a["values"][0].as_f64())
                .unwrap_or_else(|| panic!("{pixel}: no {name}"))
        };
        // The point lies where it was drawn: at the pixel and depth the projection found.
        let ds = strata_viewer::StreamDataset::open_path(&dataset).expect("dataset opens");
        let camera = strata_viewer::headless::default_camera(&ds, 320, 240);
        let rel = (glam::DVec3::new(pos[0], pos[1], pos[2]) - ds.anchor()).as_vec3();
        let (near, far) = strata_viewer::lod::clip_range(&ds, &camera, 320.0 / 240.0);
        let clip = camera.projection(320.0 / 240.0, near, far) * camera.view() * rel.extend(1.0);
        let (fx, fy) = (
            (clip.x / clip.w * 0.5 + 0.5) * 320.0,
            (0.5 - clip.y / clip.w * 0.5) * 240.0,
        );
        let drawn = [
            p["pixel"][0].as_f64().expect("x"),
            p["pixel"][1].as_f64().expect("y"),
        ];
        assert!(
            (fx.floor() as f64 - drawn[0]).abs() <= 1.0
                && (fy.floor() as f64 - drawn[1]).abs() <= 1.0,
            "{pixel}: the point projects to {fx},{fy}, drawn at {drawn:?}"
        );
        let depth = p["depth"].as_f64().expect("depth") as f32;
        assert!(
            (clip.w - depth).abs() <= depth * 1e-4,
            "{pixel}: depth {} vs {depth}",
            clip.w
        );
        let same_place: Vec<_> = points.iter().filter(|(xyz, _)| *xyz == q).collect();
        assert!(
            !same_place.is_empty(),
            "{pixel}: no exported point at {q:?}"
        );
        // intensity, classification and GPS time of one of the points stored there.
        let gps = attr("gps_time");
        assert!(
            same_place.iter().any(|(_, a)| {
                a[0] == attr("intensity") as i64
                    && a[3] == attr("classification") as i64
                    && f64::from_bits(a[12] as u64) == gps
            }),
            "{pixel}: the picked attributes match no stored point at {q:?}"
        );
        // The same point where the pipeline draws the projection's points; a stored point
        // where it reconstructs a surface over them (one of that surface: it may hide the
        // point `points` shows, as a disc of the surfels in front of it does).
        let other = picked(&dataset, pixel, "edl").expect("the same pixel is drawn");
        assert_eq!(other["position"], p["position"], "{pixel} with edl");
        assert_eq!(other["index"], p["index"], "{pixel} with edl");
        for pipeline in ["pyramid", "surfels"] {
            let other = picked(&dataset, pixel, pipeline).expect("a point near the pixel");
            let q: [i64; 3] = std::array::from_fn(|i| {
                (other["position"][i].as_f64().expect("coordinate") / scale[i]).round() as i64
            });
            assert!(
                points.iter().any(|(xyz, _)| *xyz == q),
                "{pixel} with {pipeline}: no stored point at {q:?}"
            );
            // Of the front surface, beside the point `points` shows: a reconstruction lies at
            // or in front of the nearest projected points, never a surface behind them.
            let depth = |v: &serde_json::Value| v["depth"].as_f64().expect("depth");
            let near = |v: &serde_json::Value, i: usize| v["pixel"][i].as_i64().expect("pixel");
            assert!(
                depth(&other) <= depth(&p) * 1.01,
                "{pixel} with {pipeline}: depth {} behind the points' {}",
                depth(&other),
                depth(&p)
            );
            assert!(
                (0..2).all(|i| (near(&other, i) - near(&p, i)).abs() <= 3),
                "{pixel} with {pipeline}: picked at {} where points picked at {}",
                other["pixel"],
                p["pixel"]
            );
        }
        checked += 1;
    }
    assert!(checked >= 3, "only {checked} pixels had a point");
    // Background: nothing to pick, said so with exit 3 and no output.
    assert!(picked(&dataset, "0,0", "points").is_none());
    let o = gpu_run(&["pick", s(&dataset), "--size", "64x64", "--pixel", "70,10"]);
    assert!(!o.status.success());
    let text = String::from_utf8_lossy(&o.stderr);
    assert!(
        text.contains("70,10") && !text.contains("panicked"),
        "{text}"
    );
}

/// A u64 attribute was printed as the nearest double (2^53 + 1 as 9007199254740992): it is
/// printed whole, and the JSON carries it exactly in `integers`.
#[test]
fn a_64_bit_attribute_is_picked_whole() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (las, ds) = (dir.path().join("serial.las"), dir.path().join("ds"));
    let big = (1u64 << 53) + 1;
    let mut points = Vec::new();
    for i in 0..100 {
        for k in 0..100 {
            points.push(([f64::from(i) * 0.01, 0.0, f64::from(k) * 0.01], big));
        }
    }
    common::serial_las(&las, &points);
    common::run_ok(&["convert", s(&las), "-o", s(&ds), "-q"]);
    let p = picked(&ds, "160,120", "points").expect("a point under the centre");
    let serial = p["attributes"]
        .as_array()
        .expect("attributes")
        .iter()
        .find(|a| a["name"] == "serial")
        .expect("serial")
        .clone();
    assert_eq!(serial["integers"][0].as_u64(), Some(big), "{serial}");
    let o = gpu_run(&["pick", s(&ds), "--size", "320x240", "--pixel", "160,120"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("serial 9007199254740993"), "{text}");
}

/// A view that draws nothing because the budget is below the root node's points is not
/// "only background" (exit 3): it is an error naming the budget, for pick and measure alike,
/// and a render writes no empty image that would look like a view of nothing.
#[test]
fn a_budget_below_the_root_node_is_said_not_answered_as_background() {
    // 300 k points at random in a cube: the root keeps most of them (about 250 k).
    let dir = tempfile::tempdir().expect("tempdir");
    let ply = dir.path().join("cube.ply");
    let mut unit = common::unit_randoms(5);
    let points: Vec<([f64; 3], [u8; 3])> = (0..300_000)
        .map(|_| {
            (
                [unit() * 10.0, unit() * 10.0, unit() * 10.0],
                [200, 200, 200],
            )
        })
        .collect();
    common::write_coloured_ply(&ply, &points, None);
    let dataset = dir.path().join("cube.strata");
    common::run_ok(&["convert", s(&ply), "-o", s(&dataset), "--quiet"]);
    let image = dir.path().join("empty.png");
    for command in ["pick", "measure", "render"] {
        let mut args = vec![
            command,
            s(&dataset),
            "--size",
            "160x120",
            "--budget",
            "100k",
        ];
        match command {
            "pick" => args.extend(["--pixel", "80,60"]),
            "measure" => args.extend(["--pixel", "80,60", "--pixel", "90,60"]),
            _ => args.extend(["-o", s(&image)]),
        }
        let o = gpu_run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{command}: {err}");
        assert!(
            err.contains("root node alone holds") && err.contains("--budget 100000"),
            "{command}: {err}"
        );
    }
    assert!(!image.exists(), "an empty image was written");
}

/// A wall sampled more sparsely than the pixels it covers, in front of a floor: the
/// projection sees the floor through the wall's gaps, but a pipeline that closes the wall
/// shows the wall there, and the point picked is the wall's (it was the floor's, 5 m behind).
#[test]
fn a_reconstructed_wall_is_picked_not_the_floor_seen_through_its_gaps() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ply = dir.path().join("wall.ply");
    let step = 0.05;
    let mut points: Vec<([f64; 3], [u8; 3])> = Vec::new();
    for i in 0..200 {
        for j in 0..200 {
            points.push(([i as f64 * step, j as f64 * step, 0.0], [60, 160, 60]));
        }
        for k in 0..60 {
            points.push(([5.0, i as f64 * step, k as f64 * step], [200, 100, 100]));
        }
    }
    common::write_coloured_ply(&ply, &points, None);
    let dataset = dir.path().join("wall.strata");
    common::run_ok(&["convert", s(&ply), "-o", s(&dataset), "--quiet"]);
    for pipeline in ["triangulate", "filters", "pyramid", "surfels"] {
        // Pixels about the centre, which the wall covers (the view's axis meets it at z 1.67).
        for pixel in ["160,120", "164,126", "152,114", "168,118", "156,124"] {
            let o = gpu_run(&[
                "pick",
                s(&dataset),
                "--size",
                "320x240",
                "--camera",
                "eye=-2,5,4;target=10,5,0;fov=50",
                "--pixel",
                pixel,
                "--pipeline",
                pipeline,
                "--json",
            ]);
            let err = String::from_utf8_lossy(&o.stderr);
            assert!(o.status.success(), "{pipeline} {pixel}: {err}");
            let p: serde_json::Value = serde_json::from_slice(&o.stdout).expect("pick JSON");
            let x = p["position"][0].as_f64().expect("x");
            assert!((x - 5.0).abs() < 1e-3, "{pipeline} {pixel}: picked {p}");
        }
    }
}
