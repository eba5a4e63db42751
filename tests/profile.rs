//! `strata profile` and the window's survey tools: a profile holds exactly the stored points
//! within its corridor (at full detail, all of them), with every attribute; coarser profiles
//! read less; the window draws measurements, the profile and clip boxes.

mod common;

use common::{las_points, s};
use std::path::Path;

const LINE: &str = "636316,849296;636787,849140;636900,849300";
const WIDTH: f64 = 6.0;
const VERTICES: [[f64; 2]; 3] = [
    [636316.0, 849296.0],
    [636787.0, 849140.0],
    [636900.0, 849300.0],
];

/// Within the corridor: across one segment (the foot on it) within half the width.
fn inside(x: f64, y: f64) -> bool {
    inside_of(&VERTICES, WIDTH, x, y)
}

fn inside_of(vertices: &[[f64; 2]], width: f64, x: f64, y: f64) -> bool {
    vertices.windows(2).any(|w| {
        let (a, b) = (w[0], w[1]);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len2 = dx * dx + dy * dy;
        let t = ((x - a[0]) * dx + (y - a[1]) * dy) / len2;
        let off = (dx * (y - a[1]) - dy * (x - a[0])).abs() / len2.sqrt();
        (0.0..=1.0).contains(&t) && off <= width / 2.0
    })
}

fn profile(dataset: &Path, out: &Path, extra: &[&str]) -> String {
    let w = WIDTH.to_string();
    let mut args = vec![
        "profile",
        s(dataset),
        "--line",
        LINE,
        "--width",
        &w,
        "-o",
        s(out),
    ];
    args.extend_from_slice(extra);
    let o = common::run_ok(&args);
    String::from_utf8_lossy(&o.stdout).to_string()
}

#[test]
fn a_full_profile_is_every_stored_point_in_its_corridor_with_every_attribute() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = common::converted("profile-fixture", "autzen_trim.laz", "autzen");
    let exported = dir.path().join("all.las");
    common::run_ok(&["export", s(&dataset), "-o", s(&exported)]);
    let (all, scale) = las_points(&exported);
    let mut want: Vec<_> = all
        .into_iter()
        .filter(|(q, _)| inside(q[0] as f64 * scale[0], q[1] as f64 * scale[1]))
        .collect();
    want.sort_unstable();
    assert!(
        want.len() > 300,
        "only {} points in the corridor",
        want.len()
    );

    // As LAS: exactly those points, every field as exported.
    let las = dir.path().join("p.las");
    profile(&dataset, &las, &[]);
    let (mut got, _) = las_points(&las);
    got.sort_unstable();
    assert_eq!(got.len(), want.len());
    assert!(
        got == want,
        "the profile's points differ from the exported ones in the corridor"
    );

    // As CSV: each row within the corridor, its distance along the line where its foot is.
    let csv = dir.path().join("p.csv");
    let said = profile(&dataset, &csv, &[]);
    assert!(said.contains(&format!("{} points", want.len())), "{said}");
    let text = std::fs::read_to_string(&csv).expect("csv");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    assert_eq!(&header[..5], &["distance", "offset", "x", "y", "z"]);
    assert!(
        header.contains(&"classification") && header.contains(&"gps_time"),
        "{header:?}"
    );
    let seg0 = (VERTICES[1][0] - VERTICES[0][0]).hypot(VERTICES[1][1] - VERTICES[0][1]);
    let total = seg0 + (VERTICES[2][0] - VERTICES[1][0]).hypot(VERTICES[2][1] - VERTICES[1][1]);
    let mut rows = 0;
    for line in lines {
        let v: Vec<f64> = line
            .split(',')
            .map(|c| c.parse().expect("number"))
            .collect();
        assert_eq!(v.len(), header.len());
        let (along, offset, x, y) = (v[0], v[1], v[2], v[3]);
        assert!(inside(x, y), "{x},{y} lies outside the corridor");
        assert!(offset.abs() <= WIDTH / 2.0 + 1e-3 && (0.0..=total + 1e-3).contains(&along));
        rows += 1;
    }
    assert_eq!(rows, want.len());

    // A coarser profile reads fewer levels and fewer points, all of them still in the corridor.
    let coarse = dir.path().join("coarse.csv");
    let said = profile(&dataset, &coarse, &["--spacing", "5"]);
    let n = std::fs::read_to_string(&coarse)
        .expect("csv")
        .lines()
        .count()
        - 1;
    assert!(n > 0 && n < want.len(), "{n} of {}: {said}", want.len());

    // The root's spacing as `info` gives it in decimals asks for the root level alone (node
    // spacings are single precision: compared as they were, it read one level more).
    let info = common::run_ok(&["info", s(&dataset), "--json"]);
    let info: serde_json::Value = serde_json::from_slice(&info.stdout).expect("info JSON");
    let root = info["spacing"].as_f64().expect("spacing").to_string();
    let said = profile(&dataset, &coarse, &["--spacing", &root, "--overwrite"]);
    assert!(said.contains("levels 0 to 0"), "--spacing {root}: {said}");

    // Bad input: one sentence, no output.
    for (args, says) in [
        (
            vec!["--line", "636316,849296", "--width", "5"],
            "at least two",
        ),
        (vec!["--line", LINE, "--width", "-1"], "width"),
    ] {
        let out = dir.path().join("bad.csv");
        let mut all_args = vec!["profile", s(&dataset), "-o", s(&out)];
        all_args.extend(args);
        let o = common::run(&all_args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains(says) && !err.contains("panicked"),
            "{err}"
        );
        assert!(!out.exists());
    }
}

#[test]
fn a_profile_through_a_deep_tree_reads_every_page_in_format_1_1_and_1_0() {
    // Through the 20-level cluster of the deep fixture, whose nodes lie on many hierarchy
    // pages (1.1: below proxies; 1.0: proxies on their own pages).
    let dir = tempfile::tempdir().expect("tempdir");
    let deep = common::deep_dataset("profile-deep");
    let old = dir.path().join("deep10.strata");
    strata_format::v1_0::rewrite_as_1_0(&deep, &old).expect("rewrites");
    let [cx, cy, _] = common::DEEP_CENTRE;
    let vertices = [[cx - 300.0, cy], [cx + 300.0, cy + 0.001]];
    let line = format!(
        "{},{};{},{}",
        vertices[0][0], vertices[0][1], vertices[1][0], vertices[1][1]
    );
    let width = 0.01;
    let exported = dir.path().join("all.las");
    common::run_ok(&["export", s(&deep), "-o", s(&exported)]);
    let (all, scale) = las_points(&exported);
    let mut want: Vec<_> = all
        .into_iter()
        .filter(|(q, _)| {
            inside_of(
                &vertices,
                width,
                q[0] as f64 * scale[0],
                q[1] as f64 * scale[1],
            )
        })
        .collect();
    want.sort_unstable();
    assert!(
        want.len() > 100_000,
        "only {} points in the corridor",
        want.len()
    );
    for ds in [&deep, &old] {
        let out = dir.path().join("p.las");
        let w = width.to_string();
        common::run_ok(&[
            "profile",
            s(ds),
            "--line",
            &line,
            "--width",
            &w,
            "-o",
            s(&out),
            "--overwrite",
        ]);
        let (mut got, _) = las_points(&out);
        got.sort_unstable();
        assert_eq!(got.len(), want.len(), "{}", ds.display());
        assert!(got == want, "{}: the profile's points differ", ds.display());
    }
}

#[test]
fn the_window_draws_the_measurements_and_the_profile_with_its_plot() {
    if !common::have_xvfb() {
        return;
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = common::converted("profile-fixture", "autzen_trim.laz", "autzen");
    let m = dir.path().join("m.geojson");
    std::fs::write(
        &m,
        r#"{"type":"FeatureCollection","features":[{"type":"Feature","properties":{"measure":"distance"},
        "geometry":{"type":"LineString","coordinates":[[636100,849000,420],[636300,849400,430]]}}]}"#,
    )
    .expect("write");
    let shot = dir.path().join("window.png");
    let backend = std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "vulkan".into());
    let w = WIDTH.to_string();
    let o = std::process::Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1400x900x24"])
        .arg(env!("CARGO_BIN_EXE_strata"))
        .args([
            "view",
            s(&dataset),
            "--size",
            "1300x800",
            "--screenshot",
            s(&shot),
        ])
        .args(["--screenshot-after", "30", "--measurements", s(&m)])
        .args(["--profile", LINE, "--profile-width", &w])
        .args(["--clip", "min=636300,849050,400;max=636700,849300,500"])
        .env("WGPU_BACKEND", backend)
        .output()
        .expect("xvfb-run runs");
    assert!(
        o.status.success(),
        "view failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let (_, _, rgba) = common::read_png(&shot);
    let count = |c: [u8; 3]| rgba.chunks_exact(4).filter(|p| p[..3] == c).count();
    // The distance in its colour, the profile's line in green, the clip box's handles, and the
    // profile's plot (its background) in a window of its own.
    assert!(count([255, 214, 10]) > 100, "no measurement drawn");
    assert!(count([120, 255, 120]) > 100, "no profile line drawn");
    assert!(count([16, 18, 22]) > 560 * 200 / 2, "no profile plot shown");
    assert!(count([255, 120, 60]) > 100, "no clip box handles drawn");
}

/// A `.copc.laz` name is refused before the dataset is read: a profile is plain LAS or LAZ.
#[test]
fn a_copc_name_is_refused_before_anything_is_read() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("cut.copc.laz");
    let w = WIDTH.to_string();
    let o = common::run(&[
        "profile",
        "/nonexistent/set.strata",
        "--line",
        LINE,
        "--width",
        &w,
        "-o",
        s(&out),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("not COPC"), "{err}");
    assert!(!out.exists());
}

/// A u64 attribute went into the CSV as the nearest double (2^53 + 1 as 9007199254740992):
/// it is written whole.
#[test]
fn a_64_bit_attribute_goes_into_the_csv_whole() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (las, ds) = (dir.path().join("serial.las"), dir.path().join("ds"));
    let big = (1u64 << 53) + 1;
    let points: Vec<([f64; 3], u64)> = (0..50).map(|i| ([f64::from(i), 0.0, 0.0], big)).collect();
    common::serial_las(&las, &points);
    common::run_ok(&["convert", s(&las), "-o", s(&ds), "-q"]);
    let csv = dir.path().join("p.csv");
    common::run_ok(&[
        "profile",
        s(&ds),
        "--line",
        "0,0;49,0",
        "--width",
        "1",
        "-o",
        s(&csv),
    ]);
    let text = std::fs::read_to_string(&csv).expect("csv");
    assert_eq!(text.lines().count(), 51, "{text}");
    assert!(
        text.lines()
            .skip(1)
            .all(|l| l.ends_with(",9007199254740993")),
        "{text}"
    );
}

/// A level's spacing as `info` prints it asks for that level alone. 1.024 (0.001 steps,
/// 2^17 to the cube) is a hair above itself in single precision, and the profile, which
/// compared the nodes' single-precision spacing, read one level more.
#[test]
fn a_levels_spacing_in_decimals_reads_that_level() {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = dir.path().join("grid.las");
    let points: Vec<([f64; 3], u64)> = (0..200 * 200)
        .map(|i| {
            (
                [(i % 200) as f64 * 0.5, (i / 200) as f64 * 0.5, 0.0],
                i as u64,
            )
        })
        .collect();
    common::serial_las(&las, &points);
    let dataset = dir.path().join("grid.strata");
    common::run_ok(&["convert", s(&las), "-o", s(&dataset), "--quiet"]);
    let info = common::run_ok(&["info", s(&dataset), "--json"]);
    let info: serde_json::Value = serde_json::from_slice(&info.stdout).expect("info JSON");
    assert_eq!(info["spacing"].as_f64(), Some(1.024));
    assert!(
        info["depth"].as_u64().unwrap_or(0) >= 1,
        "{}",
        info["depth"]
    );
    let csv = dir.path().join("p.csv");
    let o = common::run_ok(&[
        "profile",
        s(&dataset),
        "--line",
        "1,50;99,50",
        "--width",
        "4",
        "--spacing",
        "1.024",
        "-o",
        s(&csv),
    ]);
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(said.contains("levels 0 to 0"), "{said}");
}
