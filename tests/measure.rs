//! `strata measure` and `strata render --measurements`: measurements are made between the exact
//! stored points under pixels, kept as GeoJSON, and drawn over the image.

mod common;

use common::{gpu_run, las_points, read_png, s};
use std::path::Path;

fn json_of(o: &std::process::Output, what: &str) -> serde_json::Value {
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{what}: {stderr}");
    serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{what}: {e}"))
}

fn position(v: &serde_json::Value) -> [f64; 3] {
    std::array::from_fn(|i| v[i].as_f64().expect("coordinate"))
}

const A: &str = "100,120";
const B: &str = "230,140";

/// `strata measure DATASET --size 320x240 --kind KIND --pixel P... -o OUT`.
fn measure_into(dataset: &Path, kind: &str, pixels: &[&str], out: &Path) -> std::process::Output {
    let mut args = vec!["measure", s(dataset), "--size", "320x240", "--kind", kind];
    for p in pixels {
        args.extend(["--pixel", p]);
    }
    args.extend(["-o", s(out)]);
    gpu_run(&args)
}

#[test]
fn a_distance_between_picked_points_is_their_distance_in_the_exported_points() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = common::converted("measure-fixture", "autzen_trim.laz", "autzen");
    let exported = dir.path().join("all.las");
    common::run_ok(&["export", s(&dataset), "-o", s(&exported)]);
    let (points, scale) = las_points(&exported);
    // The exported point at each picked place, in real-world coordinates from the LAS.
    let stored = |pixel: &str| -> [f64; 3] {
        let o = gpu_run(&[
            "pick",
            s(&dataset),
            "--size",
            "320x240",
            "--pixel",
            pixel,
            "--json",
        ]);
        let p = position(&json_of(&o, pixel)["position"]);
        let q: [i64; 3] = std::array::from_fn(|i| (p[i] / scale[i]).round() as i64);
        let found = points.iter().find(|(xyz, _)| *xyz == q);
        let (xyz, _) = found.unwrap_or_else(|| panic!("{pixel}: no exported point at {q:?}"));
        std::array::from_fn(|i| xyz[i] as f64 * scale[i])
    };
    let (a, b) = (stored(A), stored(B));
    let want = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    assert!(
        want > 10.0,
        "the two pixels hit nearly the same point: {want}"
    );

    let file = dir.path().join("m.geojson");
    let measure = |kind: &str, pixels: &[&str]| {
        let mut args = vec!["measure", s(&dataset), "--size", "320x240", "--kind", kind];
        for p in pixels {
            args.extend(["--pixel", p]);
        }
        args.extend(["-o", s(&file), "--json"]);
        json_of(&gpu_run(&args), kind)
    };
    let d = measure("distance", &[A, B]);
    let got = d["properties"]["total_length"]
        .as_f64()
        .expect("total_length");
    assert!(
        (got - want).abs() < 1e-6,
        "measured {got}, exported points {want}"
    );
    let dz = d["properties"]["height_difference"].as_f64().expect("dz");
    assert!((dz - (b[2] - a[2])).abs() < 1e-6);
    // The GeoJSON holds the stored points themselves.
    let coords = &d["geometry"]["coordinates"];
    for (i, p) in [a, b].iter().enumerate() {
        let c = position(&coords[i]);
        assert!((0..3).all(|k| (c[k] - p[k]).abs() < 1e-6), "{c:?} vs {p:?}");
    }
    let h = measure("height", &[A, B]);
    assert_eq!(
        h["properties"]["height"],
        d["properties"]["height_difference"]
    );

    // Both went to the file, which the renderer draws: the first vertex is in a measurement's
    // colour (the distance's yellow, or the height's magenta drawn after it) where, without the
    // file, the scene is.
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&file).expect("saved")).expect("GeoJSON");
    assert_eq!(saved["type"], "FeatureCollection");
    assert_eq!(saved["features"].as_array().map(Vec::len), Some(2));
    let render = |out: &Path, extra: &[&str]| {
        let mut args = vec![
            "render",
            s(&dataset),
            "-o",
            s(out),
            "--size",
            "320x240",
            "--wait-complete",
        ];
        args.extend_from_slice(extra);
        let o = gpu_run(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        read_png(out).2
    };
    let plain = render(&dir.path().join("plain.png"), &[]);
    let drawn = render(&dir.path().join("drawn.png"), &["--measurements", s(&file)]);
    let picked_pixel = json_of(
        &gpu_run(&[
            "pick",
            s(&dataset),
            "--size",
            "320x240",
            "--pixel",
            A,
            "--json",
        ]),
        A,
    )["pixel"]
        .clone();
    let (x, y) = (
        picked_pixel[0].as_u64().expect("x") as usize,
        picked_pixel[1].as_u64().expect("y") as usize,
    );
    let at = (y * 320 + x) * 4;
    let marks = [[255, 214, 10], [255, 80, 220]];
    assert!(
        marks.iter().any(|m| drawn[at..at + 3] == m[..]),
        "no measurement vertex at {x},{y}: {:?}",
        &drawn[at..at + 3]
    );
    assert!(!marks.iter().any(|m| plain[at..at + 3] == m[..]));
    let changed = plain
        .chunks(4)
        .zip(drawn.chunks(4))
        .filter(|(p, d)| p != d)
        .count();
    assert!(
        changed > 200 && changed < 320 * 240 / 4,
        "{changed} pixels changed"
    );

    // Bad input is refused with the file and the fault named, and no image written.
    let bad = dir.path().join("bad.geojson");
    std::fs::write(&bad, r#"{"type":"FeatureCollection","features":[{"type":"Feature","geometry":{"type":"Point","coordinates":[1,2]}}]}"#).expect("write");
    let out = dir.path().join("bad.png");
    let o = gpu_run(&[
        "render",
        s(&dataset),
        "-o",
        s(&out),
        "--measurements",
        s(&bad),
    ]);
    let text = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && text.contains("bad.geojson") && text.contains("feature 0"),
        "{text}"
    );
    assert!(!out.exists());
    let o = gpu_run(&[
        "measure",
        s(&dataset),
        "--kind",
        "angle",
        "--pixel",
        A,
        "--pixel",
        B,
    ]);
    let text = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && text.contains("angle needs 3"),
        "{text}"
    );
    // Three picks of one point measure no angle: refused, and nothing saved.
    let saved = dir.path().join("angle.geojson");
    let o = measure_into(&dataset, "angle", &[A, A, A], &saved);
    let text = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && text.contains("measure no angle"),
        "{text}"
    );
    assert!(!saved.exists());
}

/// A measurement added to a GIS's GeoJSON keeps what the file held: its name and CRS, a
/// feature's id and properties (a rewrite from what measure understands dropped them; the
/// window saves the same way).
#[test]
fn a_measurement_added_to_a_file_keeps_what_the_file_held() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = common::converted("measure-fixture", "autzen_trim.laz", "autzen");
    let file = dir.path().join("gis.geojson");
    let before = serde_json::json!({
        "type": "FeatureCollection",
        "name": "survey",
        "crs": {"type": "name", "properties": {"name": "EPSG:2992"}},
        "features": [{
            "type": "Feature",
            "id": 7,
            "properties": {"owner": "bob", "note": "keep", "measure": "distance"},
            "geometry": {"type": "LineString", "coordinates": [[0.0, 0.0, 0.0], [3.0, 4.0, 0.0]]}
        }]
    });
    std::fs::write(&file, before.to_string()).expect("write");
    let o = measure_into(&dataset, "distance", &[A, B], &file);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let after: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&file).expect("read")).expect("GeoJSON");
    assert_eq!(after["name"], before["name"]);
    assert_eq!(after["crs"], before["crs"]);
    // The feature keeps its id, geometry and properties; the measure adds its results.
    let (was, is) = (&before["features"][0], &after["features"][0]);
    assert_eq!(is["id"], was["id"]);
    assert_eq!(is["geometry"], was["geometry"]);
    for key in ["owner", "note", "measure"] {
        assert_eq!(is["properties"][key], was["properties"][key], "{key}");
    }
    assert_eq!(is["properties"]["total_length"], serde_json::json!(5.0));
    assert_eq!(after["features"].as_array().map(Vec::len), Some(2));
    assert_eq!(after["features"][1]["properties"]["measure"], "distance");
}
