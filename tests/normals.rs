//! `strata convert --normals` as a user runs it: normals facing the scanner that took each
//! point (E57 poses), the flags refused with one sentence, and what the metadata records.

mod common;

use common::{refused, run, run_ok, s};
use e57::{E57Writer, Quaternion, Record, RecordValue, Transform, Translation};
use std::path::Path;
use strata_format::{LocalDataset, oct16_decode};

/// Two scanners, 3 m above and 3 m below the plane z = 0, each scanning its own interleaved
/// half of a 10 m square of it. Without `below_posed` the scan from below is written as a tool
/// that merged it writes it: Cartesian, in world coordinates, without a pose.
fn write_two_sided_plane(path: &Path, below_posed: bool) {
    let mut w = E57Writer::from_file(path, "strata-normals-test").expect("e57 writer");
    for (i, height) in [3.0f64, -3.0].into_iter().enumerate() {
        let mut pc = w
            .add_pointcloud(
                &format!("side-{i}"),
                vec![
                    Record::CARTESIAN_X_F64,
                    Record::CARTESIAN_Y_F64,
                    Record::CARTESIAN_Z_F64,
                ],
            )
            .expect("scan writer");
        let posed = i == 0 || below_posed;
        if posed {
            pc.set_transform(Some(Transform {
                rotation: Quaternion {
                    w: 1.0,
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                },
                translation: Translation {
                    x: 0.0,
                    y: 0.0,
                    z: height,
                },
            }));
        }
        for gx in 0..100 {
            for gy in 0..50 {
                // Scan 0 takes the even rows, scan 1 the odd ones, both on z = 0 in the world.
                let (x, y) = (gx as f64 * 0.1 - 5.0, (2 * gy + i) as f64 * 0.1 - 5.0);
                let z = if posed { -height } else { 0.0 };
                let local = [x + 0.013 * ((gx * 7 + gy) % 5) as f64, y, z];
                pc.add_point(local.map(RecordValue::Double).to_vec())
                    .expect("point");
            }
        }
        pc.finalize().expect("scan written");
    }
    w.finalize().expect("file written");
}

#[test]
fn normals_face_the_scanner_that_took_each_point() {
    let dir = tempfile::tempdir().expect("tempdir");
    let e57 = dir.path().join("plane.e57");
    write_two_sided_plane(&e57, true);
    let out = dir.path().join("ds");
    run_ok(&["convert", s(&e57), "-o", s(&out), "--normals", "-q"]);
    let meta = LocalDataset::open(&out).expect("open").metadata().clone();
    let info = meta.normals.clone().expect("normals recorded");
    assert_eq!(info.orient, "scanner");
    assert_eq!(info.computed, 10_000);
    let mut seen = [0; 2];
    for (scan, n) in normals_by_scanner(&out) {
        let want = if scan == 0 { 1.0 } else { -1.0 };
        assert!(n[2] * want > 0.999, "scan {scan}: normal {n:?}");
        seen[scan as usize] += 1;
    }
    assert_eq!(seen, [5_000, 5_000]);

    // Forced up, the scanner below no longer counts.
    let up = dir.path().join("up");
    run_ok(&[
        "convert",
        s(&e57),
        "-o",
        s(&up),
        "--normals",
        "--orient",
        "up",
        "-q",
    ]);
    let meta = LocalDataset::open(&up).expect("open").metadata().clone();
    assert_eq!(meta.normals.expect("normals").orient, "up");
}

/// Every point's `scanner` and normal.
fn normals_by_scanner(out: &Path) -> Vec<(u16, [f64; 3])> {
    let ds = LocalDataset::open(out).expect("open");
    let layout = ds.layout().clone();
    let (n_at, s_at) = (
        layout.index_of("normal").expect("normal"),
        layout.index_of("scanner").expect("scanner"),
    );
    let mut all = Vec::new();
    for node in ds.all_nodes().expect("nodes") {
        let cols = ds.read_node(&node).expect("node");
        let (nc, sc) = (cols.attribute(&layout, n_at), cols.attribute(&layout, s_at));
        for i in 0..node.point_count as usize {
            let n = oct16_decode([
                u16::from_le_bytes([nc[4 * i], nc[4 * i + 1]]),
                u16::from_le_bytes([nc[4 * i + 2], nc[4 * i + 3]]),
            ])
            .expect("a normal");
            all.push((u16::from_le_bytes([sc[2 * i], sc[2 * i + 1]]), n));
        }
    }
    all
}

#[test]
fn a_cartesian_scan_without_a_pose_names_no_scanner_and_its_normals_face_up() {
    // Its origin is the file's, not where a scanner stood: turned towards it, normals of a
    // surface through it would face either way.
    let dir = tempfile::tempdir().expect("tempdir");
    let e57 = dir.path().join("merged.e57");
    write_two_sided_plane(&e57, false);
    let out = dir.path().join("ds");
    run_ok(&["convert", s(&e57), "-o", s(&out), "--normals", "-q"]);
    let meta = LocalDataset::open(&out).expect("open").metadata().clone();
    let stood: Vec<[f64; 3]> = meta.scanners.iter().map(|s| s.position).collect();
    assert_eq!(stood, [[0.0, 0.0, 3.0]]);
    let mut seen = [0; 2];
    for (scan, n) in normals_by_scanner(&out) {
        assert!(n[2] > 0.999, "scanner {scan}: normal {n:?}");
        seen[usize::from(scan == u16::MAX)] += 1;
    }
    assert_eq!(seen, [5_000, 5_000]);
}

#[test]
fn normal_flags_are_checked_before_any_work() {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = common::data("autzen_trim.las");
    let cases: [(&[&str], &str); 5] = [
        (&["--normals", "--orient", "scanner"], "--viewpoint"),
        (&["--normals", "--normal-k", "1"], "--normal-k 1"),
        (&["--normals", "--viewpoint", "1,2"], "X,Y,Z"),
        // A negative coordinate first is the viewpoint's, not a flag.
        (&["--normals", "--viewpoint", "-5,2"], "X,Y,Z"),
        (&["--normal-k", "8"], "--normals"),
    ];
    // A negative coordinate first is taken.
    let ok = dir.path().join("viewpoint");
    run_ok(&[
        "convert",
        s(&las),
        "-o",
        s(&ok),
        "-q",
        "--normals",
        "--viewpoint",
        "-5,2,3",
    ]);
    for (i, (flags, says)) in cases.iter().enumerate() {
        let out = dir.path().join(format!("ds{i}"));
        let mut args = vec!["convert", s(&las), "-o", s(&out), "-q"];
        args.extend_from_slice(flags);
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{flags:?} was accepted");
        assert!(err.contains(says), "{flags:?}: {err}");
        assert!(!out.exists(), "{flags:?} left {}", out.display());
    }
}

#[test]
fn an_airborne_scan_gets_normals_facing_up() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("autzen");
    let las = common::data("autzen_trim.las");
    run_ok(&["convert", s(&las), "-o", s(&out), "--normals", "-q"]);
    let ds = LocalDataset::open(&out).expect("open");
    let info = ds.metadata().normals.clone().expect("normals recorded");
    assert_eq!((info.orient.as_str(), info.computed), ("up", 110_000));
    assert!(info.surfel_radius > 0.0 && info.mean_radius > 0.0);
    let layout = ds.layout().clone();
    let at = layout.index_of("normal").expect("normal");
    let (mut up, mut total, mut none) = (0, 0, 0);
    for node in ds.all_nodes().expect("nodes") {
        if node.point_count == 0 {
            continue;
        }
        let cols = ds.read_node(&node).expect("node");
        let c = cols.attribute(&layout, at);
        for i in 0..node.point_count as usize {
            let Some(n) = oct16_decode([
                u16::from_le_bytes([c[4 * i], c[4 * i + 1]]),
                u16::from_le_bytes([c[4 * i + 2], c[4 * i + 3]]),
            ]) else {
                none += 1;
                continue;
            };
            total += 1;
            up += (n[2] >= 0.0) as usize;
        }
    }
    assert_eq!(up, total, "every normal faces up");
    // Isolated returns (birds, wires) fit no plane: few, and counted.
    assert_eq!(none, info.no_normal);
    assert!(none < 200, "{none} points without a normal");
}

/// An ASCII PLY of `points`.
fn write_ply(path: &Path, points: &[[f64; 3]]) {
    let mut text = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nend_header\n",
        points.len()
    );
    for p in points {
        text.push_str(&format!("{} {} {}\n", p[0], p[1], p[2]));
    }
    std::fs::write(path, text).expect("ply written");
}

#[test]
fn a_surface_too_sparse_for_the_search_is_said() {
    // A dense 10 m square (92 % of the points) beside a square 100 m wide sampled 30 times
    // more sparsely: its points find none within the search radius the dense part sets, so
    // they fit no plane; and with a third of that sampling, a few, and their discs are cut to
    // the search radius.
    let dir = tempfile::tempdir().expect("tempdir");
    let mut rng = common::unit_randoms(17);
    let mut points: Vec<[f64; 3]> = (0..46_000)
        .map(|_| [rng() * 10.0, rng() * 10.0, 0.0])
        .collect();
    let dense_only = dir.path().join("dense.ply");
    write_ply(&dense_only, &points);
    let mut sparser = points.clone();
    points.extend((0..4_000).map(|_| [20.0 + rng() * 100.0, rng() * 100.0, 0.0]));
    let both = dir.path().join("both.ply");
    write_ply(&both, &points);
    sparser.extend((0..4_000).map(|_| [20.0 + rng() * 14.0, rng() * 14.0, 0.0]));
    let few = dir.path().join("few.ply");
    write_ply(&few, &sparser);
    let warnings = |ply: &Path, name: &str| {
        let out = dir.path().join(name);
        let o = run_ok(&["convert", s(ply), "-o", s(&out), "--normals", "-q"]);
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let said = warnings(&both, "both");
    assert!(
        said.contains("have no normal, and small discs") && said.contains("--normal-radius"),
        "the sparse square is said: {said}"
    );
    let said = warnings(&few, "few");
    assert!(
        said.contains("their discs are cut to that radius") && said.contains("--normal-radius"),
        "the sparser square is said: {said}"
    );
    assert_eq!(
        warnings(&dense_only, "dense"),
        "",
        "nothing to say of the dense one"
    );
}

/// A PLY's own `scanner` property names no scan whose position the dataset knows: it is kept
/// as `extra_scanner`, said, and its points' normals face up. Taken for the dataset's
/// `scanner`, its 1 made them face the E57's second scanner (below the plane), and alone it
/// let `--orient scanner` run with no scanner known (normals then faced up, recorded as
/// oriented towards the scanner).
#[test]
fn a_ply_scanner_property_is_not_taken_for_a_scan() {
    let dir = tempfile::tempdir().expect("tempdir");
    let e57 = dir.path().join("plane.e57");
    write_two_sided_plane(&e57, true);
    let ply = dir.path().join("beside.ply");
    let mut text = String::from(
        "ply\nformat ascii 1.0\nelement vertex 400\nproperty double x\nproperty double y\n\
         property double z\nproperty ushort scanner\nend_header\n",
    );
    for gx in 0..20 {
        for gy in 0..20 {
            let (x, y) = (6.0 + gx as f64 * 0.1, gy as f64 * 0.1 - 1.0);
            text.push_str(&format!(
                "{x} {y} {} 1\n",
                0.013 * ((gx * 7 + gy) % 5) as f64
            ));
        }
    }
    std::fs::write(&ply, text).expect("ply");
    let out = dir.path().join("ds");
    let o = run(&["convert", s(&e57), s(&ply), "-o", s(&out), "--normals"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("beside.ply: its \"scanner\" attribute names no scan")
            && err.contains("kept as \"extra_scanner\""),
        "{err}"
    );
    let ds = LocalDataset::open(&out).expect("open");
    assert!(ds.layout().index_of("extra_scanner").is_some());
    let mut from_ply = 0;
    for (scan, n) in normals_by_scanner(&out) {
        if scan == u16::MAX {
            assert!(n[2] > 0.99, "a PLY point's normal {n:?}");
            from_ply += 1;
        }
    }
    assert_eq!(from_ply, 400);
    let alone = dir.path().join("alone");
    let o = run(&[
        "convert",
        s(&ply),
        "-o",
        s(&alone),
        "--normals",
        "--orient",
        "scanner",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("needs to know where the scanner stood"),
        "{err}"
    );
    assert!(!alone.exists());
}

/// A normal radius that takes in the whole scan: every chunk's halo is all the points. Workers
/// index fewer at once so that the memory limit holds (214 MiB under a 160 MiB limit at 4
/// threads before), and a limit that cannot hold even one is said before indexing begins.
#[test]
fn a_normal_radius_wider_than_the_scan_keeps_within_the_memory_limit_or_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = dir.path().join("city.las");
    run_ok(&["synth", "--points", "400k", "-o", s(&las), "--seed", "2"]);
    let (ds, st) = (dir.path().join("ds"), dir.path().join("st.json"));
    let wide = [
        "--normals",
        "--normal-radius",
        "1e6",
        "--threads",
        "4",
        "-q",
    ];
    let convert = |limit: &str| -> Vec<String> {
        let head = ["convert", s(&las), "-o", s(&ds), "--memory-limit", limit];
        let tail = ["--stats", s(&st)];
        [&head[..], &wide, &tail]
            .concat()
            .iter()
            .map(|a| a.to_string())
            .collect()
    };
    let args = convert("160MiB");
    run_ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&st).expect("stats")).expect("json");
    let peak = stats["peak_memory_bytes"].as_u64().unwrap_or(u64::MAX);
    assert!(
        peak < 160 << 20,
        "peaked at {peak} bytes under a 160 MiB limit"
    );
    std::fs::remove_dir_all(&ds).expect("remove");
    let args = convert("64MiB");
    let err = refused(
        &args.iter().map(String::as_str).collect::<Vec<_>>(),
        &[
            "within 1000000 of chunk",
            "--normal-radius",
            "--memory-limit 64 MiB",
        ],
    );
    assert_eq!(err.trim().lines().count(), 1, "one sentence: {err}");
    assert!(!ds.exists(), "no output may appear: {err}");
}
