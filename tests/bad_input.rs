//! Bad input: one clear sentence naming the file and the fault, a non-zero exit, no panic, and
//! no output that looks valid.

mod common;
use common::*;
use std::path::{Path, PathBuf};

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).expect("write");
    p
}

fn autzen() -> Vec<u8> {
    std::fs::read(data("autzen_trim.las")).expect("autzen")
}

#[test]
fn missing_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    convert_fails(&dir.path().join("nope.las"), "does not exist");
}

#[test]
fn directory_instead_of_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path().join("folder.las");
    std::fs::create_dir(&d).expect("mkdir");
    convert_fails(&d, "not a regular file");
}

#[test]
fn truncated_las() {
    let dir = tempfile::tempdir().expect("tempdir");
    let b = autzen();
    let p = write(dir.path(), "cut.las", &b[..b.len() / 2]);
    convert_fails(&p, "truncated");
}

#[test]
fn header_count_disagrees_with_records() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut b = autzen();
    // Legacy point count at byte 107: claim fewer points than the file holds.
    b[107..111].copy_from_slice(&100_000u32.to_le_bytes());
    let p = write(dir.path(), "count.las", &b);
    convert_fails(&p, "header says 100000 points but the file holds 110000");
}

#[test]
fn truncated_laz() {
    let dir = tempfile::tempdir().expect("tempdir");
    let b = std::fs::read(data("autzen_trim.laz")).expect("laz");
    let p = write(dir.path(), "cut.laz", &b[..b.len() * 2 / 3]);
    convert_fails(&p, "corrupt or truncated");
    // Damaged in the middle: the chunk holding the damage is named (the second of three, of
    // 50,000 points each).
    let mut flipped = b.clone();
    let m = flipped.len() / 2;
    flipped[m..m + 64].iter_mut().for_each(|x| *x ^= 0x5a);
    let p = write(dir.path(), "flipped.laz", &flipped);
    convert_fails(
        &p,
        "the compressed chunk at byte 285651 (points 50000 to 99999) is corrupt",
    );
    // Zeroed inside the first chunk: the decoder reads the zeros as points, millions of
    // units off, and finishes the chunk early instead of failing.
    let mut zeroed = b.clone();
    zeroed[5000..9096].fill(0);
    let p = write(dir.path(), "zeroed.laz", &zeroed);
    convert_fails(
        &p,
        "the compressed chunk at byte 2152 (points 0 to 49999) is corrupt: its 50000 points decode from 4968 of its 283499 bytes",
    );
}

#[test]
fn unsupported_version_and_point_format() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut b = autzen();
    b[25] = 9;
    let p = write(dir.path(), "v19.las", &b);
    convert_fails(&p, "version 1.9 is not supported");
    let mut b = autzen();
    b[104] = 11;
    let p = write(dir.path(), "pf11.las", &b);
    convert_fails(&p, "point format 11 is not supported");
    // With a top bit set the byte is named too: 99 is not 'format 35' to the user who wrote it.
    b[104] = 99;
    let p = write(dir.path(), "pf99.las", &b);
    convert_fails(&p, "point format 35 (byte 99) is not supported");
}

#[test]
fn random_bytes_with_point_cloud_names() {
    let dir = tempfile::tempdir().expect("tempdir");
    let junk: Vec<u8> = (0..5000u32)
        .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
        .collect();
    convert_fails(
        &write(dir.path(), "junk.las", &junk),
        "not a LAS or LAZ file",
    );
    convert_fails(
        &write(dir.path(), "junk.laz", &junk),
        "not a LAS or LAZ file",
    );
    convert_fails(&write(dir.path(), "junk.ply", &junk), "not a PLY file");
    convert_fails(&write(dir.path(), "tiny.las", b"LASF"), "too short");
    // `info` on a LAS or LAZ file checks it as the conversion does, and says the same.
    let laz = std::fs::read(data("autzen_trim.laz")).expect("autzen");
    let cut = write(dir.path(), "cut.laz", &laz[..5000]);
    let o = run(&["info", s(&cut)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("the chunk table offset") && err.contains("truncated"),
        "{err}"
    );
    // An uncompressed LAS cut after its header: its count was printed as if the records were there.
    let las = std::fs::read(data("autzen_trim.las")).expect("autzen");
    let cut = write(dir.path(), "cut.las", &las[..las.len() / 2]);
    let o = run(&["info", s(&cut)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("cut.las") && err.contains("(truncated)"),
        "{err}"
    );
}

#[test]
fn ply_without_z_or_with_a_bad_header() {
    let dir = tempfile::tempdir().expect("tempdir");
    let no_z = b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n";
    convert_fails(&write(dir.path(), "noz.ply", no_z), "no \"z\" property");
    let bad = b"ply\nformat ascii 1.0\nelement vertex one\nproperty float x\nend_header\n";
    convert_fails(&write(dir.path(), "bad.ply", bad), "malformed PLY header");
    let short = b"ply\nformat binary_little_endian 1.0\nelement vertex 10\nproperty float x\nproperty float y\nproperty float z\nend_header\n\x00\x00\x00\x00";
    convert_fails(&write(dir.path(), "short.ply", short), "truncated");
}

/// The elements after the vertices are read to the end of the body too (their faults were
/// taken silently where the vertices were not the last element).
#[test]
fn ply_faults_after_the_vertices_are_found() {
    let dir = tempfile::tempdir().expect("tempdir");
    let binary = |faces: u32, tail: &[u8]| {
        let mut b = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face {faces}\nproperty list uchar int vertex_indices\nend_header\n"
        )
        .into_bytes();
        for v in [[0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
            v.iter().for_each(|c| b.extend(c.to_le_bytes()));
        }
        b.push(3);
        [0i32, 1, 2].iter().for_each(|i| b.extend(i.to_le_bytes()));
        b.extend_from_slice(tail);
        b
    };
    let good = write(dir.path(), "good.ply", &binary(1, b""));
    run_ok(&["convert", s(&good), "-o", s(&dir.path().join("ds")), "-q"]);
    convert_fails(
        &write(dir.path(), "faces.ply", &binary(5, b"")),
        "the file ends inside element \"face\" (item 1)",
    );
    convert_fails(
        &write(dir.path(), "tail.ply", &binary(1, b"garbage")),
        "7 bytes follow the last item of element \"face\"",
    );
    let ascii = |faces: u32, body: &str| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nelement face {faces}\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n{body}"
        )
    };
    convert_fails(
        &write(
            dir.path(),
            "tail_ascii.ply",
            ascii(1, "3 0 0 0\nnot a face\n").as_bytes(),
        ),
        "text follows the last item of element \"face\"",
    );
    convert_fails(
        &write(
            dir.path(),
            "few_ascii.ply",
            ascii(3, "3 0 0 0\n3 0 0 0\n").as_bytes(),
        ),
        "the file ends inside element \"face\" (item 2, counting from 0)",
    );
    convert_fails(
        &write(dir.path(), "count.ply", ascii(1, "300 0 0 0\n").as_bytes()),
        "list \"vertex_indices\" has an item count 300 that its count type, u8, cannot give",
    );
    // Text PLY is words, not lines: a blank line, or two faces on one line, is fine; so is NUL
    // padding after the body.
    for (name, body) in [
        ("blank.ply", &b"\n3 0 0 0\n\n3 0 0 0\n"[..]),
        ("one_line.ply", b"3 0 0 0 3 0 0 0\n"),
        ("padded.ply", b"3 0 0 0\n3 0 0 0\n\0\0\0\0"),
    ] {
        let mut bytes = ascii(2, "").into_bytes();
        bytes.extend_from_slice(body);
        let p = write(dir.path(), name, &bytes);
        run_ok(&[
            "convert",
            s(&p),
            "-o",
            s(&dir.path().join(name).with_extension("ds")),
            "-q",
        ]);
    }
}

#[test]
fn non_finite_coordinates() {
    let dir = tempfile::tempdir().expect("tempdir");
    let nan = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 nan 1\n2 2 2\n";
    convert_fails(
        &write(dir.path(), "nan.ply", nan),
        "point 1 has a non-finite y coordinate",
    );
    let inf = b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 1 inf\n";
    convert_fails(
        &write(dir.path(), "inf.ply", inf),
        "non-finite z coordinate",
    );
    // Beyond f32's range, in a float property: not a float's value (it was taken as infinity,
    // or as the double it spells for a coordinate).
    for (name, line) in [("big_x.ply", "1e39 0 0 1"), ("big_i.ply", "0 0 0 -1e39")] {
        let ply = format!(
            "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty float intensity\nend_header\n0 0 0 1\n{line}\n"
        );
        convert_fails(
            &write(dir.path(), name, ply.as_bytes()),
            "e39\" that is not a f32 number",
        );
    }
}

#[test]
fn disk_full_leaves_no_valid_looking_output() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("ds");
    let o = run_file_limited(
        1024,
        &["convert", s(&data("autzen_trim.las")), "-o", s(&out)],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(err.contains("File too large"), "{err}");
    assert!(!err.contains("panicked"));
    assert!(!out.exists());
    let v = run(&["verify", s(&out)]);
    assert!(!v.status.success());
}

#[test]
fn laz_header_count_below_its_records_is_refused_like_las() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut b = std::fs::read(data("autzen_trim.laz")).expect("autzen laz");
    // 109,999 of 110,000: the same number of chunks, one point short in the last.
    b[107..111].copy_from_slice(&109_999u32.to_le_bytes());
    let p = write(dir.path(), "short.laz", &b);
    convert_fails(&p, "holds more than 9999 points");
    b[107..111].copy_from_slice(&0u32.to_le_bytes());
    let p = write(dir.path(), "zero.laz", &b);
    convert_fails(&p, "lists 3 chunks, but the file holds 0 points");
}

#[test]
fn laz_bit_without_a_laszip_vlr_says_so() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut b = autzen();
    b[104] |= 0x80;
    let p = write(dir.path(), "bit.las", &b);
    convert_fails(
        &p,
        "marks the points as LAZ-compressed, but the file has no laszip VLR",
    );
}

#[test]
fn laszip_vlr_that_disagrees_with_the_header_is_refused_before_decoding() {
    let dir = tempfile::tempdir().expect("tempdir");
    let orig = std::fs::read(data("autzen_trim.laz")).expect("autzen laz");
    let vlr = laszip_vlr_body(&orig);
    let cases: [(usize, &[u8], &str); 4] = [
        (
            105,
            &35u16.to_le_bytes(),
            "items add up to 34 bytes per point",
        ),
        (
            vlr + 32,
            &0u16.to_le_bytes(),
            "it lists no compressed items",
        ),
        (
            vlr + 12,
            &7u32.to_le_bytes(),
            "in chunks of 7 (laszip VLR) make 15715",
        ),
        (
            vlr + 12,
            &1999u32.to_le_bytes(),
            "in chunks of 1999 (laszip VLR) make 56",
        ),
    ];
    for (i, (at, bytes, want)) in cases.into_iter().enumerate() {
        let mut b = orig.clone();
        b[at..at + bytes.len()].copy_from_slice(bytes);
        let p = write(dir.path(), &format!("vlr{i}.laz"), &b);
        convert_fails(&p, want);
    }
}

#[test]
fn a_coarse_step_is_said_even_with_quiet_and_recorded() {
    let dir = tempfile::tempdir().expect("tempdir");
    // Doubles 10^12 apart: stored in steps of 1000, which merges points nearer than that.
    let ply = "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\nend_header\n0.5 0 0\n1e12 1 1\n";
    let p = write(dir.path(), "far.ply", ply.as_bytes());
    let out = dir.path().join("ds");
    let o = run(&["convert", s(&p), "-o", s(&out), "--quiet"]);
    assert!(o.status.success());
    let said = "floating-point coordinates stored in steps of 1e3 (the points span x 5e-1 to 1e12";
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("warning:") && err.contains(said), "{err}");
    let meta = std::fs::read_to_string(out.join("metadata.json")).expect("metadata");
    let v: serde_json::Value = serde_json::from_str(&meta).expect("json");
    let warnings = v["warnings"].as_array().expect("warnings recorded");
    assert!(
        warnings
            .iter()
            .any(|w| w.as_str().is_some_and(|w| w.contains(said)))
    );
    run_ok(&["verify", s(&out)]);
    // Doubles a few metres apart fit on a fine step: nothing to say.
    let near = ply.replace("1e12 1 1", "2 1 1");
    let p = write(dir.path(), "near.ply", near.as_bytes());
    let o = run_ok(&["convert", s(&p), "-o", s(&dir.path().join("near"))]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("warning"), "{err}");
}

#[test]
fn a_header_box_far_larger_than_the_points_moves_none_of_them() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (i, v) in [1e9, 1e300].into_iter().enumerate() {
        let mut b = autzen();
        b[179..187].copy_from_slice(&f64::to_le_bytes(v));
        let p = write(dir.path(), &format!("box{i}.las"), &b);
        let out = dir.path().join(format!("ds{i}"));
        let o = run_ok(&["convert", s(&p), "-o", s(&out), "--quiet"]);
        assert!(!String::from_utf8_lossy(&o.stderr).contains("coarsened"));
        let back = dir.path().join(format!("back{i}.las"));
        run_ok(&["export", s(&out), "-o", s(&back)]);
        assert!(las_multiset(&back) == las_multiset(&p), "points moved");
    }
}

#[test]
fn absurd_counts_are_refused_in_one_sentence() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("ds");
    run_ok(&["convert", s(&data("autzen_trim.las")), "-o", s(&ds), "-q"]);
    let path = dir.path().join("path.json");
    std::fs::write(
        &path,
        r#"{"keyframes": [{"eye": [0, 0, 100], "target": [0, 0, 0]},
                          {"eye": [10, 0, 100], "target": [0, 0, 0]}]}"#,
    )
    .expect("write");
    let out = dir.path().join("x.las");
    let png = dir.path().join("f.png");
    let fails = |args: &[&str], expect: &str| {
        let o = run(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} ran");
        assert!(
            err.contains(expect) && !err.contains("panicked"),
            "{args:?}: {err}"
        );
    };
    // Counts that saturated or allocated without bound, and timeouts that overflowed the
    // clock at each request.
    fails(
        &["synth", "--points", "1e30", "-o", s(&out)],
        "is more than",
    );
    fails(
        &["synth", "--points", "1.5", "-o", s(&out)],
        "not a whole count",
    );
    fails(
        &["synth", "--points", "10", "--noise", "1e300", "-o", s(&out)],
        "--noise 1e300 is more than the 1000 m",
    );
    assert!(!out.exists());
    for flag in [
        "--max-connections",
        "--idle-timeout",
        "--header-timeout",
        "--blocking-threads",
    ] {
        fails(
            &["serve", s(dir.path()), flag, "18446744073709551615"],
            flag,
        );
    }
    fails(
        &["render", s(&ds), "-o", s(&png), "--loaders", "100000"],
        "--loaders",
    );
    // A fly-through with `extra` arguments.
    let fly = |extra: &[&str], says: &str| {
        let mut args = vec!["render", s(&ds), "-o", s(&png), "--path", s(&path)];
        args.extend_from_slice(extra);
        fails(&args, says);
    };
    fly(
        &["--frames", "4294967295"],
        "4294967295 is more than the 100000 frames a fly-through may take: \"--frames\"",
    );
    // 0 was taken as the default (frames from the keyframes' times).
    fly(&["--frames", "0"], "'--frames <FRAMES>'");
    // A pace so slow that the run would not end (a frame every 30 years), or whose period
    // is no number of seconds at all; refused for a still too (it was taken unread).
    for fps in ["1e-9", "1e-39", "NaN", "inf"] {
        let says = "is not 0 (unpaced) or a pace from 0.1 to 1000 frames per second";
        fly(&["--frames", "2", "--fps", fps], says);
        fails(&["render", s(&ds), "-o", s(&png), "--fps", fps], says);
    }
    // A keyframe's time that is no positive number (it was taken as the default 3 s).
    for seconds in ["0", "-1"] {
        let cut = dir.path().join(format!("cut{seconds}.json"));
        std::fs::write(
            &cut,
            format!(
                r#"{{"keyframes": [{{"eye": [0, 0, 100], "target": [0, 0, 0]}},
                   {{"eye": [10, 0, 100], "target": [0, 0, 0], "seconds": {seconds}}}]}}"#
            ),
        )
        .expect("write");
        fails(
            &["render", s(&ds), "-o", s(&png), "--path", s(&cut)],
            &format!("keyframe 2 has seconds {seconds}; it must be a positive number"),
        );
    }
}

#[test]
fn a_file_given_twice_is_said() {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = data("autzen_trim.las");
    let again = las
        .parent()
        .expect("folder")
        .join(".")
        .join("autzen_trim.las");
    let out = dir.path().join("ds");
    let o = run_ok(&["convert", s(&las), s(&again), "-o", s(&out), "-q"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("the same file as") && err.contains("converted twice"),
        "{err}"
    );
}
