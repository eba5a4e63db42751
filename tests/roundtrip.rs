//! Every input point comes out exactly once with all its attributes.

mod common;
use common::*;
use strata_converter::input::open_source;

fn convert_export_compare(input: &str, out_ext: &str, extra_args: &[&str]) {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("ds");
    let out = dir.path().join(format!("out.{out_ext}"));
    let src = data(input);
    let mut args = vec!["convert", s(&src), "-o", s(&ds), "-q"];
    args.extend_from_slice(extra_args);
    run_ok(&args);
    run_ok(&["verify", s(&ds)]);
    run_ok(&["export", s(&ds), "-o", s(&out)]);
    let a = las_multiset(&src);
    let b = las_multiset(&out);
    assert_eq!(a.len(), b.len(), "{input}: point count");
    assert!(a == b, "{input}: exported points differ from the input");
}

#[test]
fn autzen_las_round_trips_exactly() {
    convert_export_compare("autzen_trim.las", "las", &[]);
}

#[test]
fn autzen_laz_round_trips_exactly() {
    convert_export_compare("autzen_trim.laz", "laz", &[]);
}

#[test]
fn autzen_point_format_7_round_trips_exactly() {
    convert_export_compare("autzen_trim_pf7.las", "las", &["--sampling", "random"]);
}

#[test]
fn synth_split_into_many_chunks_round_trips_exactly() {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = dir.path().join("city.las");
    run_ok(&["synth", "--points", "300000", "-o", s(&las), "--seed", "7"]);
    let ds = dir.path().join("ds");
    let out = dir.path().join("back.laz");
    // A small memory limit forces several chunks and a real top-level merge.
    let o = run_ok(&[
        "convert",
        s(&las),
        "-o",
        s(&ds),
        "--memory-limit",
        "64MiB",
        "--stats",
        s(&dir.path().join("st.json")),
    ]);
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("st.json")).expect("stats"))
            .expect("json");
    assert!(
        stats["chunks"].as_u64().unwrap_or(0) >= 4,
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    run_ok(&["verify", s(&ds)]);
    run_ok(&["export", s(&ds), "-o", s(&out)]);
    assert!(las_multiset(&las) == las_multiset(&out));
}

/// Many more threads than a small memory limit has room for: the chunks' floor and the
/// distribution's blocks must not multiply by the thread count (159 MB at 64 threads under a
/// 64 MiB limit before the workers were bounded by memory), and the dataset is the same.
#[test]
fn many_threads_stay_near_a_small_memory_limit() {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = dir.path().join("city.las");
    run_ok(&["synth", "--points", "1.5M", "-o", s(&las), "--seed", "1"]);
    let convert = |threads: &str| {
        let (ds, st) = (
            dir.path().join(threads),
            dir.path().join(format!("{threads}.json")),
        );
        let limit = ["--memory-limit", "64MiB", "--threads", threads];
        run_ok(
            &[
                &["convert", s(&las), "-o", s(&ds), "-q", "--stats", s(&st)][..],
                &limit,
            ]
            .concat(),
        );
        let stats: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&st).expect("stats")).expect("json");
        let octree = std::fs::read(ds.join("octree.bin")).expect("octree");
        (
            stats["peak_memory_bytes"].as_u64().unwrap_or(u64::MAX),
            octree,
        )
    };
    let (_, two) = convert("2");
    let (peak, many) = convert("64");
    assert!(two == many, "64 threads built another octree than 2");
    assert!(
        peak < 96 << 20,
        "64 threads peaked at {peak} bytes under a 64 MiB limit"
    );
}

/// Header bounds that miss some points (a real fault of some writers): the converter must
/// notice, measure the bounds itself, keep every point and say so.
#[test]
fn wrong_header_bounds_are_measured_instead() {
    let dir = tempfile::tempdir().expect("tempdir");
    for ext in ["las", "laz"] {
        let src = dir.path().join(format!("city.{ext}"));
        run_ok(&["synth", "--points", "50000", "-o", s(&src), "--seed", "3"]);
        let mut bytes = std::fs::read(&src).expect("read");
        // LAS header: max and min of x, y, z as f64 pairs from byte 179. Claim a box far
        // smaller than the points', so that the cube chosen from it cannot hold them.
        let f = |b: &[u8], o: usize| f64::from_le_bytes(b[o..o + 8].try_into().expect("8"));
        let max_x = f(&bytes, 179);
        for axis in 0..3 {
            let at = 179 + 16 * axis;
            let (max, min) = (f(&bytes, at), f(&bytes, at + 8));
            let narrow = min + (max - min) / 1000.0;
            bytes[at..at + 8].copy_from_slice(&narrow.to_le_bytes());
        }
        std::fs::write(&src, &bytes).expect("write");
        let ds = dir.path().join(format!("ds_{ext}"));
        let out = dir.path().join(format!("back_{ext}.las"));
        let o = run_ok(&["convert", s(&src), "-o", s(&ds)]);
        let said =
            String::from_utf8_lossy(&o.stderr).to_string() + &String::from_utf8_lossy(&o.stdout);
        assert!(
            said.contains("outside the bounds the header declares"),
            "{said}"
        );
        run_ok(&["verify", s(&ds)]);
        run_ok(&["export", s(&ds), "-o", s(&out)]);
        assert!(las_multiset(&src) == las_multiset(&out), "{ext}");
        let info = run_ok(&["info", s(&ds), "--json"]);
        let info: serde_json::Value = serde_json::from_slice(&info.stdout).expect("json");
        let real_max = info["bounds"]["max"][0].as_f64().unwrap_or(0.0);
        assert!((real_max - max_x).abs() < 0.01, "{real_max} vs {max_x}");
    }
}

#[test]
fn autzen_las_and_laz_give_identical_datasets() {
    let dir = tempfile::tempdir().expect("tempdir");
    let a = dir.path().join("a");
    let b = dir.path().join("b");
    run_ok(&["convert", s(&data("autzen_trim.las")), "-o", s(&a), "-q"]);
    run_ok(&["convert", s(&data("autzen_trim.laz")), "-o", s(&b), "-q"]);
    for f in ["octree.bin", "hierarchy.bin"] {
        assert!(
            std::fs::read(a.join(f)).ok() == std::fs::read(b.join(f)).ok(),
            "{f} differs"
        );
    }
    let meta = |p: &std::path::Path| {
        let mut v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(p.join("metadata.json")).expect("metadata"))
                .expect("json");
        v["sources"] = serde_json::Value::Null;
        v
    };
    assert_eq!(meta(&a), meta(&b));
}

#[test]
fn far_from_origin_coordinates_keep_their_precision() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("ds");
    let out = dir.path().join("out.ply");
    let src = data("autzen_trim.las");
    run_ok(&["convert", s(&src), "-o", s(&ds), "-q"]);
    run_ok(&["export", s(&ds), "-o", s(&out)]);
    // Compare real coordinates, exported as doubles, to the input's.
    let mut a = read_xyz(&src);
    let mut b = read_xyz(&out);
    assert_eq!(a.len(), b.len());
    assert!(a[0][0] > 600_000.0, "autzen lies far from the origin");
    let key = |p: &[f64; 3]| (p[0].to_bits(), p[1].to_bits(), p[2].to_bits());
    a.sort_by_key(key);
    b.sort_by_key(key);
    let half = las_scale(&src)[0] / 2.0;
    for (p, q) in a.iter().zip(&b) {
        for k in 0..3 {
            assert!((p[k] - q[k]).abs() <= half, "{p:?} vs {q:?}");
        }
    }
}

fn read_xyz(path: &std::path::Path) -> Vec<[f64; 3]> {
    read_all(path).0
}

/// Reads positions and attribute rows of any input through Strata's readers.
fn read_all(path: &std::path::Path) -> (Vec<[f64; 3]>, Vec<u8>, usize, Vec<String>) {
    let mut src = open_source(path).expect("opens");
    let names = src
        .info()
        .attributes
        .iter()
        .map(|a| a.name.clone())
        .collect();
    let row_len = src.info().row_len();
    let mut xyz = Vec::new();
    let mut rows = Vec::new();
    while src.read(1 << 16, &mut xyz, &mut rows).expect("reads") > 0 {}
    (xyz, rows, row_len, names)
}

fn ply_round_trip(input: &str) {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("ds");
    let out = dir.path().join("out.ply");
    let src = data(input);
    run_ok(&["convert", s(&src), "-o", s(&ds), "-q"]);
    run_ok(&["verify", s(&ds)]);
    run_ok(&["export", s(&ds), "-o", s(&out)]);
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(ds.join("metadata.json")).expect("metadata"))
            .expect("json");
    let scale: Vec<f64> = (0..3)
        .map(|k| meta["scale"][k].as_f64().expect("scale"))
        .collect();
    // The bunny's axes reach 0.11 and 0.19, which single precision holds to 1e-9 and 1e-8:
    // both are stored in the finer, or the octree's cubes would be boxes ten times taller.
    assert!(
        scale.iter().all(|&k| k == scale[0]),
        "{input}: one step on every axis, not {scale:?}"
    );
    let (a, ra, la, na) = read_all(&src);
    let (b, rb, lb, nb) = read_all(&out);
    assert_eq!(na, nb, "attribute names");
    assert_eq!(la, lb);
    assert_eq!(a.len(), b.len());
    // Quantize both sides to the dataset grid and compare (position, attributes) multisets.
    let keyed = |xyz: &[[f64; 3]], rows: &[u8], len: usize| {
        let mut v: Vec<(i64, i64, i64, Vec<u8>)> = xyz
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let q = |k: usize| {
                    ((p[k] - meta["offset"][k].as_f64().unwrap_or(0.0)) / scale[k]).round() as i64
                };
                (q(0), q(1), q(2), rows[i * len..(i + 1) * len].to_vec())
            })
            .collect();
        v.sort_unstable();
        v
    };
    let (ka, kb) = (keyed(&a, &ra, la), keyed(&b, &rb, lb));
    let first_diff = ka.iter().zip(&kb).position(|(x, y)| x != y);
    assert!(
        first_diff.is_none(),
        "{input}: points differ after round trip, first at sorted index {first_diff:?}: {:?} vs {:?}",
        first_diff.map(|i| &ka[i]),
        first_diff.map(|i| &kb[i])
    );
    // The dataset grid is below the float32 resolution of the input: no precision lost.
    for (k, sk) in scale.iter().enumerate() {
        let max = a.iter().fold(0f64, |m, p| m.max(p[k].abs())) as f32;
        assert!(
            *sk <= (max.next_up() - max) as f64,
            "axis {k}: scale {sk} is coarser than the input's float32 step"
        );
    }
}

#[test]
fn bunny_range_scans_round_trip() {
    ply_round_trip("bunny_range_scans_merged.ply");
}

#[test]
fn bunny_mesh_vertices_round_trip() {
    ply_round_trip("bunny_bun_zipper.ply");
}

#[test]
fn several_inputs_make_one_dataset_with_the_union_of_attributes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("ds");
    let out = dir.path().join("out.las");
    let a = data("autzen_trim.las");
    let b = data("autzen_trim_pf7.las");
    run_ok(&["convert", s(&a), s(&b), "-o", s(&ds), "-q"]);
    let info = run_ok(&["info", s(&ds), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&info.stdout).expect("json");
    assert_eq!(v["points"], 220000);
    let names = common::attribute_names(&v);
    assert!(
        names.contains(&"scan_angle_rank")
            && names.contains(&"scan_angle")
            && names.contains(&"scanner_channel")
    );
    run_ok(&["export", s(&ds), "-o", s(&out)]);
    assert_eq!(las_multiset(&out).len(), 220000);
}

#[test]
fn info_json_has_the_promised_fields() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("ds");
    run_ok(&["convert", s(&data("autzen_trim.laz")), "-o", s(&ds), "-q"]);
    let o = run_ok(&["info", s(&ds), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["points"], 110000);
    assert!(v["nodes"].as_u64().unwrap_or(0) > 1);
    assert!(v["depth"].as_u64().unwrap_or(0) >= 1);
    assert!(v["bounds"]["min"][0].as_f64().unwrap_or(0.0) > 636000.0);
    assert!(
        v["attributes"]
            .as_array()
            .is_some_and(|a| a.iter().any(|x| x["name"] == "rgb"))
    );
}

#[test]
fn a_reader_that_stops_early_ends_info_quietly() {
    // `strata info DS | head -1`: the pipe closes before info has written everything.
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("ds");
    run_ok(&["convert", s(&data("autzen_trim.laz")), "-o", s(&ds), "-q"]);
    let mut child = common::strata()
        .args(["info", s(&ds)])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("strata runs");
    // Close the reading end at once: every write of info meets a closed pipe.
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("strata ends");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// A LAS file of one point in format 1 whose GPS times are `time` (global encoding bit 0).
fn timed_las(path: &std::path::Path, time: las::GpsTimeType, t: f64) {
    let mut builder = las::Builder::from((1, 4));
    builder.point_format = las::point::Format::new(1).expect("format");
    builder.gps_time_type = time;
    let header = builder.into_header().expect("header");
    let mut writer = las::Writer::from_path(path, header).expect("writer");
    writer
        .write_point(las::Point {
            gps_time: Some(t),
            ..Default::default()
        })
        .expect("write");
    writer.close().expect("close");
}

/// Adjusted standard GPS times came back labelled GPS week time (global encoding bit 0 was
/// dropped), and a merge mixed the two time bases without a word.
#[test]
fn the_gps_time_base_survives_and_two_are_never_merged() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (adjusted, week, ds) = (
        dir.path().join("adjusted.las"),
        dir.path().join("week.las"),
        dir.path().join("ds"),
    );
    timed_las(&adjusted, las::GpsTimeType::Standard, 3e8);
    timed_las(&week, las::GpsTimeType::Week, 86400.5);
    run_ok(&["convert", s(&adjusted), "-o", s(&ds), "-q"]);
    let info = String::from_utf8_lossy(&run_ok(&["info", s(&ds)]).stdout).to_string();
    assert!(info.contains("adjusted standard GPS time"), "{info}");
    for name in ["out.las", "out.laz", "out.copc.laz"] {
        let out = dir.path().join(name);
        run_ok(&["export", s(&ds), "-o", s(&out)]);
        let reader = las::Reader::from_path(&out).expect("read export");
        assert_eq!(
            reader.header().gps_time_type(),
            las::GpsTimeType::Standard,
            "{name}"
        );
    }
    let week_ds = dir.path().join("week_ds");
    run_ok(&["convert", s(&week), "-o", s(&week_ds), "-q"]);
    let out = dir.path().join("week_out.las");
    run_ok(&["export", s(&week_ds), "-o", s(&out)]);
    let reader = las::Reader::from_path(&out).expect("read export");
    assert_eq!(reader.header().gps_time_type(), las::GpsTimeType::Week);
    refused(
        &[
            "convert",
            s(&adjusted),
            s(&week),
            "-o",
            s(&dir.path().join("mixed")),
        ],
        &["week.las: its \"gps_time\" is GPS week time but adjusted standard GPS time in"],
    );
}

/// Waveform packets (their descriptors and data) are not kept: said, as the points keep wave
/// packet fields that then refer to nothing.
#[test]
fn waveform_packets_left_behind_are_said() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (input, ds) = (dir.path().join("wave.las"), dir.path().join("ds"));
    let mut builder = las::Builder::from((1, 4));
    builder.point_format = las::point::Format::new(4).expect("format");
    builder.vlrs.push(las::Vlr {
        user_id: "LASF_Spec".into(),
        record_id: 100,
        description: "wave packet descriptor".into(),
        data: vec![0; 26],
    });
    let header = builder.into_header().expect("header");
    let mut writer = las::Writer::from_path(&input, header).expect("writer");
    writer
        .write_point(las::Point {
            gps_time: Some(1.0),
            waveform: Some(las::raw::point::Waveform {
                wave_packet_descriptor_index: 1,
                ..Default::default()
            }),
            ..Default::default()
        })
        .expect("write");
    writer.close().expect("close");
    let o = run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("wave.las: its waveform data is not kept"),
        "{err}"
    );
}

/// A legacy input's scan angle (whole degrees) merged with a format 6 input's (steps of
/// 0.006°): the legacy points came out of a format 6 export with a scan angle of 0, their real
/// one in an extra field. Each point now has both forms.
#[test]
fn scan_angles_of_legacy_and_extended_inputs_merge_into_one_field() {
    let dir = tempfile::tempdir().expect("tempdir");
    let write = |name: &str, format: u8, x: f64, angle: f32| {
        let path = dir.path().join(name);
        let mut builder = las::Builder::from((1, 4));
        builder.point_format = las::point::Format::new(format).expect("format");
        let header = builder.into_header().expect("header");
        let mut writer = las::Writer::from_path(&path, header).expect("writer");
        writer
            .write_point(las::Point {
                x,
                scan_angle: angle,
                gps_time: Some(0.0),
                return_number: 1,
                number_of_returns: 1,
                ..Default::default()
            })
            .expect("write");
        writer.close().expect("close");
        path
    };
    let legacy = write("legacy.las", 1, 0.0, 52.0);
    let extended = write("extended.las", 6, 1.0, -30.0);
    let ds = dir.path().join("ds");
    run_ok(&["convert", s(&legacy), s(&extended), "-o", s(&ds), "-q"]);
    let out = dir.path().join("out.las");
    run_ok(&["export", s(&ds), "-o", s(&out)]);
    let mut reader = las::Reader::from_path(&out).expect("read export");
    let mut got: Vec<(i64, f32)> = reader
        .read_all()
        .expect("all points")
        .points()
        .map(|p| {
            let p = p.expect("point");
            (p.x.round() as i64, p.scan_angle)
        })
        .collect();
    got.sort_by_key(|g| g.0);
    assert_eq!(got.len(), 2);
    assert!(
        (got[0].1 - 52.0).abs() < 0.01,
        "the legacy point's angle: {got:?}"
    );
    assert!(
        (got[1].1 + 30.0).abs() < 0.01,
        "the extended point's angle: {got:?}"
    );
}
