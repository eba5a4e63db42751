//! Filters on values the GPU's attribute word cannot hold as they are: a float intensity, a
//! 16-bit class, a return number above 15. The word packed them into 16, 8 and 4 bits, and a
//! filter compared the packed value (intensity 0.3 as 0, class 258 as 2, return 200 as 15); the
//! loader now compares them exact. Also: elevation bounds as exact as the points' positions,
//! intensity bounds between whole numbers, and filters on attributes the points lack refused,
//! as are classes of which the dataset holds no point.

mod common;

use common::{gpu_run, run_ok, s};
use std::path::{Path, PathBuf};

const COLUMNS: usize = 200;
const ROWS: usize = 20;

/// A PLY of 200 columns by 20 rows, whose values depend on the column `i` alone: intensity of
/// type `intensity_type` (`float`: i / 200, but 70000 in column 199 and NaN in 198; `ushort`:
/// 300 i), class 2 i (a ushort, so 258 in column 129), return number i (a uchar) and height
/// 100 + i / 1000 m, 3 km higher from column 100 on (millimetres at a height where f32 steps
/// are a quarter of one).
fn write_ply(path: &Path, intensity_type: &str) {
    let mut body = Vec::new();
    for i in 0..COLUMNS {
        for j in 0..ROWS {
            let z = 100.0 + i as f64 * 0.001 + if i >= 100 { 3000.0 } else { 0.0 };
            for v in [500_000.0 + i as f64, 4_600_000.0 + j as f64, z] {
                body.extend_from_slice(&f64::to_le_bytes(v));
            }
            if intensity_type == "float" {
                let v = match i {
                    199 => 70000.0,
                    198 => f32::NAN,
                    _ => i as f32 * 0.005,
                };
                body.extend_from_slice(&v.to_le_bytes());
            } else {
                body.extend_from_slice(&(i as u16 * 300).to_le_bytes());
            }
            body.extend_from_slice(&(i as u16 * 2).to_le_bytes());
            body.push(i as u8);
        }
    }
    let header = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty double x\n\
         property double y\nproperty double z\nproperty {intensity_type} intensity\n\
         property ushort classification\nproperty uchar return_number\nend_header\n",
        COLUMNS * ROWS
    );
    let mut bytes = header.into_bytes();
    bytes.extend_from_slice(&body);
    std::fs::write(path, bytes).expect("write ply");
}

fn dataset(intensity_type: &str) -> PathBuf {
    let dir = common::fresh_dir(&format!("filter-values-{intensity_type}"));
    let ply = dir.join("grid.ply");
    write_ply(&ply, intensity_type);
    let ds = dir.join("grid.strata");
    run_ok(&["convert", s(&ply), "-o", s(&ds), "--quiet"]);
    ds
}

/// The points the filters let through in a view of the whole grid, or the error.
fn drawn(ds: &Path, filters: &[&str]) -> Result<u64, String> {
    let image = ds.with_file_name("view.png");
    let stats = ds.with_file_name("view.json");
    let mut args = vec!["render", s(ds), "-o", s(&image), "--size", "160x120"];
    args.extend_from_slice(&["--wait-complete", "--stats", s(&stats)]);
    args.extend_from_slice(filters);
    let out = gpu_run(&args);
    if !out.status.success() {
        return Err(String::from_utf8_lossy(&out.stderr).into_owned());
    }
    let text = std::fs::read_to_string(&stats).expect("stats");
    let v: serde_json::Value = serde_json::from_str(&text).expect("json");
    Ok(v["frames"][0]["points_drawn"]
        .as_u64()
        .expect("points_drawn"))
}

fn columns(n: u64) -> u64 {
    n * ROWS as u64
}

#[test]
fn values_the_attribute_word_cannot_hold_are_filtered_exact() {
    let ds = dataset("float");
    assert_eq!(drawn(&ds, &[]), Ok(columns(COLUMNS as u64)));
    let cases: [(&[&str], u64); 8] = [
        // 0.205 (column 41) to 0.5 (column 100).
        (&["--filter", "intensity=0.2025..0.5025"], columns(60)),
        // Not the NaN of column 198.
        (&["--filter", "intensity=0..0.99"], columns(198)),
        (&["--filter", "intensity=70000..70000"], columns(1)),
        (&["--filter", "intensity=65535..65535"], 0),
        // Class 2 is column 1 alone, not also 258 (column 129).
        (&["--classes", "2"], columns(1)),
        // Hiding class 0 leaves 256 (column 128).
        (&["--hide-classes", "0"], columns(COLUMNS as u64 - 1)),
        (&["--filter", "return_number=15..15"], columns(1)),
        (&["--filter", "return_number=14..15"], columns(2)),
    ];
    for (filters, want) in cases {
        assert_eq!(drawn(&ds, filters), Ok(want), "{filters:?}");
    }
}

#[test]
fn elevation_and_intensity_bounds_keep_what_lies_within() {
    let ds = dataset("ushort");
    let cases: [(&[&str], u64); 5] = [
        // One column each, 2 mm apart from their neighbours' heights at most.
        (&["--filter", "elevation=100.05..100.05"], columns(1)),
        (&["--filter", "elevation=3100.15..3100.15"], columns(1)),
        (&["--filter", "elevation=100.0105..100.0195"], columns(9)),
        // Whole intensities: 3000 (column 10) is below 3000.0001.
        (&["--filter", "intensity=3000.0001..6000"], columns(10)),
        (&["--filter", "intensity=3000..5999.9999"], columns(10)),
    ];
    for (filters, want) in cases {
        assert_eq!(drawn(&ds, filters), Ok(want), "{filters:?}");
    }
}

#[test]
fn a_filter_on_what_the_points_lack_is_refused() {
    let dir = common::fresh_dir("filter-values-bare");
    let ply = dir.join("bare.ply");
    let mut bytes = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec();
    bytes.extend_from_slice(b"0 0 0\n1 0 0\n0 1 0\n");
    std::fs::write(&ply, bytes).expect("write");
    let ds = dir.join("bare.strata");
    run_ok(&["convert", s(&ply), "-o", s(&ds), "--quiet"]);
    for (filters, name) in [
        (&["--filter", "intensity=100..900"][..], "intensity"),
        (&["--filter", "intensity=0..0"], "intensity"),
        (&["--filter", "return_number=1..1"], "return_number"),
        (&["--classes", "0"], "classification"),
        (&["--hide-classes", "0"], "classification"),
    ] {
        let err = drawn(&ds, filters).expect_err("a filter on nothing");
        assert!(
            err.contains(&format!(
                "no attribute \"{name}\" to filter on (there are elevation)"
            )),
            "{filters:?}: {err}"
        );
    }
}

/// Classes to show of which the dataset holds no point are refused, naming the ones it has,
/// where a blank image came back with exit 0; one it has among them is drawn.
#[test]
fn classes_the_dataset_has_no_point_of_are_refused() {
    let dir = common::fresh_dir("filter-values-classes");
    let las = dir.join("city.las");
    run_ok(&["synth", "--points", "20k", "-o", s(&las)]);
    let ds = dir.join("city.strata");
    run_ok(&["convert", s(&las), "-o", s(&ds), "--quiet"]);
    let err = drawn(&ds, &["--classes", "1,3"]).expect_err("classes of no point");
    assert!(
        err.contains("no point has a class the filter shows")
            && err.contains("classes are 2, 5, 6"),
        "{err}"
    );
    assert!(drawn(&ds, &["--classes", "1,6"]).is_ok_and(|n| n > 0));
}
