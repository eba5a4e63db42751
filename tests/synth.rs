//! Synthetic scenes are deterministic and readable in every output format.

mod common;
use common::*;

#[test]
fn same_seed_same_bytes_other_seed_other_points() {
    let dir = tempfile::tempdir().expect("tempdir");
    let a = dir.path().join("a.las");
    let b = dir.path().join("b.las");
    let c = dir.path().join("c.las");
    run_ok(&["synth", "--points", "50k", "-o", s(&a), "--seed", "3"]);
    run_ok(&["synth", "--points", "50k", "-o", s(&b), "--seed", "3"]);
    run_ok(&["synth", "--points", "50k", "-o", s(&c), "--seed", "4"]);
    assert_eq!(las_multiset(&a), las_multiset(&b));
    assert_ne!(las_multiset(&a), las_multiset(&c));
}

#[test]
fn scenes_have_ground_buildings_and_vegetation_with_colour() {
    let dir = tempfile::tempdir().expect("tempdir");
    let a = dir.path().join("city.laz");
    run_ok(&["synth", "--points", "100000", "-o", s(&a)]);
    let pts = las_multiset(&a);
    assert_eq!(pts.len(), 100_000);
    let mut head = [0u8; 105];
    std::io::Read::read_exact(&mut std::fs::File::open(&a).expect("open"), &mut head)
        .expect("header");
    assert_ne!(head[104] & 0x80, 0, ".laz output must be LAZ-compressed");
    assert!(
        std::fs::metadata(&a).expect("meta").len() < 100_000 * 34 / 2,
        "LAZ should be well under half the LAS size"
    );
    let classes: std::collections::BTreeSet<i64> = pts.iter().map(|p| p.1[3]).collect();
    for c in [2, 6] {
        assert!(classes.contains(&c), "class {c} missing: {classes:?}");
    }
    assert!(
        classes.contains(&4) || classes.contains(&5),
        "no vegetation"
    );
    assert!(pts.iter().any(|p| p.1[13] != p.1[14]), "colour varies");
    // Far from the origin, like survey data.
    assert!(pts[0].0[0] as f64 * 0.001 > 400_000.0);
}

#[test]
fn ply_and_terrain_outputs_convert() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = dir.path().join("t.ply");
    run_ok(&[
        "synth",
        "--points",
        "20000",
        "--scene",
        "terrain",
        "-o",
        s(&p),
    ]);
    let ds = dir.path().join("ds");
    run_ok(&["convert", s(&p), "-o", s(&ds), "-q"]);
    let o = run_ok(&["info", s(&ds), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["points"], 20000);
}

#[test]
fn noise_moves_every_point_by_about_its_deviation_and_nothing_else() {
    let dir = tempfile::tempdir().expect("tempdir");
    let exact = dir.path().join("exact.las");
    let noisy = dir.path().join("noisy.las");
    run_ok(&["synth", "--points", "20k", "-o", s(&exact)]);
    run_ok(&[
        "synth",
        "--points",
        "20k",
        "--noise",
        "0.05",
        "-o",
        s(&noisy),
    ]);
    // Points keep their order; LAS integers are millimetres.
    let (a, b) = (las_points(&exact).0, las_points(&noisy).0);
    assert_eq!(a.len(), b.len());
    let mut squares = 0.0;
    for (p, q) in a.iter().zip(&b) {
        assert_eq!(p.1, q.1, "noise changed an attribute");
        for c in 0..3 {
            squares += ((q.0[c] - p.0[c]) as f64 * 0.001).powi(2);
        }
    }
    let deviation = (squares / (3 * a.len()) as f64).sqrt();
    assert!(
        (deviation - 0.05).abs() < 0.005,
        "deviation {deviation} m for --noise 0.05"
    );
    let bad = run(&[
        "synth",
        "--points",
        "1k",
        "--noise=-1",
        "-o",
        s(&noisy),
        "--overwrite",
    ]);
    assert!(!bad.status.success());
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert!(stderr.contains("--noise"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// A `.copc.laz` name asks for COPC, which only `export` of a dataset makes: refused, with the
/// way to make one, rather than a plain LAZ file under a COPC name.
#[test]
fn a_copc_name_is_refused_with_the_way_to_make_one() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("scan.copc.laz");
    let o = run(&["synth", "--points", "1000", "-o", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "synth wrote {}", out.display());
    assert!(
        err.contains("not COPC") && err.contains("strata export"),
        "{err}"
    );
    assert!(!out.exists(), "nothing is left under the COPC name");
}

/// `demo --points 0` is refused before it makes its folder.
#[test]
fn an_empty_demo_is_refused_before_its_folder_is_made() {
    let dir = tempfile::tempdir().expect("tempdir");
    let demo = dir.path().join("demo");
    let o = run(&["demo", "--points", "0", "--dir", s(&demo), "--png"]);
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("--points must be at least 1"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(!demo.exists(), "the refused demo left {}", demo.display());
}

/// A user's own files where the demo writes its own are left alone: the demo overwrote a
/// city.laz, then failed on a city.png that was not an image.
#[test]
fn the_demo_replaces_only_its_own_files() {
    let dir = tempfile::tempdir().expect("tempdir");
    for name in ["city.laz", "city.png"] {
        let demo = dir.path().join(name.replace('.', "_"));
        std::fs::create_dir_all(&demo).expect("dir");
        std::fs::write(demo.join(name), b"precious").expect("write");
        let o = run(&["demo", "--points", "1000", "--dir", s(&demo), "--png"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{name}: {err}");
        assert!(
            err.contains(name) && err.contains("exists and is not"),
            "{err}"
        );
        assert_eq!(std::fs::read(demo.join(name)).expect("read"), b"precious");
        let made: Vec<_> = std::fs::read_dir(&demo).expect("dir").flatten().collect();
        assert_eq!(made.len(), 1, "{name}: the refused demo made {made:?}");
    }
}

/// A scene no disk here holds is refused before a byte is written (it ran on for hours).
#[test]
fn a_scene_larger_than_the_free_disk_is_refused_up_front() {
    let dir = tempfile::tempdir().expect("tempdir");
    for ext in ["las", "laz", "ply"] {
        let out = dir.path().join(format!("huge.{ext}"));
        let o = run(&["synth", "--points", "1e14", "-o", s(&out)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{ext}: {err}");
        assert!(err.contains("of free disk there"), "{ext}: {err}");
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .expect("dir")
            .flatten()
            .collect();
        assert!(left.is_empty(), "{ext}: {left:?}");
    }
}

/// A bare file name is the working folder's: the space check once skipped it (its parent, "",
/// does not exist) and the write ran until the disk filled.
#[test]
fn a_bare_output_name_is_checked_for_space_too() {
    let dir = tempfile::tempdir().expect("tempdir");
    let o = strata()
        .current_dir(dir.path())
        .args(["synth", "--points", "1e14", "-o", "huge.laz"])
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("of free disk there"), "{err}");
}

/// SOURCE_DATE_EPOCH dates the LAS header, so the same seed gives the same file on any day;
/// the times are marked adjusted standard GPS time (global encoding bit 0), which 10^8 s is,
/// where the header said GPS week time.
#[test]
fn a_dated_scene_is_the_same_file_and_its_times_are_adjusted_standard() {
    let dir = tempfile::tempdir().expect("tempdir");
    let write = |name: &str| {
        let out = dir.path().join(name);
        let o = strata()
            .env("SOURCE_DATE_EPOCH", "31622400") // 1971-01-02
            .args(["synth", "--points", "5k", "-o", s(&out)])
            .output()
            .expect("runs");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(out).expect("read")
    };
    let (a, b) = (write("a.las"), write("b.las"));
    assert_eq!(a, b);
    // Day of the year and year (LAS 1.4 header bytes 90 to 93).
    assert_eq!(u16::from_le_bytes([a[90], a[91]]), 2);
    assert_eq!(u16::from_le_bytes([a[92], a[93]]), 1971);
    assert_eq!(
        u16::from_le_bytes([a[6], a[7]]) & 1,
        1,
        "adjusted standard GPS time"
    );
}

/// A part another writer holds (locked) refuses a second writer, which leaves it alone; once
/// it is let go (its writer killed), the next run replaces it. Two runs to one output wrote
/// into one file, and the first to finish moved the mixture into place with exit 0.
#[test]
fn a_second_writer_of_one_output_is_refused_and_a_left_part_replaced() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("x.las");
    let part = dir.path().join("x.las.part");
    std::fs::write(&part, b"another writer's").expect("write");
    let held = std::fs::File::open(&part).expect("open");
    held.try_lock().expect("lock");
    let o = run(&["synth", "--points", "1k", "-o", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("another strata is writing it"), "{err}");
    assert_eq!(std::fs::read(&part).expect("read"), b"another writer's");
    assert!(!out.exists());
    drop(held);
    run_ok(&["synth", "--points", "1k", "-o", s(&out)]);
    assert!(out.exists() && !part.exists());
}
