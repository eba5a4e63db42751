//! Potree 2.0 export's attributes as Potree reads them: colour as 3 x uint16, normals as
//! NormalX/Y/Z floats whatever their stored type, one attribute per name, and 64-bit integers
//! only where a double holds them exactly.

mod common;
use common::*;
use serde_json::Value;
use std::path::Path;

/// Converts the PLY `text` and exports it as Potree 2.0; returns metadata.json and the
/// records of octree.bin (a dataset this small is one node).
fn potree_of(dir: &Path, tag: &str, text: &str) -> (Value, Vec<u8>) {
    let (input, ds, out) = (
        dir.join(format!("{tag}.ply")),
        dir.join(format!("{tag}.strata")),
        dir.join(format!("{tag}_p2")),
    );
    std::fs::write(&input, text).expect("write ply");
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    run_ok(&["export", s(&ds), "-o", s(&out), "--format", "potree2"]);
    let meta: Value =
        serde_json::from_slice(&std::fs::read(out.join("metadata.json")).expect("read"))
            .expect("metadata.json is JSON");
    (
        meta,
        std::fs::read(out.join("octree.bin")).expect("octree.bin"),
    )
}

/// Each attribute's (name, type, numElements) and byte offset in a record.
fn attributes(meta: &Value) -> Vec<(String, String, u64, usize)> {
    let mut at = 0;
    meta["attributes"]
        .as_array()
        .expect("attributes")
        .iter()
        .map(|a| {
            let row = (
                a["name"].as_str().expect("name").to_string(),
                a["type"].as_str().expect("type").to_string(),
                a["numElements"].as_u64().expect("numElements"),
                at,
            );
            at += a["size"].as_u64().expect("size") as usize;
            row
        })
        .collect()
}

/// 8-bit colour goes out as Potree's 3 x uint16, times 257; Potree's decoder reads rgb as
/// uint16 whatever the metadata says, so 8-bit values were read two at a time.
#[test]
fn eight_bit_colour_goes_out_as_uint16() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (meta, octree) = potree_of(
        dir.path(),
        "c8",
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n0 0 0 255 128 1\n",
    );
    let attrs = attributes(&meta);
    let rgb = attrs.iter().find(|a| a.0 == "rgb").expect("rgb");
    assert_eq!((rgb.1.as_str(), rgb.2), ("uint16", 3), "{attrs:?}");
    let c: Vec<u16> = (0..3)
        .map(|k| u16::from_le_bytes([octree[rgb.3 + 2 * k], octree[rgb.3 + 2 * k + 1]]))
        .collect();
    assert_eq!(c, [65535, 128 * 257, 257]);
}

/// A normal of doubles goes out as NormalX/Y/Z floats, as f32 and estimated ones do; it went
/// out as one `normal` of three doubles, which Potree reads as floats.
#[test]
fn double_normals_go_out_as_normal_xyz_floats() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (meta, octree) = potree_of(
        dir.path(),
        "dn",
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty double x\nproperty double y\nproperty double z\nproperty double nx\nproperty double ny\nproperty double nz\nend_header\n0 0 0 0.6 0.8 0\n",
    );
    let attrs = attributes(&meta);
    let shapes: Vec<(&str, &str, u64)> = attrs
        .iter()
        .map(|a| (a.0.as_str(), a.1.as_str(), a.2))
        .collect();
    assert_eq!(
        shapes,
        [
            ("position", "int32", 3),
            ("NormalX", "float", 1),
            ("NormalY", "float", 1),
            ("NormalZ", "float", 1),
        ]
    );
    let n: Vec<f32> = attrs[1..]
        .iter()
        .map(|a| f32::from_le_bytes(octree[a.3..a.3 + 4].try_into().expect("4 bytes")))
        .collect();
    assert_eq!(n, [0.6, 0.8, 0.0]);
}

/// An attribute whose Potree name another has (a `gps-time` beside the GPS time, Potree's
/// `gps-time`) gets a number, as PLY export's properties do; the real one keeps the name.
#[test]
fn names_potree_gives_twice_are_numbered() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (meta, octree) = potree_of(
        dir.path(),
        "names",
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty double gps-time\nproperty double gps_time\nend_header\n0 0 0 7 1.5\n",
    );
    let attrs = attributes(&meta);
    let names: Vec<&str> = attrs.iter().map(|a| a.0.as_str()).collect();
    assert_eq!(names, ["position", "gps-time_1", "gps-time"]);
    let value = |a: &(String, String, u64, usize)| {
        f64::from_le_bytes(octree[a.3..a.3 + 8].try_into().expect("8 bytes"))
    };
    assert_eq!((value(&attrs[1]), value(&attrs[2])), (7.0, 1.5));
}

/// A 64-bit integer a double would round is refused, as PLY export refuses it; 993 of 1000
/// such values went out changed.
#[test]
fn a_64_bit_integer_a_double_cannot_hold_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (input, ds) = (dir.path().join("serial.las"), dir.path().join("ds"));
    let big = (1u64 << 53) + 1;
    serial_las(&input, &[([0.0; 3], 12345), ([1.0, 0.0, 0.0], big)]);
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    let out = dir.path().join("p2");
    let err = refused(
        &["export", s(&ds), "-o", s(&out), "--format", "potree2"],
        &[
            "serial is 9007199254740993 (point ",
            "no Potree 2.0 attribute holds exactly",
            "export to .las",
        ],
    );
    // (A warning may come before it: Potree 2.0 has no place for the times' base.)
    let errors = err.lines().filter(|l| l.starts_with("error:")).count();
    assert_eq!(errors, 1, "one sentence: {err}");
    assert!(!out.exists() && !dir.path().join("p2.part").exists());
    // Within 2^53: exact, as doubles.
    let (input, ds) = (dir.path().join("small.las"), dir.path().join("small"));
    serial_las(&input, &[([0.0; 3], 12345), ([1.0, 0.0, 0.0], 1 << 53)]);
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    run_ok(&["export", s(&ds), "-o", s(&out), "--format", "potree2"]);
}

#[test]
fn a_second_conversion_into_one_potree2_output_is_refused_through_its_export() {
    // The first run, as the second sees it: it holds the output's lock (through its export,
    // when it no longer holds the hidden Strata dataset's).
    let dir = tempfile::tempdir().expect("tempdir");
    let las = dir.path().join("city.las");
    common::run_ok(&["synth", "--points", "20k", "-o", s(&las)]);
    let out = dir.path().join("p2");
    let first = strata_converter::workdir::WorkDir::for_output(&out)
        .lock_only(&out)
        .expect("first lock");
    let o = common::run(&["convert", s(&las), "-o", s(&out), "--format", "potree2"]);
    assert!(!o.status.success());
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(
        said.contains("is being written by another conversion"),
        "{said}"
    );
    assert!(!out.exists());
    drop(first);
    common::run_ok(&[
        "convert",
        s(&las),
        "-o",
        s(&out),
        "--format",
        "potree2",
        "-q",
    ]);
    assert!(out.join("metadata.json").is_file());
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .expect("list")
        .map(|e| e.expect("entry").file_name())
        .collect();
    assert_eq!(
        left.len(),
        2,
        "nothing beside the input and the output: {left:?}"
    );
}

/// A float attribute's range in metadata.json is that of its finite values: Potree scales
/// colours by it, and an infinity went out as null, which is no number. One with none finite
/// gets 0 to 0.
#[test]
fn float_ranges_leave_out_nan_and_infinities() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (meta, _) = potree_of(
        dir.path(),
        "nf",
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty float quality\nproperty float unknown\nend_header\n0 0 0 1.5 nan\n1 0 0 inf nan\n0 1 0 -inf nan\n0 0 1 -2 nan\n",
    );
    let range = |name: &str| {
        let a = meta["attributes"]
            .as_array()
            .expect("attributes")
            .iter()
            .find(|a| a["name"] == name)
            .unwrap_or_else(|| panic!("{name} in {meta}"));
        (a["min"][0].as_f64(), a["max"][0].as_f64())
    };
    assert_eq!(range("quality"), (Some(-2.0), Some(1.5)));
    assert_eq!(range("unknown"), (Some(0.0), Some(0.0)));
}
