//! E57 input: every scan of a file comes out once, in world coordinates, with colour and
//! intensity scaled to 16 bits and the scanner that took it; compared with the `e57` crate's
//! own reading of the file. Malformed files are refused in one sentence.

mod common;
#[path = "e57/extras.rs"]
mod extras;
#[path = "e57/malformed.rs"]
mod malformed;
#[path = "e57/ranges.rs"]
mod ranges;
#[path = "e57/sections.rs"]
mod sections;
#[path = "e57/write.rs"]
mod write;

use common::*;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use strata_format::{LocalDataset, Metadata};
use write::{CratePoint, ScanSpec, Storage, crate_points, pose, world, write_e57};

/// A stored point: integer position and the values of `scanner`, `rgb`, `intensity` (those the
/// dataset has, in that order).
type Key = ([i64; 3], Vec<u16>);

/// Every point of a dataset, and its metadata.
fn stored(ds: &Path) -> (Metadata, Vec<Key>) {
    let d = LocalDataset::open(ds).expect("dataset opens");
    let layout = d.layout().clone();
    let fields: Vec<(usize, usize)> = [("scanner", 1), ("rgb", 3), ("intensity", 1)]
        .iter()
        .filter_map(|&(n, c)| layout.index_of(n).map(|i| (layout.offsets[i], c)))
        .collect();
    let mut out = Vec::new();
    for node in d.all_nodes().expect("nodes") {
        let rows = d.read_node(&node).expect("node").to_rows(&layout);
        for r in rows.chunks_exact(layout.stride) {
            let i32_at = |o: usize| i32::from_le_bytes([r[o], r[o + 1], r[o + 2], r[o + 3]]);
            let u16_at = |o: usize| u16::from_le_bytes([r[o], r[o + 1]]);
            let tags = fields
                .iter()
                .flat_map(|&(o, c)| (0..c).map(move |k| o + 2 * k))
                .map(u16_at)
                .collect();
            out.push(([i32_at(0), i32_at(4), i32_at(8)].map(i64::from), tags));
        }
    }
    (d.metadata().clone(), out)
}

/// The tags `stored` gives a crate point of scan `base + scan`.
fn tags(meta: &Metadata, p: &CratePoint, base: usize) -> Vec<u16> {
    let has = |n: &str| meta.attributes.iter().any(|a| a.name == n);
    let mut t = vec![(base + p.scan) as u16];
    if has("rgb") {
        t.extend(p.rgb.unwrap_or([0; 3]));
    }
    if has("intensity") {
        t.push(p.intensity.unwrap_or(0));
    }
    t
}

/// Every expected point matches one stored point with the same tags, at the same integer
/// position or one step away (the converter and the crate apply a pose each in its own
/// floating-point order), and nothing else is stored.
fn assert_same_points(meta: &Metadata, stored: &[Key], expected: &[([f64; 3], Vec<u16>)]) {
    assert_eq!(stored.len(), expected.len(), "point count");
    let mut left: HashMap<&Key, usize> = HashMap::new();
    for k in stored {
        *left.entry(k).or_default() += 1;
    }
    let q =
        |p: [f64; 3]| [0, 1, 2].map(|a| ((p[a] - meta.offset[a]) / meta.scale[a]).round() as i64);
    let mut take = |k: &Key| match left.get_mut(k) {
        Some(n) if *n > 0 => {
            *n -= 1;
            true
        }
        _ => false,
    };
    let mut near = Vec::new();
    for (p, t) in expected {
        if !take(&(q(*p), t.clone())) {
            near.push((*p, t.clone()));
        }
    }
    for (p, t) in near {
        let c = q(p);
        let found = (0..27).any(|n| {
            let d = [n / 9 - 1, n / 3 % 3 - 1, n % 3 - 1];
            take(&([0, 1, 2].map(|a| c[a] + d[a]), t.clone()))
        });
        assert!(found, "{p:?} (tags {t:?}) is not stored within one step");
    }
}

/// Converts `inputs` into a fresh dataset under `dir`.
fn convert(dir: &Path, inputs: &[&Path]) -> PathBuf {
    let ds = dir.join("ds");
    let mut args = vec!["convert"];
    args.extend(inputs.iter().map(|p| s(p)));
    args.extend(["-o", s(&ds), "--quiet"]);
    run_ok(&args);
    run_ok(&["verify", s(&ds)]);
    ds
}

/// Converting a shared E57 file stores exactly the crate's valid points. Where the file says
/// where its scanner stood (`stood`: spherical coordinates, or a pose) the points name it;
/// Cartesian points without a pose name none.
fn shared_file(name: &str, coloured: bool, stood: bool) {
    let dir = tempfile::tempdir().expect("tempdir");
    let input = data(name);
    let ds = convert(dir.path(), &[&input]);
    let (meta, got) = stored(&ds);
    let expected: Vec<_> = crate_points(&input)
        .iter()
        .map(|p| {
            let mut t = tags(&meta, p, 0);
            if !stood {
                t[0] = u16::MAX;
            }
            (p.position, t)
        })
        .collect();
    assert!(!expected.is_empty());
    assert_same_points(&meta, &got, &expected);
    let has_rgb = meta
        .attributes
        .iter()
        .any(|a| a.name == "rgb" && a.count == 3 && a.ty.name() == "u16");
    assert_eq!(has_rgb, coloured, "{name}: rgb attribute");
    let sources: Vec<&str> = meta.scanners.iter().map(|s| s.source.as_str()).collect();
    assert_eq!(sources, if stood { vec![name] } else { vec![] });
}

#[test]
fn e57_scaled_integer_bunny_converts_exactly() {
    shared_file("e57_bunnyInt21.e57", false, false);
}

#[test]
fn e57_spherical_scan_converts_its_valid_points() {
    shared_file("e57_tiny_spherical.e57", false, true);
}

#[test]
fn e57_float_rgb_scan_keeps_its_colour() {
    shared_file("e57_tinyCartesianFloatRgb.e57", true, false);
}

pub(crate) fn three_scans() -> Vec<ScanSpec> {
    let mut a = ScanSpec::new(Storage::Double, 3000)
        .rotated([0.0, 0.0, 1.0], 30.0)
        .at([10.0, -5.0, 2.0]);
    a.colour = true;
    let mut b = ScanSpec::new(Storage::Scaled, 2500)
        .rotated([1.0, 2.0, 0.5], 75.0)
        .at([-20.0, 7.0, 1.5]);
    b.intensity = true;
    b.invalid_every = Some(7);
    let mut c = ScanSpec::new(Storage::Spherical, 2000)
        .rotated([0.3, -1.0, 0.2], -140.0)
        .at([3.0, 3.0, 30.0]);
    c.colour = true;
    c.invalid_every = Some(11);
    vec![a, b, c]
}

#[test]
fn e57_scans_with_poses_come_out_in_world_coordinates_with_their_scanner() {
    let dir = tempfile::tempdir().expect("tempdir");
    let input = dir.path().join("site.e57");
    let specs = three_scans();
    let local = write_e57(&input, &specs);
    let read = crate_points(&input);
    // The crate's reading is the poses applied to what was written: world coordinates.
    let mine: Vec<[f64; 3]> = specs
        .iter()
        .zip(&local)
        .flat_map(|(spec, pts)| pts.iter().map(|p| world(spec, *p)))
        .collect();
    assert_eq!(read.len(), mine.len());
    for (r, m) in read.iter().zip(&mine) {
        for a in 0..3 {
            assert!((r.position[a] - m[a]).abs() < 1e-9, "{r:?} vs {m:?}");
        }
    }
    let ds = convert(dir.path(), &[&input]);
    let (meta, got) = stored(&ds);
    let expected: Vec<_> = read
        .iter()
        .map(|p| (p.position, tags(&meta, p, 0)))
        .collect();
    assert_same_points(&meta, &got, &expected);
    // Each scan's points carry its index.
    for scan in 0..3u16 {
        let n = got.iter().filter(|(_, t)| t[0] == scan).count();
        assert_eq!(n, local[scan as usize].len(), "points of scan {scan}");
    }
    let names: Vec<&str> = meta.attributes.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(names, ["rgb", "intensity", "scanner"]);
    let positions: Vec<[f64; 3]> = meta.scanners.iter().map(|s| s.position).collect();
    let translations: Vec<[f64; 3]> = specs.iter().map(|s| s.translation).collect();
    assert_eq!(positions, translations);
    assert!(meta.scanners.iter().all(|s| s.source == "site.e57"));
    // Every scan's points lie around its scanner (a wrong pose would move them away).
    for (scan, spec) in specs.iter().enumerate() {
        let far = read
            .iter()
            .filter(|p| p.scan == scan)
            .map(|p| {
                (0..3)
                    .map(|a| (p.position[a] - spec.translation[a]).powi(2))
                    .sum::<f64>()
            })
            .fold(0.0, f64::max);
        assert!(
            far.sqrt() < 10.0,
            "scan {scan} lies {} from its scanner",
            far.sqrt()
        );
    }
    let info = run_ok(&["info", s(&ds), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&info.stdout).expect("json");
    assert_eq!(v["scanners"][2]["position"][2], 30.0);
}

#[test]
fn two_e57_inputs_number_their_scanners_globally() {
    let dir = tempfile::tempdir().expect("tempdir");
    let specs = three_scans();
    let (a, b) = (dir.path().join("a.e57"), dir.path().join("b.e57"));
    write_e57(&a, &specs[..2]);
    write_e57(&b, &specs[2..]);
    let ds = convert(dir.path(), &[&a, &b]);
    let (meta, got) = stored(&ds);
    let mut expected: Vec<_> = crate_points(&a)
        .iter()
        .map(|p| (p.position, tags(&meta, p, 0)))
        .collect();
    expected.extend(
        crate_points(&b)
            .iter()
            .map(|p| (p.position, tags(&meta, p, 2))),
    );
    assert_same_points(&meta, &got, &expected);
    let listed: Vec<(&str, [f64; 3])> = meta
        .scanners
        .iter()
        .map(|s| (s.source.as_str(), s.position))
        .collect();
    assert_eq!(
        listed,
        [
            ("a.e57", specs[0].translation),
            ("a.e57", specs[1].translation),
            ("b.e57", specs[2].translation)
        ]
    );
}

#[test]
fn points_of_inputs_without_scanners_name_none() {
    let dir = tempfile::tempdir().expect("tempdir");
    let e57 = dir.path().join("scan.E57");
    write_e57(&e57, &three_scans()[..1]);
    let las = data("autzen_trim.las");
    let ds = convert(dir.path(), &[&las, &e57]);
    let (meta, got) = stored(&ds);
    let none = got.iter().filter(|(_, t)| t[0] == u16::MAX).count();
    let first = got.iter().filter(|(_, t)| t[0] == 0).count();
    assert_eq!((none, first), (110_000, 3000));
    assert_eq!(meta.scanners.len(), 1);
    assert_eq!(meta.scanners[0].source, "scan.E57");
}

#[test]
fn info_describes_an_e57_file_as_convert_reads_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let input = dir.path().join("site.e57");
    let mut specs = three_scans();
    specs[1].posed = false;
    write_e57(&input, &specs);
    let doc: serde_json::Value =
        serde_json::from_slice(&run_ok(&["info", s(&input), "--json"]).stdout).expect("JSON");
    assert_eq!(doc["kind"], "E57");
    assert_eq!(doc["points"], 3000 + 2500 + 2000);
    assert_eq!(
        attribute_names(&doc),
        ["rgb", "intensity", "scanner"],
        "{doc}"
    );
    // Scan b states no pose: its scanner is not listed.
    let stood: Vec<[f64; 3]> =
        serde_json::from_value(doc["scanners"].clone()).expect("scanner positions");
    assert_eq!(stood, [specs[0].translation, specs[2].translation]);
    let text = String::from_utf8_lossy(&run_ok(&["info", s(&input)]).stdout).to_string();
    assert!(text.contains("points    7500 records"), "{text}");
}

#[test]
fn cartesian_scans_without_a_pose_name_no_scanner() {
    let dir = tempfile::tempdir().expect("tempdir");
    let input = dir.path().join("merged.e57");
    // A Cartesian cloud without a pose between two posed scans: the scanner indices of the
    // others close up (its normals: tests/normals.rs).
    let mut specs = three_scans();
    specs[1].posed = false;
    write_e57(&input, &specs);
    let ds = convert(dir.path(), &[&input]);
    let (meta, got) = stored(&ds);
    let listed: Vec<[f64; 3]> = meta.scanners.iter().map(|s| s.position).collect();
    assert_eq!(listed, [specs[0].translation, specs[2].translation]);
    let count = |tag: u16| got.iter().filter(|(_, t)| t[0] == tag).count();
    // Scan b: 2500 points, every 7th invalid.
    assert_eq!(count(u16::MAX), 2500 - 2500 / 7);
    assert_eq!(count(0), 3000);
    assert_eq!(count(1), 2000 - 2000 / 11);
    assert_eq!(count(2), 0);
}

/// `bytes` written to `name` in `dir`.
pub(crate) fn written(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).expect("write");
    p
}

#[test]
fn an_empty_scan_among_others_keeps_its_scanner() {
    let dir = tempfile::tempdir().expect("tempdir");
    let input = dir.path().join("gap.e57");
    let mut specs = three_scans();
    specs[1].points = 0;
    let local = write_e57(&input, &specs);
    let ds = convert(dir.path(), &[&input]);
    let (meta, got) = stored(&ds);
    assert_eq!(meta.scanners.len(), 3);
    assert!(got.iter().all(|(_, t)| t[0] != 1));
    assert_eq!(
        got.iter().filter(|(_, t)| t[0] == 0).count(),
        local[0].len()
    );
    assert_eq!(
        got.iter().filter(|(_, t)| t[0] == 2).count(),
        local[2].len()
    );
}

/// `b` with its XML section's `from` replaced by `to`, of the same length, and the checksums
/// of the pages it touched repaired (every 1024-byte page ends in a CRC-32C of the rest).
fn xml_replaced(mut b: Vec<u8>, from: &str, to: &str) -> Vec<u8> {
    const PAGE: usize = 1024;
    assert_eq!(from.len(), to.len());
    let u64_at = |o: usize| u64::from_le_bytes(b[o..o + 8].try_into().expect("8 bytes")) as usize;
    let (at, len) = (u64_at(24), u64_at(32));
    // Physical places of the XML's bytes, skipping each page's checksum.
    let places: Vec<usize> = (at..b.len())
        .filter(|p| p % PAGE < PAGE - 4)
        .take(len)
        .collect();
    let xml: Vec<u8> = places.iter().map(|&p| b[p]).collect();
    let start = xml
        .windows(from.len())
        .position(|w| w == from.as_bytes())
        .expect("the text to replace");
    for (i, &c) in to.as_bytes().iter().enumerate() {
        b[places[start + i]] = c;
    }
    for page in (places[start] / PAGE)..=(places[start + to.len() - 1] / PAGE) {
        let p = page * PAGE;
        let crc = e57_crc32c(&b[p..p + PAGE - 4]);
        b[p + PAGE - 4..p + PAGE].copy_from_slice(&crc.to_be_bytes());
    }
    b
}

#[test]
fn an_e57_point_count_beyond_its_file_is_refused_naming_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let b = std::fs::read(data("e57_tinyCartesianFloatRgb.e57")).expect("seed");
    // The indentation before the element gives the count its extra digits.
    let b = xml_replaced(
        b,
        "\n      <points type=\"CompressedVector\" fileOffset=\"48\" recordCount=\"2090\"",
        "\n<points type=\"CompressedVector\" fileOffset=\"48\" recordCount=\"2090000000\"",
    );
    // Repaired, the file still opens: only the count is wrong.
    convert_fails(
        &written(dir.path(), "many.e57", &b),
        "scan 0 of 1 says it holds 2090000000 points, more than a file of 34816 bytes can",
    );
}

#[test]
fn single_precision_scans_far_from_the_origin_keep_their_own_precision() {
    // Singles of ±4 m are good to a micrometre in the scan's frame; its pose puts it 5e6 m
    // away, where a single would be good to half a metre.
    let dir = tempfile::tempdir().expect("tempdir");
    let input = dir.path().join("far.e57");
    let spec = ScanSpec::new(Storage::Single, 3000)
        .rotated([0.0, 0.0, 1.0], 20.0)
        .at([5e6, 4e6, 100.0]);
    write_e57(&input, std::slice::from_ref(&spec));
    assert_stored_finely(dir.path(), &input, "a scan 5e6 away");
}

/// Converting `input` (in `dir`) stores exactly the crate's points, on a micrometre step or
/// finer (`what` names the case).
fn assert_stored_finely(dir: &Path, input: &Path, what: &str) {
    let read = crate_points(input);
    let ds = convert(dir, &[input]);
    let (meta, got) = stored(&ds);
    assert!(
        meta.scale.iter().all(|&s| s <= 1e-6),
        "{what}: scale {:?} is coarser than the singles",
        meta.scale
    );
    let expected: Vec<_> = read
        .iter()
        .map(|p| (p.position, tags(&meta, p, 0)))
        .collect();
    assert_same_points(&meta, &got, &expected);
}

#[test]
fn a_non_finite_coordinate_is_named_where_it_is() {
    let dir = tempfile::tempdir().expect("tempdir");
    let input = dir.path().join("inf.e57");
    let mut w = e57::E57Writer::from_file(&input, "strata-test-inf").expect("writer");
    let prototype = vec![
        e57::Record::CARTESIAN_X_F64,
        e57::Record::CARTESIAN_Y_F64,
        e57::Record::CARTESIAN_Z_F64,
    ];
    let mut pc = w.add_pointcloud("scan", prototype).expect("scan");
    pc.set_transform(Some(pose([1.0, 0.0, 0.0, 0.0], [10.0, 20.0, 0.0])));
    for k in 0..5 {
        let y = if k == 3 { f64::INFINITY } else { 1.0 };
        pc.add_point(
            [f64::from(k), y, 0.0]
                .map(e57::RecordValue::Double)
                .to_vec(),
        )
        .expect("point");
    }
    pc.finalize().expect("scan written");
    w.finalize().expect("file written");
    let err = convert_fails(&input, "non-finite");
    assert!(
        err.contains("point 3 has a non-finite y coordinate (inf)"),
        "{err}"
    );
}

#[test]
fn intensity_limits_stored_as_scaled_integers_scale_the_intensity() {
    // Intensity as 0.01 steps of 0..40 with limits 0..20: a value of 10 is half way.
    let dir = tempfile::tempdir().expect("tempdir");
    let written = dir.path().join("raw.e57");
    let scaled = e57::RecordDataType::ScaledInteger {
        min: 0,
        max: 4000,
        scale: 0.01,
        offset: 0.0,
    };
    let mut prototype = vec![
        e57::Record::CARTESIAN_X_F64,
        e57::Record::CARTESIAN_Y_F64,
        e57::Record::CARTESIAN_Z_F64,
    ];
    prototype.push(e57::Record {
        name: e57::RecordName::Intensity,
        data_type: scaled,
    });
    let mut w = e57::E57Writer::from_file(&written, "strata-test-limits").expect("writer");
    let mut pc = w.add_pointcloud("scan", prototype).expect("scan");
    // The crate writes a scaled limit without its scale: a raw value as long as the text
    // that replaces it below.
    pc.set_intensity_limits(Some(e57::IntensityLimits {
        intensity_min: Some(e57::RecordValue::ScaledInteger(0)),
        intensity_max: Some(e57::RecordValue::ScaledInteger(1_000_000_000_000_002_000)),
    }));
    let raw = [0i64, 500, 1000, 2000, 3000];
    for (k, &v) in raw.iter().enumerate() {
        let mut values: Vec<e57::RecordValue> =
            [k as f64, 0.0, 0.0].map(e57::RecordValue::Double).to_vec();
        values.push(e57::RecordValue::ScaledInteger(v));
        pc.add_point(values).expect("point");
    }
    pc.finalize().expect("scan written");
    w.finalize().expect("file written");
    let bytes = xml_replaced(
        std::fs::read(&written).expect("read"),
        "\">1000000000000002000<",
        "\" scale=\"0.01\">002000<",
    );
    let input = dir.path().join("limits.e57");
    std::fs::write(&input, bytes).expect("write");
    let ds = convert(dir.path(), &[&input]);
    let (meta, got) = stored(&ds);
    assert!(meta.attributes.iter().any(|a| a.name == "intensity"));
    let mut by_x: Vec<(i64, u16)> = got
        .iter()
        .map(|(q, tags)| (q[0], *tags.last().expect("intensity")))
        .collect();
    by_x.sort_unstable();
    let want: Vec<u16> = raw
        .iter()
        .map(|&v| ((v as f64 * 0.01 / 20.0).clamp(0.0, 1.0) * 65535.0).round() as u16)
        .collect();
    let intensities: Vec<u16> = by_x.iter().map(|p| p.1).collect();
    assert_eq!(intensities, want);
}

#[test]
fn single_precision_limits_of_the_whole_float_range_say_nothing() {
    // libE57Format gives every float field the limits ±FLT_MAX.
    for translation in [[0.0, 0.0, 0.0], [5e6, 4e6, 100.0]] {
        let dir = tempfile::tempdir().expect("tempdir");
        let input = dir.path().join("flt_max.e57");
        let single = e57::RecordDataType::Single {
            min: Some(-f32::MAX),
            max: Some(f32::MAX),
        };
        let prototype = [
            e57::RecordName::CartesianX,
            e57::RecordName::CartesianY,
            e57::RecordName::CartesianZ,
        ]
        .map(|name| e57::Record {
            name,
            data_type: single.clone(),
        })
        .to_vec();
        let mut w = e57::E57Writer::from_file(&input, "strata-test-flt-max").expect("writer");
        let mut pc = w.add_pointcloud("scan", prototype).expect("scan");
        pc.set_transform(Some(pose([1.0, 0.0, 0.0, 0.0], translation)));
        for k in 0..400 {
            let p = [(k % 20) as f32 * 0.01, (k / 20) as f32 * 0.01, 1.5];
            pc.add_point(p.map(e57::RecordValue::Single).to_vec())
                .expect("point");
        }
        pc.finalize().expect("scan written");
        w.finalize().expect("file written");
        assert_stored_finely(dir.path(), &input, &format!("at {translation:?}"));
    }
}

#[test]
fn a_pose_so_far_away_that_the_scan_is_lost_in_it_is_refused() {
    // Scaled integers of ±4 m placed 1e300 away: beside that translation the scan's extent is
    // lost, and every point would get the same x (a LAS offset that large is refused too).
    let dir = tempfile::tempdir().expect("tempdir");
    let input = dir.path().join("lost.e57");
    let spec = ScanSpec::new(Storage::Scaled, 500).at([1e300, 0.0, 0.0]);
    write_e57(&input, std::slice::from_ref(&spec));
    convert_fails(
        &input,
        "scan 0 of 1: its pose's translation x = 1e300 is so large that the scan's own extent",
    );
    // 5e6 away, as a georeferenced scan is, the same scan converts.
    let input = dir.path().join("far.e57");
    let spec = ScanSpec::new(Storage::Scaled, 500).at([5e6, 4e6, 100.0]);
    write_e57(&input, std::slice::from_ref(&spec));
    convert(dir.path(), &[&input]);
}
