//! What `export` writes holds what the dataset holds: classes and return numbers beyond the
//! legacy LAS formats' bits, header bounds on the points themselves, PLY property names that a
//! reader accepts, and extra attributes described in an extended VLR.

mod common;
use common::*;
use std::path::Path;

/// A binary PLY of points (x, classification, return number) on the x axis.
fn classed_ply(path: &Path, points: &[(f32, u8, u8)]) {
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty uchar classification\nproperty uchar return_number\nproperty uchar number_of_returns\nend_header\n",
        points.len()
    )
    .into_bytes();
    for &(x, class, ret) in points {
        for v in [x, 0.0, 0.0] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        bytes.extend_from_slice(&[class, ret, ret]);
    }
    std::fs::write(path, bytes).expect("write ply");
}

#[test]
fn classes_and_returns_beyond_the_legacy_bits_export_whole() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (ply, ds, las) = (
        dir.path().join("c.ply"),
        dir.path().join("ds"),
        dir.path().join("c.las"),
    );
    let points = [(0.0, 200, 9), (1.0, 37, 12), (2.0, 2, 1), (3.0, 255, 15)];
    classed_ply(&ply, &points);
    run_ok(&["convert", s(&ply), "-o", s(&ds), "-q"]);
    run_ok(&["export", s(&ds), "-o", s(&las)]);
    let mut reader = las::Reader::from_path(&las).expect("read export");
    assert!(
        reader.header().point_format().is_extended,
        "formats 0 to 5 cannot hold class 200"
    );
    // Formats 6 to 10 keep no legacy compatibility: the legacy counts are 0 (LAS 1.4).
    let bytes = std::fs::read(&las).expect("read");
    assert_eq!(bytes[107..131], [0u8; 24], "legacy counts");
    let mut got: Vec<(i64, u8, u8, u8)> = reader
        .read_all()
        .expect("all points")
        .points()
        .map(|p| {
            let p = p.expect("point");
            (
                p.x.round() as i64,
                u8::from(p.classification),
                p.return_number,
                p.number_of_returns,
            )
        })
        .collect();
    got.sort_unstable();
    let want: Vec<(i64, u8, u8, u8)> = points
        .iter()
        .map(|&(x, c, r)| (x as i64, c, r, r))
        .collect();
    assert_eq!(got, want);
}

/// Points of an input without returns, merged with one that has them, were stored as return 0
/// of 0, which formats 6 and up forbid; alone they export as single returns, and merged too.
#[test]
fn points_without_returns_merged_with_returns_are_single_returns() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (with, without, ds, las) = (
        dir.path().join("with.ply"),
        dir.path().join("without.ply"),
        dir.path().join("ds"),
        dir.path().join("out.las"),
    );
    classed_ply(&with, &[(0.0, 2, 3), (1.0, 2, 2)]);
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec();
    for x in [10.0f32, 11.0] {
        for v in [x, 0.0, 0.0] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(&without, bytes).expect("write ply");
    run_ok(&["convert", s(&with), s(&without), "-o", s(&ds), "-q"]);
    run_ok(&["export", s(&ds), "-o", s(&las)]);
    let mut reader = las::Reader::from_path(&las).expect("read export");
    let mut got: Vec<(i64, u8, u8)> = reader
        .read_all()
        .expect("all points")
        .points()
        .map(|p| {
            let p = p.expect("point");
            (p.x.round() as i64, p.return_number, p.number_of_returns)
        })
        .collect();
    got.sort_unstable();
    assert_eq!(got, [(0, 3, 3), (1, 2, 2), (10, 1, 1), (11, 1, 1)]);
}

#[test]
fn a_return_number_past_the_legacy_format_takes_an_extended_one_and_past_that_is_refused() {
    // A legacy LAS beside a PLY: the union carries the legacy scan angle rank, so the export
    // picks a legacy format (the metadata counts the classes, which would tell it otherwise,
    // but not the returns). The PLY's return number 12 does not fit it: the export was
    // refused; it is written in an extended format, and the profile through those points too.
    // A return number of 20 fits no LAS format and is refused, with nothing left behind.
    let dir = tempfile::tempdir().expect("tempdir");
    let autzen = data("autzen_trim.las");
    let reader = las::Reader::from_path(&autzen).expect("autzen");
    assert!(
        !reader.header().point_format().is_extended,
        "the test needs a legacy LAS"
    );
    for (ret, fits) in [(12u8, true), (20, false)] {
        let ply = dir.path().join(format!("c{ret}.ply"));
        let (ds, las) = (
            dir.path().join(format!("ds{ret}")),
            dir.path().join(format!("c{ret}.las")),
        );
        classed_ply(&ply, &[(637000.0, 2, ret), (637001.0, 2, 1)]);
        run_ok(&["convert", s(&autzen), s(&ply), "-o", s(&ds), "-q"]);
        let out = run(&["export", s(&ds), "-o", s(&las)]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !dir.path().join(format!("c{ret}.las.part")).exists(),
            "no leftover"
        );
        if !fits {
            assert!(!out.status.success(), "export must fail: {err}");
            assert!(
                err.contains("return_number is 20") && err.contains("holds (0 to 15)"),
                "the error names the value and the extended format: {err}"
            );
            assert!(!las.exists(), "no output that looks complete");
            continue;
        }
        assert!(out.status.success(), "{err}");
        assert_eq!(extended_returns(&las), (true, vec![1, 12]));
        let prof = dir.path().join("profile.las");
        let line = "--line=636999,0;637002,0";
        run_ok(&["profile", s(&ds), line, "--width", "1", "-o", s(&prof)]);
        assert_eq!(extended_returns(&prof), (true, vec![1, 12]));
    }
}

/// Whether the LAS file `path` has an extended point format, and the return numbers of its
/// points on the PLY's line (y = z = 0 there), sorted.
fn extended_returns(path: &Path) -> (bool, Vec<u8>) {
    let mut reader = las::Reader::from_path(path).expect("read LAS");
    let extended = reader.header().point_format().is_extended;
    let points = reader.read_all().expect("all points");
    let mut returns: Vec<u8> = points
        .points()
        .map(|p| p.expect("point"))
        .filter(|p| p.y == 0.0 && p.z == 0.0)
        .map(|p| p.return_number)
        .collect();
    returns.sort_unstable();
    (extended, returns)
}

#[test]
fn exported_las_header_bounds_are_the_points_own() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (input, ds, out) = (
        dir.path().join("one.las"),
        dir.path().join("ds"),
        dir.path().join("out.las"),
    );
    let (scale, offset) = (0.01, [700000.0, 4e6, 100.0]);
    let ints = [17, -3, 99];
    let mut builder = las::Builder::from((1, 4));
    builder.transforms = las::Vector {
        x: las::Transform {
            scale,
            offset: offset[0],
        },
        y: las::Transform {
            scale,
            offset: offset[1],
        },
        z: las::Transform {
            scale,
            offset: offset[2],
        },
    };
    let header = builder.into_header().expect("header");
    let mut writer = las::Writer::from_path(&input, header).expect("writer");
    let real = |a: usize| offset[a] + scale * f64::from(ints[a]);
    writer
        .write_point(las::Point {
            x: real(0),
            y: real(1),
            z: real(2),
            ..Default::default()
        })
        .expect("write");
    writer.close().expect("close");
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    run_ok(&["export", s(&ds), "-o", s(&out)]);
    let bytes = std::fs::read(&out).expect("export");
    let at = |i: usize| f64::from_le_bytes(bytes[179 + 8 * i..187 + 8 * i].try_into().unwrap());
    for a in 0..3 {
        assert_eq!(at(2 * a), real(a), "max on axis {a}");
        assert_eq!(at(2 * a + 1), real(a), "min on axis {a}");
    }
}

#[test]
fn ply_export_declares_every_property_once() {
    // A colour under the diffuse names beside a scalar called red.
    let dir = tempfile::tempdir().expect("tempdir");
    let (input, ds, out, again) = (
        dir.path().join("in.ply"),
        dir.path().join("ds"),
        dir.path().join("out.ply"),
        dir.path().join("again"),
    );
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty uchar diffuse_red\nproperty uchar diffuse_green\nproperty uchar diffuse_blue\nproperty float red\nend_header\n".to_vec();
    for (x, red) in [(0.0f32, 0.25f32), (1.0, 0.75)] {
        for v in [x, 0.0, 0.0] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        bytes.extend_from_slice(&[10, 20, 30]);
        bytes.extend_from_slice(&red.to_le_bytes());
    }
    std::fs::write(&input, bytes).expect("write");
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    run_ok(&["export", s(&ds), "-o", s(&out)]);
    let text = std::fs::read(&out).expect("export");
    let end = text
        .windows(10)
        .position(|w| w == b"end_header")
        .expect("header");
    let header = String::from_utf8_lossy(&text[..end]);
    let names: Vec<&str> = header
        .lines()
        .filter_map(|l| l.strip_prefix("property "))
        .filter_map(|l| l.split_whitespace().nth(1))
        .collect();
    let mut unique = names.clone();
    unique.sort_unstable();
    unique.dedup();
    assert_eq!(unique.len(), names.len(), "a name twice: {names:?}");
    assert!(
        names.contains(&"red") && names.contains(&"red_1"),
        "{names:?}"
    );
    // And it reads back, the colour still a colour.
    run_ok(&["convert", s(&out), "-o", s(&again), "-q"]);
    let meta = std::fs::read_to_string(again.join("metadata.json")).expect("metadata");
    assert!(
        meta.contains("\"rgb\"") && meta.contains("\"red_1\""),
        "{meta}"
    );
}

/// A LAS 1.4 file of three points with one i32 extra-bytes field "height" (described in an
/// extended VLR: LAS 1.4 R15, table 24, 192 bytes a field), value = offset + scale · raw.
fn height_las(path: &Path, scale: f64, offset: f64, raw: i32) {
    let mut eb = vec![0u8; 192];
    eb[2] = 6; // data type: i32
    eb[3] = (1 << 3) | (1 << 4); // options: scale and offset present
    eb[4..10].copy_from_slice(b"height");
    eb[112..120].copy_from_slice(&scale.to_le_bytes());
    eb[136..144].copy_from_slice(&offset.to_le_bytes());
    let points: Vec<_> = (0..3)
        .map(|i| ([f64::from(i), 0.0, 0.0], raw.to_le_bytes().to_vec()))
        .collect();
    extra_bytes_las(path, eb, true, &points);
}

#[test]
fn extra_bytes_described_in_an_extended_vlr_keep_their_names() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (input, ds) = (dir.path().join("evlr.las"), dir.path().join("ds"));
    height_las(&input, 0.01, 0.0, 1234);
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(ds.join("metadata.json")).expect("metadata"))
            .expect("json");
    let height = meta["attributes"]
        .as_array()
        .expect("attributes")
        .iter()
        .find(|a| a["name"] == "height")
        .unwrap_or_else(|| panic!("no height in {meta}"));
    assert_eq!(height["type"], "i32");
    assert_eq!(height["scale"][0], 0.01);
    // PLY has no place for the scale: the value it stands for goes out, as a double.
    let ply = dir.path().join("out.ply");
    run_ok(&["export", s(&ds), "-o", s(&ply)]);
    let bytes = std::fs::read(&ply).expect("export");
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .expect("header")
        + 11;
    let header = String::from_utf8_lossy(&bytes[..end]);
    let properties: Vec<(&str, &str)> = header
        .lines()
        .filter_map(|l| l.strip_prefix("property "))
        .filter_map(|l| l.split_once(' '))
        .collect();
    let size = |ty: &str| match ty {
        "char" | "uchar" => 1,
        "short" | "ushort" => 2,
        "int" | "uint" | "float" => 4,
        _ => 8,
    };
    let record: usize = properties.iter().map(|(ty, _)| size(ty)).sum();
    let at: usize = properties
        .iter()
        .take_while(|(_, name)| *name != "height")
        .map(|(ty, _)| size(ty))
        .sum();
    assert!(properties.contains(&("double", "height")), "{header}");
    for i in 0..3 {
        let v = &bytes[end + i * record + at..][..8];
        let value = f64::from_le_bytes(v.try_into().expect("8 bytes"));
        assert!((value - 12.34).abs() < 1e-9, "height {value}");
    }
}

/// The rows keep an extra attribute's raw integers under one scale: inputs that scale it
/// differently are refused (their values were read with the first input's scale).
#[test]
fn extra_bytes_scaled_differently_in_two_inputs_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (a, b, same) = (
        dir.path().join("a.las"),
        dir.path().join("b.las"),
        dir.path().join("same.las"),
    );
    height_las(&a, 0.01, 0.0, 100);
    height_las(&b, 0.1, 5.0, 100);
    height_las(&same, 0.01, 0.0, 250);
    let ds = dir.path().join("ds");
    let o = run(&["convert", s(&a), s(&b), "-o", s(&ds), "-q"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("b.las")
            && err.contains("\"height\"")
            && err.contains("scale 0.1 and offset 5")
            && err.contains("scale 0.01 and offset 0"),
        "{err}"
    );
    assert!(!ds.exists(), "no output");
    // Scaled alike, they merge, each value kept.
    run_ok(&["convert", s(&a), s(&same), "-o", s(&ds), "-q"]);
    let ply = dir.path().join("out.ply");
    run_ok(&["export", s(&ds), "-o", s(&ply)]);
    let text = String::from_utf8_lossy(&std::fs::read(&ply).expect("export")).into_owned();
    assert!(text.contains("property double height"), "{text}");
}

#[test]
fn a_return_number_beyond_four_bits_is_refused_not_cut() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (ply, ds) = (dir.path().join("r.ply"), dir.path().join("ds"));
    classed_ply(&ply, &[(0.0, 2, 20), (1.0, 2, 3)]);
    run_ok(&["convert", s(&ply), "-o", s(&ds), "-q"]);
    for name in ["r.las", "r.copc.laz"] {
        let out = dir.path().join(name);
        let o = run(&["export", s(&ds), "-o", s(&out)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{name}: {err}");
        assert!(err.contains("return_number is 20"), "{name}: {err}");
        assert!(!out.exists(), "{name}: no output that looks complete");
    }
    run_ok(&["export", s(&ds), "-o", s(&dir.path().join("out.ply"))]);
}

/// A standard field held in another type than LAS's (a PLY's ushort return number, float
/// intensity) is refused where LAS cannot hold its value, as a uchar one is, not cut to its bits
/// or clamped; so is a scanner channel beyond the two bits of formats 6 to 10.
#[test]
fn standard_fields_of_other_types_beyond_las_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, value, v, said) in [
        ("return_number", "ushort", "20", "return_number is 20"),
        ("intensity", "float", "70000", "intensity is 70000"),
        (
            "scanner_channel",
            "uchar",
            "7",
            "outside what LAS point format 6 holds (0 to 3)",
        ),
    ] {
        let ply = dir.path().join(format!("{name}.ply"));
        std::fs::write(
            &ply,
            format!(
                "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty {value} {name}\nend_header\n0 0 0 1\n1 0 0 {v}\n"
            ),
        )
        .expect("write ply");
        let ds = dir.path().join(format!("{name}_ds"));
        run_ok(&["convert", s(&ply), "-o", s(&ds), "-q"]);
        for out in ["r.las", "r.copc.laz"] {
            let out = dir.path().join(out);
            let o = run(&["export", s(&ds), "-o", s(&out)]);
            let err = String::from_utf8_lossy(&o.stderr);
            assert!(!o.status.success() && err.contains(said), "{name}: {err}");
            assert!(!out.exists(), "{name}: no output that looks complete");
        }
        run_ok(&[
            "export",
            s(&ds),
            "-o",
            s(&dir.path().join(format!("{name}_out.ply"))),
        ]);
    }
}

#[test]
fn undescribed_extra_bytes_go_back_out_undescribed() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (input, ds, out) = (
        dir.path().join("raw.las"),
        dir.path().join("ds"),
        dir.path().join("out.las"),
    );
    let mut builder = las::Builder::from((1, 4));
    builder.point_format = las::point::Format::new(1).expect("format");
    builder.point_format.extra_bytes = 2;
    let header = builder.into_header().expect("header");
    let mut writer = las::Writer::from_path(&input, header).expect("writer");
    for i in 0..3u8 {
        writer
            .write_point(las::Point {
                x: f64::from(i),
                gps_time: Some(0.0),
                extra_bytes: vec![i, 200 + i],
                ..Default::default()
            })
            .expect("write");
    }
    writer.close().expect("close");
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    run_ok(&["export", s(&ds), "-o", s(&out)]);
    let mut reader = las::Reader::from_path(&out).expect("read export");
    let eb = reader
        .header()
        .vlrs()
        .iter()
        .find(|v| v.user_id == "LASF_Spec" && v.record_id == 4)
        .expect("an Extra Bytes record")
        .data
        .clone();
    assert_eq!(eb.len(), 192, "one descriptor");
    assert_eq!((eb[2], eb[3]), (0, 2), "type 0 (undescribed), two bytes");
    let mut got: Vec<Vec<u8>> = reader
        .read_all()
        .expect("points")
        .points()
        .map(|p| p.expect("point").extra_bytes)
        .collect();
    got.sort();
    assert_eq!(got, vec![vec![0, 200], vec![1, 201], vec![2, 202]]);
}

#[test]
fn an_empty_las_has_finite_bounds() {
    // A profile with no point in its corridor still writes a LAS file readers accept.
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = common::converted("export-fidelity", "autzen_trim.laz", "autzen");
    let out = dir.path().join("empty.las");
    run_ok(&[
        "profile",
        s(&dataset),
        "--line",
        "0,0;1,1",
        "--width",
        "1",
        "-o",
        s(&out),
    ]);
    let bytes = std::fs::read(&out).expect("profile");
    for i in 0..6 {
        let v = f64::from_le_bytes(bytes[179 + 8 * i..187 + 8 * i].try_into().unwrap());
        assert_eq!(v, 0.0, "bound {i}");
    }
}

/// A u64 extra attribute went out to PLY as a double, rounded without a word (2^53 + 1 read
/// back as 2^53); it is refused there, naming the value, and kept whole in LAS.
#[test]
fn a_64_bit_integer_a_ply_double_cannot_hold_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (input, ds) = (dir.path().join("serial.las"), dir.path().join("ds"));
    let big = (1u64 << 53) + 1;
    serial_las(&input, &[([0.0; 3], 12345), ([1.0, 0.0, 0.0], big)]);
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    let ply = dir.path().join("out.ply");
    refused(
        &["export", s(&ds), "-o", s(&ply)],
        &["serial is 9007199254740993 (point ", "export to .las"],
    );
    assert!(!ply.exists());
    let las_out = dir.path().join("out.las");
    run_ok(&["export", s(&ds), "-o", s(&las_out)]);
    let mut reader = las::Reader::from_path(&las_out).expect("read export");
    let mut serials: Vec<u64> = reader
        .read_all()
        .expect("all points")
        .points()
        .map(|p| {
            let e = p.expect("point").extra_bytes;
            u64::from_le_bytes(e[..8].try_into().expect("8 bytes"))
        })
        .collect();
    serials.sort_unstable();
    assert_eq!(serials, [12345, big]);
}

/// A colour under the short names `r g b` is one colour, as under `red green blue`; it was
/// three scalars, which no viewer colours by.
#[test]
fn ply_colour_named_r_g_b_is_a_colour() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (input, ds) = (dir.path().join("in.ply"), dir.path().join("ds"));
    let text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty uchar r\nproperty uchar g\nproperty uchar b\nend_header\n0 0 0 10 20 30\n1 0 0 40 50 60\n";
    std::fs::write(&input, text).expect("write");
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(ds.join("metadata.json")).expect("metadata"))
            .expect("JSON");
    let names: Vec<&str> = meta["attributes"]
        .as_array()
        .expect("attributes")
        .iter()
        .filter_map(|a| a["name"].as_str())
        .collect();
    assert!(names.contains(&"rgb"), "{names:?}");
    assert!(
        !names.iter().any(|n| ["r", "g", "b"].contains(n)),
        "{names:?}"
    );
}

/// An extra attribute's no-data value (Extra Bytes descriptor option bit 0) goes back out to
/// LAS and COPC as the input stated it; it was dropped, and the marker read as a real value.
#[test]
fn extra_bytes_no_data_goes_back_out() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (input, ds) = (dir.path().join("nodata.las"), dir.path().join("ds"));
    // "height" f64 (type 10) with no_data -9999; "count" u32 (type 5) with no_data u32::MAX.
    let field = |name: &str, code: u8, no_data: u64| {
        let mut d = vec![0u8; 192];
        d[2] = code;
        d[3] = 0x01;
        d[4..4 + name.len()].copy_from_slice(name.as_bytes());
        d[40..48].copy_from_slice(&no_data.to_le_bytes());
        d
    };
    let height = (-9999.0f64).to_bits();
    let count = u64::from(u32::MAX);
    let descriptor = [field("height", 10, height), field("count", 5, count)].concat();
    let extra = |h: f64, c: u32| [h.to_le_bytes().to_vec(), c.to_le_bytes().to_vec()].concat();
    let points = [
        ([0.0, 0.0, 0.0], extra(-9999.0, 7)),
        ([1.0, 0.0, 0.0], extra(2.5, u32::MAX)),
    ];
    extra_bytes_las(&input, descriptor, false, &points);
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    for name in ["out.las", "out.copc.laz"] {
        let out = dir.path().join(name);
        run_ok(&["export", s(&ds), "-o", s(&out)]);
        let reader = las::Reader::from_path(&out).expect("read");
        let h = reader.header();
        let vlr = h
            .vlrs()
            .iter()
            .chain(h.evlrs())
            .find(|v| v.user_id == "LASF_Spec" && v.record_id == 4)
            .expect("an Extra Bytes VLR");
        let stated: Vec<(String, u8, u64)> = vlr
            .data
            .chunks_exact(192)
            .map(|d| {
                let end = d[4..36].iter().position(|&b| b == 0).unwrap_or(32);
                let name = String::from_utf8_lossy(&d[4..4 + end]).into_owned();
                let no_data = u64::from_le_bytes(d[40..48].try_into().expect("8 bytes"));
                (name, d[3] & 0x01, no_data)
            })
            .collect();
        for (field, value) in [("height", height), ("count", count)] {
            assert!(
                stated.contains(&(field.to_string(), 1, value)),
                "{name}: {field} in {stated:?}"
            );
        }
    }
}
