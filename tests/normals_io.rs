//! Normals in and out: LAS extra bytes named like a normal's components read as one `normal`,
//! `strata export` writing estimated normals, radii and surface variation to PLY and LAS so that
//! they read back, and `strata info` describing them.

mod common;
use common::*;
use std::path::Path;
use strata_converter::writers::{LasChoices, open_writer};
use strata_format::{AttrType, Attribute, LocalDataset, RowLayout, oct16_decode};

/// One point of a dataset: position on a common grid, normal, radius, surface variation.
type Point = ([i64; 3], Option<[f64; 3]>, f64, f64);

/// Every point of a dataset, sorted; positions on the grid of `grid` (scale, offset).
fn points(dir: &Path, grid: ([f64; 3], [f64; 3])) -> Vec<Point> {
    let ds = LocalDataset::open(dir).expect("dataset opens");
    let layout = ds.layout().clone();
    let meta = ds.metadata().clone();
    let index = |name: &str| layout.index_of(name);
    let n = index("normal").expect("a normal attribute");
    let (r, s) = (index("radius"), index("surface_variation"));
    let mut out = Vec::new();
    for node in ds.all_nodes().expect("nodes") {
        if node.point_count == 0 {
            continue;
        }
        let cols = ds.read_node(&node).expect("node reads");
        let value = |i: Option<usize>, p: usize| {
            i.map_or(0.0, |i| {
                let a = &layout.attributes[i];
                a.ty.read_f64(&cols.attribute(&layout, i)[p * a.size()..])
            })
        };
        let na = &layout.attributes[n];
        let nc = cols.attribute(&layout, n);
        for p in 0..node.point_count as usize {
            let normal = if na.is_oct16() {
                let c = &nc[p * 4..];
                oct16_decode([
                    u16::from_le_bytes([c[0], c[1]]),
                    u16::from_le_bytes([c[2], c[3]]),
                ])
            } else {
                let sz = na.ty.size();
                let v: [f64; 3] = std::array::from_fn(|k| na.ty.read_f64(&nc[(p * 3 + k) * sz..]));
                (v != [0.0; 3]).then_some(v)
            };
            let real = meta.to_real(cols.position(p));
            let q: [i64; 3] =
                std::array::from_fn(|a| ((real[a] - grid.1[a]) / grid.0[a]).round() as i64);
            out.push((q, normal, value(r, p), value(s, p)));
        }
    }
    out.sort_by(|a, b| {
        a.0.cmp(&b.0)
            .then(a.2.total_cmp(&b.2))
            .then(a.3.total_cmp(&b.3))
            .then_with(|| {
                let n = |x: &Point| x.1.unwrap_or_default();
                n(a).partial_cmp(&n(b)).unwrap_or(std::cmp::Ordering::Equal)
            })
    });
    out
}

fn metadata(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("metadata.json")).expect("metadata"))
        .expect("metadata JSON")
}

fn grid(dir: &Path) -> ([f64; 3], [f64; 3]) {
    let m = LocalDataset::open(dir)
        .expect("dataset opens")
        .metadata()
        .clone();
    (m.scale, m.offset)
}

fn angle(a: [f64; 3], b: [f64; 3]) -> f64 {
    let l = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let d = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / (l(a) * l(b));
    d.clamp(-1.0, 1.0).acos().to_degrees()
}

#[test]
fn las_extra_bytes_nx_ny_nz_are_one_normal_that_normals_keeps() {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = dir.path().join("normals.las");
    // A LAS whose extra bytes are nx, a field between, ny and nz (scalar floats).
    let layout = RowLayout::new(vec![
        Attribute::new("intensity", AttrType::U16, 1),
        Attribute::new("nx", AttrType::F32, 1),
        Attribute::new("h", AttrType::U16, 1),
        Attribute::new("ny", AttrType::F32, 1),
        Attribute::new("nz", AttrType::F32, 1),
    ]);
    let side: i32 = 60;
    let normal = |i: i32, j: i32| {
        let v = [
            (i as f64 * 0.1).sin() * 0.3,
            (j as f64 * 0.1).cos() * 0.3,
            1.0,
        ];
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|c| (c / l) as f32)
    };
    let mut rows = Vec::new();
    for i in 0..side {
        for j in 0..side {
            for p in [i * 100, j * 100, (i + j) * 10] {
                rows.extend_from_slice(&p.to_le_bytes());
            }
            let n = normal(i, j);
            rows.extend_from_slice(&7u16.to_le_bytes());
            rows.extend_from_slice(&n[0].to_le_bytes());
            rows.extend_from_slice(&((i * side + j) as u16).to_le_bytes());
            rows.extend_from_slice(&n[1].to_le_bytes());
            rows.extend_from_slice(&n[2].to_le_bytes());
        }
    }
    let scale = [0.001; 3];
    let mut w = open_writer(
        &las,
        &layout,
        scale,
        [0.0; 3],
        (side * side) as u64,
        false,
        LasChoices::default(),
    )
    .expect("LAS writer");
    w.write_rows(&rows).expect("rows written");
    w.finish().expect("LAS finished");

    let ds = dir.path().join("ds");
    run_ok(&["convert", s(&las), "-o", s(&ds), "-q"]);
    let meta = metadata(&ds);
    let attrs = meta["attributes"].as_array().expect("attributes");
    let shape = |name: &str| {
        attrs.iter().find(|a| a["name"] == name).map(|a| {
            (
                a["type"].as_str().unwrap_or("").to_string(),
                a["count"].as_u64(),
            )
        })
    };
    assert_eq!(shape("normal"), Some(("f32".into(), Some(3))), "{attrs:?}");
    assert_eq!(shape("h"), Some(("u16".into(), Some(1))));
    for gone in ["nx", "ny", "nz"] {
        assert_eq!(shape(gone), None, "{gone} is part of normal");
    }
    let got = points(&ds, (scale, [0.0; 3]));
    assert_eq!(got.len(), (side * side) as usize);
    for (q, n, _, _) in &got {
        let (i, j) = ((q[0] / 100) as i32, (q[1] / 100) as i32);
        let want = normal(i, j).map(f64::from);
        assert_eq!(*n, Some(want), "point {i},{j}");
    }

    let kept = dir.path().join("kept");
    run_ok(&["convert", s(&las), "-o", s(&kept), "-q", "--normals"]);
    let normals = &metadata(&kept)["normals"];
    assert_eq!(normals["kept"], side * side, "{normals}");
    assert_eq!(normals["computed"], 0, "{normals}");
}

/// `convert --normals`, export to `ext`, convert the export again: the normals, radii and
/// surface variation come back.
fn export_round_trip(ext: &str) {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = dir.path().join("city.las");
    run_ok(&["synth", "--points", "50000", "-o", s(&las), "--seed", "5"]);
    let ds = dir.path().join("ds");
    run_ok(&["convert", s(&las), "-o", s(&ds), "-q", "--normals"]);
    let out = dir.path().join(format!("out.{ext}"));
    run_ok(&["export", s(&ds), "-o", s(&out)]);
    let again = dir.path().join("again");
    run_ok(&["convert", s(&out), "-o", s(&again), "-q"]);
    let a = points(&ds, grid(&ds));
    let b = points(&again, grid(&ds));
    assert_eq!(a.len(), b.len());
    let mut worst: f64 = 0.0;
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.0, y.0, "positions");
        match (x.1, y.1) {
            (Some(m), Some(n)) => worst = worst.max(angle(m, n)),
            (None, None) => {}
            other => panic!("at {:?} the normals are {other:?}", x.0),
        }
        // f16 values widened to f32 are exact.
        for (u, v) in [(x.2, y.2), (x.3, y.3)] {
            assert!(
                (u - v).abs() <= u.abs() * 1e-3,
                "{u} became {v} at {:?}",
                x.0
            );
        }
    }
    assert!(
        worst < 0.01,
        "{ext}: normals moved by up to {worst} degrees"
    );
    assert!(a.iter().filter(|p| p.1.is_some()).count() > a.len() * 9 / 10);
    assert!(a.iter().any(|p| p.2 > 0.0) && a.iter().any(|p| p.3 > 0.0));
}

#[test]
fn exported_ply_keeps_normals_radii_and_surface_variation() {
    export_round_trip("ply");
}

#[test]
fn exported_las_keeps_normals_radii_and_surface_variation_as_extra_bytes() {
    export_round_trip("las");
}

#[test]
fn exported_files_name_the_normal_as_other_tools_read_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = dir.path().join("city.las");
    run_ok(&["synth", "--points", "20000", "-o", s(&las), "--seed", "2"]);
    let ds = dir.path().join("ds");
    run_ok(&["convert", s(&las), "-o", s(&ds), "-q", "--normals"]);
    let ply = dir.path().join("out.ply");
    run_ok(&["export", s(&ds), "-o", s(&ply)]);
    let bytes = std::fs::read(&ply).expect("PLY written");
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(2000)]);
    for p in ["nx", "ny", "nz", "radius", "surface_variation"] {
        assert!(head.contains(&format!("property float {p}\n")), "{head}");
    }
    let laz = dir.path().join("out.laz");
    run_ok(&["export", s(&ds), "-o", s(&laz)]);
    let reader = las::Reader::from_path(&laz).expect("LAZ reads");
    let vlr = reader
        .header()
        .vlrs()
        .iter()
        .find(|v| v.user_id == "LASF_Spec" && v.record_id == 4)
        .expect("an extra bytes VLR");
    let fields: Vec<(String, u8)> = vlr
        .data
        .chunks_exact(192)
        .map(|d| {
            let end = d[4..36].iter().position(|&b| b == 0).unwrap_or(32);
            (String::from_utf8_lossy(&d[4..4 + end]).into_owned(), d[2])
        })
        .collect();
    let f32_code = 9;
    for name in [
        "NormalX",
        "NormalY",
        "NormalZ",
        "radius",
        "surface_variation",
    ] {
        assert!(
            fields.contains(&(name.to_string(), f32_code)),
            "{name} as a scalar f32 in {fields:?}"
        );
    }
    // Read back with --normals: every normal is the file's own.
    let kept = dir.path().join("kept");
    run_ok(&["convert", s(&laz), "-o", s(&kept), "-q", "--normals"]);
    assert_eq!(metadata(&kept)["normals"]["kept"], 20000);
}

#[test]
fn info_shows_encodings_and_how_normals_were_made() {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = dir.path().join("city.las");
    run_ok(&["synth", "--points", "20000", "-o", s(&las), "--seed", "4"]);
    let ds = dir.path().join("ds");
    run_ok(&[
        "convert",
        s(&las),
        "-o",
        s(&ds),
        "-q",
        "--normals",
        "--normal-k",
        "12",
    ]);
    let text = String::from_utf8_lossy(&run_ok(&["info", s(&ds)]).stdout).into_owned();
    let line = |start: &str| {
        text.lines()
            .find(|l| l.trim_start().starts_with(start))
            .unwrap_or_else(|| panic!("no line for {start} in\n{text}"))
            .to_string()
    };
    assert!(line("normal ").ends_with("2 x u16 (oct16)"), "{text}");
    assert!(line("rgb").ends_with("3 x u16"), "{text}");
    assert!(line("radius").ends_with("f32"), "{text}");
    let normals = line("normals");
    assert!(
        normals.contains("k 12")
            && normals.contains("oriented up")
            && normals.contains("20000 computed, 0 kept"),
        "{normals}"
    );
    assert!(
        text.contains("mean radius") && text.contains("surfel radius"),
        "{text}"
    );

    let json: serde_json::Value =
        serde_json::from_slice(&run_ok(&["info", s(&ds), "--json"]).stdout).expect("JSON");
    let normal = json["attributes"]
        .as_array()
        .and_then(|a| a.iter().find(|x| x["name"] == "normal"))
        .expect("normal listed");
    assert_eq!(normal["encoding"], "oct16");
    assert_eq!(json["normals"]["k"], 12);
    assert_eq!(json["normals"]["computed"], 20000);
    assert!(json["normals"]["mean_radius"].as_f64().unwrap_or(0.0) > 0.0);

    // Without --normals: no normals section, no encodings.
    let plain = dir.path().join("plain");
    run_ok(&["convert", s(&las), "-o", s(&plain), "-q"]);
    let text = String::from_utf8_lossy(&run_ok(&["info", s(&plain)]).stdout).into_owned();
    assert!(
        !text.contains("normals") && !text.contains("oct16"),
        "{text}"
    );
    let json: serde_json::Value =
        serde_json::from_slice(&run_ok(&["info", s(&plain), "--json"]).stdout).expect("JSON");
    assert!(json["normals"].is_null());
}

/// PLY normals named `normal_x normal_y normal_z` are one `normal`, as `nx ny nz` are, and kept
/// by `--normals`.
#[test]
fn ply_normal_x_y_z_are_one_normal_that_normals_keeps() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ply = dir.path().join("n.ply");
    let mut text = String::from(
        "ply\nformat ascii 1.0\nelement vertex 400\nproperty float x\nproperty float y\nproperty float z\nproperty float normal_x\nproperty float normal_y\nproperty float normal_z\nend_header\n",
    );
    for i in 0..400 {
        // A flat grid whose stated normals lean away from the plane's: kept, not estimated.
        text += &format!("{} {} 0 0.6 0 0.8\n", i % 20, i / 20);
    }
    std::fs::write(&ply, text).expect("write ply");
    let ds = dir.path().join("ds");
    run_ok(&["convert", s(&ply), "-o", s(&ds), "-q", "--normals"]);
    let meta = metadata(&ds);
    let names = attribute_names(&meta);
    assert!(
        names.contains(&"normal") && !names.contains(&"normal_x"),
        "{names:?}"
    );
    assert_eq!(meta["normals"]["kept"], 400, "{meta}");
    for (_, n, _, _) in points(&ds, grid(&ds)) {
        let n = n.expect("a normal");
        assert!(angle(n, [0.6, 0.0, 0.8]) < 0.1, "{n:?}");
    }
}

#[test]
fn an_input_radius_is_kept_with_its_normal_and_a_named_rule_turns_kept_normals() {
    // A plane whose given normals face down, every point with a splat radius of its own.
    let dir = tempfile::tempdir().expect("tempdir");
    let ply = dir.path().join("splats.ply");
    let mut text = String::from(
        "ply\nformat ascii 1.0\nelement vertex 1600\nproperty float x\nproperty float y\n\
         property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
         property float radius\nend_header\n",
    );
    for i in 0..40 {
        for j in 0..40 {
            text.push_str(&format!(
                "{} {} 0 0.6 0 -0.8 7\n",
                i as f32 * 0.1,
                j as f32 * 0.1
            ));
        }
    }
    std::fs::write(&ply, text).expect("write PLY");
    let cases: [(&str, &[&str], [f64; 3]); 3] = [
        ("keep", &["--normals"], [0.6, 0.0, -0.8]),
        ("up", &["--normals", "--orient", "up"], [-0.6, 0.0, 0.8]),
        ("compute", &["--normals", "compute"], [0.0, 0.0, 1.0]),
    ];
    for (name, flags, want) in cases {
        let ds = dir.path().join(name);
        let mut args = vec!["convert", s(&ply), "-o", s(&ds)];
        args.extend(flags);
        let out = run_ok(&args);
        let warned = String::from_utf8_lossy(&out.stderr)
            .contains("replaced the inputs' radius of 1600 points");
        assert_eq!(warned, name == "compute", "{name}");
        let got = points(&ds, grid(&ds));
        assert_eq!(got.len(), 1600);
        for (q, normal, radius, _) in got {
            let n = normal.unwrap_or_else(|| panic!("{name}: no normal at {q:?}"));
            assert!(angle(n, want) < 0.01, "{name}: {n:?} at {q:?}");
            if name == "compute" {
                assert!(radius < 1.0, "{name}: the estimate, not 7: {radius}");
            } else {
                assert_eq!(radius, 7.0, "{name}: the given radius at {q:?}");
            }
        }
    }
}
