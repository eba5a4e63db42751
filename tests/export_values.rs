//! Values `export` writes as the format means them, or refuses: a fraction in a LAS integer
//! field (a PLY's float intensity), colour in LAS's 16 bits (8-bit and float colours scaled),
//! and outputs that would destroy the dataset being read.

mod common;
use common::*;
use std::path::Path;

/// An ASCII PLY of points on the x axis with `props` (type and name) holding `rows`' values.
fn ply(path: &Path, props: &[(&str, &str)], rows: &[Vec<String>]) {
    let mut text = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
        rows.len()
    );
    for (ty, name) in props {
        text.push_str(&format!("property {ty} {name}\n"));
    }
    text.push_str("end_header\n");
    for (i, row) in rows.iter().enumerate() {
        text.push_str(&format!("{i} 0 0 {}\n", row.join(" ")));
    }
    std::fs::write(path, text).expect("write ply");
}

/// A failed export: one line naming `expect`, and nothing left where the output would be.
fn export_refused(ds: &Path, out: &Path, expect: &[&str]) {
    let err = refused(&["export", s(ds), "-o", s(out)], expect);
    assert_eq!(err.trim().lines().count(), 1, "one sentence: {err}");
    assert!(!out.exists(), "{}: no output", out.display());
    let mut part = out.as_os_str().to_owned();
    part.push(".part");
    assert!(!Path::new(&part).exists(), "{}: no leftover", out.display());
}

/// PLY floats named like LAS fields go into those fields where they are whole numbers; a
/// fraction is refused (it was rounded without a word: 0.25 became 0), naming the dataset,
/// the field, the value and the point, for LAS, LAZ and COPC alike.
#[test]
fn a_fraction_in_a_las_integer_field_is_refused_not_rounded() {
    let dir = tempfile::tempdir().expect("tempdir");
    let fields = [
        "intensity",
        "classification",
        "user_data",
        "point_source_id",
        "scan_angle",
        "return_number",
        "number_of_returns",
        "nir",
    ];
    let props: Vec<(&str, &str)> = fields.iter().map(|f| ("float", *f)).collect();
    let whole = [
        vec!["3", "2", "7", "1234", "-250", "1", "2", "900"],
        vec!["65535", "200", "255", "65535", "5", "2", "2", "0"],
    ];
    let text = |r: &[&str]| r.iter().map(|v| v.to_string()).collect::<Vec<_>>();
    let (input, ds) = (dir.path().join("w.ply"), dir.path().join("w.strata"));
    ply(&input, &props, &[text(&whole[0]), text(&whole[1])]);
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    let las = dir.path().join("w.las");
    run_ok(&["export", s(&ds), "-o", s(&las)]);
    let points = las_points_by_x(&las);
    // The fields in the order of `fields`.
    let got: Vec<[i64; 8]> = points
        .iter()
        .map(|p| {
            [
                i64::from(p.intensity),
                i64::from(u8::from(p.classification)),
                i64::from(p.user_data),
                i64::from(p.point_source_id),
                // In degrees; the field's steps are 0.006°.
                (f64::from(p.scan_angle) / 0.006).round() as i64,
                i64::from(p.return_number),
                i64::from(p.number_of_returns),
                // The las crate reads a NIR of 0 as none.
                i64::from(p.nir.unwrap_or(0)),
            ]
        })
        .collect();
    assert_eq!(
        got,
        [
            [3, 2, 7, 1234, -250, 1, 2, 900],
            [65535, 200, 255, 65535, 5, 2, 2, 0],
        ]
    );
    // Each field with a fraction in the second point: refused, by name.
    for (k, field) in fields.iter().enumerate() {
        let mut second = whole[1].to_vec();
        let value = if *field == "scan_angle" {
            "2.5"
        } else {
            "1.25"
        };
        second[k] = value;
        let (input, ds) = (
            dir.path().join(format!("{field}.ply")),
            dir.path().join(format!("{field}.strata")),
        );
        ply(&input, &props, &[text(&whole[0]), text(&second)]);
        run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
        for ext in ["las", "laz", "copc.laz"] {
            let out = dir.path().join(format!("{field}.{ext}"));
            let said = format!("{field} is {value} (point ");
            export_refused(&ds, &out, &[&said, s(&ds), "not a whole number"]);
        }
        run_ok(&[
            "export",
            s(&ds),
            "-o",
            s(&dir.path().join(format!("{field}_out.ply"))),
        ]);
    }
}

/// An exported LAS file's points, by x.
fn las_points_by_x(path: &Path) -> Vec<las::Point> {
    let mut reader = las::Reader::from_path(path).expect("read export");
    let mut points: Vec<las::Point> = reader
        .read_all()
        .expect("points")
        .points()
        .map(|p| p.expect("point"))
        .collect();
    points.sort_by(|a, b| a.x.total_cmp(&b.x));
    points
}

/// (red, green, blue) of each exported LAS point, by x.
fn las_colours(path: &Path) -> Vec<(u16, u16, u16)> {
    let points = las_points_by_x(path);
    points
        .iter()
        .map(|p| {
            let c = p.color.expect("a colour");
            (c.red, c.green, c.blue)
        })
        .collect()
}

/// 8-bit colour goes into LAS's 16-bit RGB scaled by 257 (255 is 65535; LAS 1.4 R15 asks for
/// colour normalised to 16 bits), a float colour in 0 to 1 times 65535; PLY keeps 8 bits.
#[test]
fn colour_goes_into_las_in_16_bits() {
    let dir = tempfile::tempdir().expect("tempdir");
    let rgb = [
        ("uchar", "red"),
        ("uchar", "green"),
        ("uchar", "blue"),
        ("uchar", "nir"),
    ];
    let (input, ds) = (dir.path().join("c8.ply"), dir.path().join("c8.strata"));
    let rows =
        [["255", "128", "1", "255"], ["0", "10", "20", "3"]].map(|r| r.map(String::from).to_vec());
    ply(&input, &rgb, &rows);
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    for name in ["c8.las", "c8.laz", "c8.copc.laz"] {
        let out = dir.path().join(name);
        run_ok(&["export", s(&ds), "-o", s(&out)]);
        assert_eq!(
            las_colours(&out),
            [(65535, 128 * 257, 257), (0, 10 * 257, 20 * 257)],
            "{name}"
        );
        let nir: Vec<Option<u16>> = las_points_by_x(&out).iter().map(|p| p.nir).collect();
        assert_eq!(
            nir,
            [Some(65535), Some(3 * 257)],
            "{name}: the near infrared too"
        );
    }
    let back = dir.path().join("c8_out.ply");
    run_ok(&["export", s(&ds), "-o", s(&back)]);
    let head = String::from_utf8_lossy(&std::fs::read(&back).expect("ply")).into_owned();
    assert!(head.contains("property uchar red\n"), "{head}");

    let float = [("float", "red"), ("float", "green"), ("float", "blue")];
    let (input, ds) = (dir.path().join("cf.ply"), dir.path().join("cf.strata"));
    let rows = [["1", "0.5", "0"], ["0.25", "0", "1"]].map(|r| r.map(String::from).to_vec());
    ply(&input, &float, &rows);
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    for name in ["cf.las", "cf.copc.laz"] {
        let out = dir.path().join(name);
        run_ok(&["export", s(&ds), "-o", s(&out)]);
        assert_eq!(
            las_colours(&out),
            [(65535, 32768, 0), (16384, 0, 65535)],
            "{name}"
        );
    }
    // A float colour outside 0 to 1 has no 16-bit value: refused, as other values are.
    let (input, ds) = (dir.path().join("c255.ply"), dir.path().join("c255.strata"));
    let rows = [["1", "0.5", "0"], ["200", "0", "1"]].map(|r| r.map(String::from).to_vec());
    ply(&input, &float, &rows);
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    for name in ["c255.las", "c255.copc.laz"] {
        let out = dir.path().join(name);
        export_refused(&ds, &out, &["rgb is 200 (point ", "outside 0 to 1"]);
    }
}

/// An export onto, into or around its own dataset is refused before anything is written: a
/// Potree 2.0 export with --overwrite replaced the dataset it was reading.
#[test]
fn an_export_over_its_own_dataset_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (input, ds) = (dir.path().join("p.ply"), dir.path().join("p.strata"));
    let rows = [["1"], ["2"]].map(|r| r.map(String::from).to_vec());
    ply(&input, &[("uchar", "classification")], &rows);
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    let before = std::fs::read(ds.join("octree.bin")).expect("octree");
    let potree = |out: &Path| {
        vec![
            "export".to_string(),
            s(&ds).to_string(),
            "-o".into(),
            s(out).to_string(),
            "--format".into(),
            "potree2".into(),
            "--overwrite".into(),
        ]
    };
    for (out, said) in [
        (ds.clone(), "is the dataset being exported"),
        (ds.join("p2"), "lies inside the dataset"),
        (dir.path().to_path_buf(), "holds the dataset"),
    ] {
        let args = potree(&out);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let err = refused(&args, &[said, "give -o a place outside the dataset"]);
        assert_eq!(err.trim().lines().count(), 1, "one sentence: {err}");
    }
    let inside = ds.join("p.las");
    let err = refused(
        &["export", s(&ds), "-o", s(&inside), "--overwrite"],
        &["lies inside the dataset"],
    );
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(!inside.exists());
    assert_eq!(
        std::fs::read(ds.join("octree.bin")).expect("octree"),
        before
    );
    run_ok(&["verify", s(&ds)]);
}

/// A `.copc.las` would be taken for COPC; it was written as plain LAS without a word.
#[test]
fn a_copc_las_name_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (input, ds) = (dir.path().join("p.ply"), dir.path().join("p.strata"));
    let rows = [["1"], ["2"]].map(|r| r.map(String::from).to_vec());
    ply(&input, &[("uchar", "classification")], &rows);
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    export_refused(&ds, &dir.path().join("p.copc.las"), &["NAME.copc.laz"]);
    export_refused(&ds, &dir.path().join("p.xyz"), &[".copc.laz", "potree2"]);
    // A trailing slash names a folder: refused before the export, not when it is moved there.
    for tail in ["/", "/."] {
        let slashed = format!("{}{tail}", s(&dir.path().join("q.las")));
        export_refused(&ds, Path::new(&slashed), &["which names a folder"]);
    }
}

/// Time stamps of no base (a PLY's) go to LAS as GPS week time, LAS having no "unknown": that
/// is said; to PLY, which states none, it is not.
#[test]
fn times_of_no_base_are_said_when_las_states_one() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (input, ds) = (dir.path().join("timed.ply"), dir.path().join("ds"));
    ply(
        &input,
        &[("double", "gps_time")],
        &[vec!["5e8".into()], vec!["5.1e8".into()]],
    );
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    for (name, warned) in [
        ("out.las", true),
        ("out.copc.laz", true),
        ("out.ply", false),
    ] {
        let out = run_ok(&["export", s(&ds), "-o", s(&dir.path().join(name))]);
        let said = String::from_utf8_lossy(&out.stderr).contains("states no time base");
        assert_eq!(said, warned, "{name}");
    }
}

/// Fields laspy and PDAL take for standard ones (`X`, `Intensity` in another case or
/// spelling) go out as `extra_NAME`, said: laspy refused a LAS whose extra field was `X`.
#[test]
fn extra_fields_named_like_standard_ones_are_renamed_on_export() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (input, ds) = (dir.path().join("named.ply"), dir.path().join("ds"));
    let props = [("float", "X"), ("float", "Intensity"), ("float", "height")];
    ply(
        &input,
        &props,
        &[vec!["1.5".into(), "7".into(), "3".into()]],
    );
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    for name in ["out.las", "out.copc.laz"] {
        let out = dir.path().join(name);
        let o = run_ok(&["export", s(&ds), "-o", s(&out)]);
        let err = String::from_utf8_lossy(&o.stderr);
        for said in [
            "\"X\" is written as \"extra_X\"",
            "\"Intensity\" is written as",
        ] {
            assert!(err.contains(said), "{name}: {err}");
        }
        let back = dir.path().join(format!("{name}.strata"));
        run_ok(&["convert", s(&out), "-o", s(&back), "-q"]);
        let meta = strata_format::LocalDataset::open(&back)
            .expect("opens")
            .metadata()
            .clone();
        let names: Vec<&str> = meta.attributes.iter().map(|a| a.name.as_str()).collect();
        for kept in ["extra_X", "extra_Intensity", "height"] {
            assert!(names.contains(&kept), "{name}: {names:?}");
        }
    }
}

/// What an output has no place for is said, not dropped without a word: the scanners'
/// positions (E57 poses) in every format, a time base in PLY and Potree 2.0.
#[test]
fn scanner_positions_and_time_bases_an_output_cannot_hold_are_said() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scans = dir.path().join("scans");
    run_ok(&[
        "convert",
        s(&data("e57_tiny_spherical.e57")),
        "-o",
        s(&scans),
        "-q",
    ]);
    for name in ["out.las", "out.ply", "out.copc.laz"] {
        let o = run_ok(&["export", s(&scans), "-o", s(&dir.path().join(name))]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("1 scanner(s) stood"), "{name}: {err}");
    }
    let timed = dir.path().join("timed");
    run_ok(&[
        "convert",
        s(&data("autzen_trim.las")),
        "-o",
        s(&timed),
        "-q",
    ]);
    for (name, said) in [("t.ply", true), ("t.las", false)] {
        let o = run_ok(&["export", s(&timed), "-o", s(&dir.path().join(name))]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(err.contains("counts from"), said, "{name}: {err}");
    }
}

/// A legacy LAS merged with a PLY whose classes go past 31: the LAS export takes a point
/// format that holds them (it took the legacy format of the LAS input and refused the PLY's
/// class 40), and keeps every class, the legacy input's among them.
#[test]
fn classes_past_31_merged_with_a_legacy_las_take_an_extended_format() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (las_in, ply_in) = (dir.path().join("a.las"), dir.path().join("b.ply"));
    run_ok(&["synth", "--points", "500", "-o", s(&las_in), "--seed", "3"]);
    ply(
        &ply_in,
        &[("uchar", "classification")],
        &[vec!["40".into()], vec!["200".into()]],
    );
    let ds = dir.path().join("ds");
    run_ok(&["convert", s(&las_in), s(&ply_in), "-o", s(&ds), "-q"]);
    for name in ["out.las", "out.laz"] {
        let out = dir.path().join(name);
        run_ok(&["export", s(&ds), "-o", s(&out)]);
        let r = las::Reader::from_path(&out).expect("read export");
        assert!(r.header().point_format().is_extended, "{name}");
        let classes: std::collections::BTreeSet<u8> = las_points_by_x(&out)
            .iter()
            .map(|p| u8::from(p.classification))
            .collect();
        assert!(
            classes.contains(&40) && classes.contains(&200),
            "{name}: {classes:?}"
        );
        assert!(classes.iter().any(|&c| c <= 31), "{name}: {classes:?}");
    }
    // A profile through the PLY's points alone: its rows say so, whatever the dataset counts.
    let prof = dir.path().join("profile.las");
    let line = "--line=-1,0;3,0";
    run_ok(&["profile", s(&ds), line, "--width", "1", "-o", s(&prof)]);
    let r = las::Reader::from_path(&prof).expect("read profile");
    assert!(r.header().point_format().is_extended, "profile");
    let classes: Vec<u8> = las_points_by_x(&prof)
        .iter()
        .map(|p| u8::from(p.classification))
        .collect();
    assert_eq!(classes, [40, 200]);
}
