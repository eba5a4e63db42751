//! Files that are not what they seem: a device or a pipe where a small text file is named, a
//! disk that fills while a file is written, a header built to be slow, points too close to
//! store apart, dataset metadata that points outside the dataset, a file or a dead link where
//! a work folder is named, headers whose sizes would take the memory, and compressed chunks
//! damaged inside.

mod common;
use common::*;

#[test]
fn side_files_that_are_devices_are_refused_before_they_are_read() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = converted("side", "autzen_trim.las", "ds");
    let png = dir.path().join("x.png");
    // Each was read to its end: /dev/zero has none, and filled the memory.
    for args in [
        vec![
            "render",
            s(&ds),
            "-o",
            s(&png),
            "--camera-file",
            "/dev/zero",
        ],
        vec!["render", s(&ds), "-o", s(&png), "--path", "/dev/zero"],
        vec!["serve", s(&ds), "--token-file", "/dev/zero"],
    ] {
        let o = run_bounded(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("/dev/zero") && err.contains("not a regular file"),
            "{args:?}: {err}"
        );
    }
    assert!(!png.exists());
}

#[test]
fn synth_on_a_full_disk_leaves_no_partial_file() {
    for ext in ["las", "laz", "ply"] {
        let dir = tempfile::tempdir().expect("tempdir");
        let out = dir.path().join(format!("s.{ext}"));
        let o = run_file_limited(64, &["synth", "--points", "200000", "-o", s(&out)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{ext}: {err}");
        assert!(err.contains("File too large"), "{ext}: {err}");
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .expect("dir")
            .flatten()
            .map(|e| e.file_name())
            .collect();
        assert!(left.is_empty(), "{ext}: {left:?} left behind");
    }
}

#[test]
fn an_output_under_a_file_is_named_as_such() {
    let dir = tempfile::tempdir().expect("tempdir");
    let file = dir.path().join("afile");
    std::fs::write(&file, b"not a folder").expect("write");
    let out = file.join("ds");
    let o = run(&["convert", s(&data("autzen_trim.las")), "-o", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("afile/ds") && err.contains("a part of its path is a file"),
        "{err}"
    );
}

/// A binary PLY of `vertices` float x, y, z vertices and then the header lines `more`,
/// followed by `body`.
fn write_ply(path: &std::path::Path, vertices: usize, more: &str, body: &[u8]) {
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {vertices}\nproperty float x\nproperty float y\nproperty float z\n{more}end_header\n"
    )
    .into_bytes();
    bytes.extend_from_slice(body);
    std::fs::write(path, bytes).expect("write");
}

#[test]
fn a_ply_header_of_a_hundred_thousand_lines_is_read_at_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    // Each line was compared with every line before it: this header took minutes.
    let props: String = (0..100_000)
        .map(|i| format!("property float p{i}\n"))
        .collect();
    let many_props = dir.path().join("props.ply");
    write_ply(&many_props, 1, &props, &vec![0u8; 4 * 100_003]);
    let out = dir.path().join("props.strata");
    let o = run_bounded(&["convert", s(&many_props), "-o", s(&out), "-q"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("props.ply: its points have 100000 attributes; a dataset holds at most 1024"),
        "{err}"
    );
    assert!(!out.exists());
    // As many empty elements after the vertices: read, skipped, and the point converted.
    let elements: String = (0..100_000)
        .map(|i| format!("element e{i} 0\nproperty float v\n"))
        .collect();
    let many_elements = dir.path().join("elements.ply");
    write_ply(&many_elements, 1, &elements, &[0u8; 12]);
    let out = dir.path().join("elements.strata");
    let o = run_bounded(&["convert", s(&many_elements), "-o", s(&out), "-q"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// Inputs just under the cap, with what --normals adds, would have made a dataset no reader
/// opens.
#[test]
fn the_attributes_normals_adds_count_towards_the_cap() {
    let dir = tempfile::tempdir().expect("tempdir");
    let props: String = (0..1023)
        .map(|i| format!("property uchar p{i}\n"))
        .collect();
    let ply = dir.path().join("wide.ply");
    let mut body = Vec::new();
    for x in [0f32, 1.0] {
        for v in [x, 0.0, 0.0] {
            body.extend(v.to_le_bytes());
        }
        body.extend(vec![0u8; 1023]);
    }
    write_ply(&ply, 2, &props, &body);
    let out = dir.path().join("wide.strata");
    let o = run(&["convert", s(&ply), "-o", s(&out), "-q", "--normals"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("those --normals adds come to 1026"), "{err}");
    assert!(!out.exists());
}

#[test]
fn points_that_would_all_become_one_position_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ply = dir.path().join("tiny.ply");
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 100\nproperty double x\nproperty double y\nproperty double z\nend_header\n".to_vec();
    for i in 0..300 {
        bytes.extend((i as f64 * 1e-302).to_le_bytes());
    }
    std::fs::write(&ply, bytes).expect("write");
    let out = dir.path().join("tiny.strata");
    let o = run(&["convert", s(&ply), "-o", s(&out), "-q"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("tiny.ply") && err.contains("would all become one position"),
        "{err}"
    );
    assert!(!out.exists());
}

/// A copy of a converted dataset whose metadata.json `edit` changed.
fn edited_dataset(
    dir: &std::path::Path,
    edit: impl Fn(&mut serde_json::Value),
) -> std::path::PathBuf {
    let ds = converted("hostile-meta", "autzen_trim.las", "ds");
    let copy = dir.join("ds.strata");
    std::fs::create_dir_all(&copy).expect("dir");
    for f in ["metadata.json", "hierarchy.bin", "octree.bin"] {
        std::fs::copy(ds.join(f), copy.join(f)).expect("copy");
    }
    let text = std::fs::read_to_string(copy.join("metadata.json")).expect("read");
    let mut meta: serde_json::Value = serde_json::from_str(&text).expect("json");
    edit(&mut meta);
    std::fs::write(copy.join("metadata.json"), meta.to_string()).expect("write");
    copy
}

#[test]
fn metadata_naming_files_outside_the_dataset_or_overflowing_its_coordinates_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let other = converted("hostile-meta", "autzen_trim.las", "ds").join("octree.bin");
    let outside = edited_dataset(dir.path(), |m| {
        m["files"]["octree"]["name"] = s(&other).into();
    });
    for cmd in ["info", "verify"] {
        let o = run(&[cmd, s(&outside)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{cmd}: {err}");
        assert!(
            err.contains("files.octree.name") && err.contains("not a path"),
            "{cmd}: {err}"
        );
    }
    std::fs::remove_dir_all(&outside).expect("remove");
    // Every coordinate came out infinite, and verify said ok: the metadata is refused at open.
    let huge = edited_dataset(dir.path(), |m| {
        m["scale"] = serde_json::json!([1e308, 1e308, 1e308]);
    });
    let o = run(&["verify", s(&huge)]);
    let said = String::from_utf8_lossy(&o.stdout).to_string() + &String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{said}");
    assert!(
        said.contains("its scale 1e308") && said.contains("not a finite number"),
        "{said}"
    );
    // COPC writes its own header and bounds: it wrote infinite ones.
    for name in ["out.ply", "out.copc.laz"] {
        let out = dir.path().join(name);
        let o = run(&["export", s(&huge), "-o", s(&out)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{name}: {err}");
        assert!(
            err.contains("metadata.json: its scale 1e308") && err.contains("not a finite number"),
            "{name}: {err}"
        );
        assert!(!out.exists(), "{name}");
    }
    let potree = dir.path().join("potree");
    let o = run(&["export", s(&huge), "--format", "potree2", "-o", s(&potree)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("not a finite number"), "{err}");
    assert!(!potree.exists());
}

#[test]
fn a_las_export_the_las_crate_cannot_close_is_an_error_not_a_panic() {
    // Autzen with x offset 1e9 and two points at the ends of the 32-bit range: the `las`
    // crate's header bounds, floored to the grid, fall one step past 32 bits. Its writer then
    // panicked as it was dropped.
    let dir = tempfile::tempdir().expect("tempdir");
    let mut b = std::fs::read(data("autzen_trim.las")).expect("autzen");
    let offset = 1e9f64;
    b[155..163].copy_from_slice(&offset.to_le_bytes());
    let start = u32::from_le_bytes(b[96..100].try_into().expect("4 bytes")) as usize;
    let len = u16::from_le_bytes(b[105..107].try_into().expect("2 bytes")) as usize;
    for (k, x) in [i32::MIN, i32::MAX].into_iter().enumerate() {
        b[start + k * len..start + k * len + 4].copy_from_slice(&x.to_le_bytes());
    }
    let (lo, hi) = (
        offset - 0.01 * 2f64.powi(31),
        offset + 0.01 * f64::from(i32::MAX),
    );
    b[179..187].copy_from_slice(&hi.to_le_bytes());
    b[187..195].copy_from_slice(&lo.to_le_bytes());
    let input = dir.path().join("ends.las");
    std::fs::write(&input, &b).expect("write");
    let ds = dir.path().join("ds");
    run_ok(&["convert", s(&input), "-o", s(&ds), "-q"]);
    for ext in ["las", "laz"] {
        let out = dir.path().join(format!("back.{ext}"));
        let o = run(&["export", s(&ds), "-o", s(&out)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(
            err.contains("cannot finish the LAS header") && !err.contains("panicked"),
            "{err}"
        );
        assert!(!out.exists(), "no output that looks valid");
    }
    // PLY holds them.
    run_ok(&["export", s(&ds), "-o", s(&dir.path().join("back.ply"))]);
}

#[test]
fn a_one_chunk_laz_whose_chunk_size_would_take_gigabytes_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let small = dir.path().join("small.laz");
    run_ok(&["synth", "--points", "2000", "-o", s(&small)]);
    let orig = std::fs::read(&small).expect("synth laz");
    let vlr = laszip_vlr_body(&orig);
    // One chunk of 2,000 points: the decoder reserved chunk size x record length (an abort
    // on 2^31 points of 34 bytes).
    for size in [0x8000_0000u32, 0x00ff_c350] {
        let mut b = orig.clone();
        b[vlr + 12..vlr + 16].copy_from_slice(&size.to_le_bytes());
        let p = written(dir.path(), &format!("chunk{size}.laz"), &b);
        let err = convert_fails(&p, "more than the 2000 points the file holds");
        assert!(err.contains("the decoder would reserve"), "{err}");
    }
    // 0 declares variable-size chunks (as 2^32 - 1 does): the fixed table then reads as
    // garbage, and the message says which two disagree.
    let mut b = orig.clone();
    b[vlr + 12..vlr + 16].copy_from_slice(&0u32.to_le_bytes());
    let p = written(dir.path(), "chunk0.laz", &b);
    convert_fails(
        &p,
        "variable-size chunks the laszip VLR's chunk size declares",
    );
    // Writers' 50,000 for a file of fewer points is the usual case, and reads.
    let mut b = orig.clone();
    b[vlr + 12..vlr + 16].copy_from_slice(&50_000u32.to_le_bytes());
    let p = written(dir.path(), "usual.laz", &b);
    run_ok(&["convert", s(&p), "-o", s(&dir.path().join("usual.strata"))]);
}

#[test]
fn a_las_offset_that_swallows_the_scale_is_refused_and_a_fine_scale_far_away_is_not() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut b = std::fs::read(data("autzen_trim.las")).expect("autzen");
    // X offset 1e308 with a scale of 0.01: every record's x the same number.
    b[155..163].copy_from_slice(&1e308f64.to_le_bytes());
    let p = written(dir.path(), "far.las", &b);
    convert_fails(
        &p,
        "header field \"x offset\" is 1e308, so large that the steps of the scale factor",
    );
    // A scale of 1e-9 beside an offset of 5e6 (a small float cloud far from the origin, as
    // an export writes it) loses no record's place: it converts.
    for a in 0..3 {
        b[131 + 8 * a..139 + 8 * a].copy_from_slice(&1e-9f64.to_le_bytes());
        b[155 + 8 * a..163 + 8 * a].copy_from_slice(&5e6f64.to_le_bytes());
    }
    // Bounds that hold the records (2^31 steps of 1e-9 reach 2.1 either side).
    for a in 0..3 {
        b[179 + 16 * a..187 + 16 * a].copy_from_slice(&(5e6f64 + 3.0).to_le_bytes());
        b[187 + 16 * a..195 + 16 * a].copy_from_slice(&(5e6f64 - 3.0).to_le_bytes());
    }
    let p = written(dir.path(), "fine.las", &b);
    run_ok(&["convert", s(&p), "-o", s(&dir.path().join("fine.strata"))]);
}

#[test]
fn a_temp_dir_that_is_a_file_or_a_link_to_nothing_is_refused_before_the_run() {
    let dir = tempfile::tempdir().expect("tempdir");
    let file = dir.path().join("not-a-folder");
    std::fs::write(&file, b"x").expect("write");
    // A link to nothing: `exists` is false, and the run failed on a path under it.
    let dangling = dir.path().join("gone");
    std::os::unix::fs::symlink(dir.path().join("nowhere"), &dangling).expect("symlink");
    let (input, out) = (data("autzen_trim.las"), dir.path().join("ds"));
    for temp in [&file, &dangling] {
        let args = ["convert", s(&input), "-o", s(&out), "--temp-dir", s(temp)];
        refused(&args, &["--temp-dir", "is not a folder"]);
        assert!(!out.exists(), "{temp:?}: no dataset");
    }
}

/// The folders of a --temp-dir that did not exist are made for the run and removed with its
/// work, whether it succeeds or fails before it could be resumed; they were left behind, empty.
/// A folder that existed stays.
#[test]
fn the_temp_dir_folders_a_run_makes_go_with_its_work() {
    let dir = tempfile::tempdir().expect("tempdir");
    let input = data("autzen_trim.las");
    let kept = dir.path().join("kept");
    std::fs::create_dir(&kept).expect("mkdir");
    let bad = written(dir.path(), "bad.las", b"not a LAS file at all");
    let runs = [
        (&input, kept.join("a/b"), "good"),
        (&bad, dir.path().join("c/d"), "failed"),
        // Through `..`: `gone` is made and goes; `kept`, missing as written, stays.
        (&input, dir.path().join("gone/../kept"), "good2"),
    ];
    for (input, temp, out) in runs {
        let out = dir.path().join(out);
        let args = [
            "convert",
            s(input),
            "-o",
            s(&out),
            "--temp-dir",
            s(&temp),
            "-q",
        ];
        let ok = common::run(&args).status.success();
        assert_eq!(ok, !out.ends_with("failed"), "{input:?}");
    }
    let mut left: Vec<_> = std::fs::read_dir(dir.path())
        .expect("list")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["bad.las", "good", "good2", "kept"]);
    assert_eq!(std::fs::read_dir(&kept).expect("list").count(), 0);
}

/// `bytes` written to `dir/name`.
fn written(dir: &std::path::Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).expect("write");
    path
}

#[test]
fn a_layered_laz_chunk_that_runs_out_is_named() {
    // Format 7 exported as LAZ: layered chunks, whose decoder reads every field's stream with
    // the first point. Zeroed inside the first chunk, a stream runs out of bytes.
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("pf7.strata");
    let laz = dir.path().join("pf7.laz");
    run_ok(&[
        "convert",
        s(&data("autzen_trim_pf7.las")),
        "-o",
        s(&ds),
        "--quiet",
    ]);
    run_ok(&["export", s(&ds), "-o", s(&laz)]);
    let mut b = std::fs::read(&laz).expect("exported laz");
    assert_eq!(b[104], 0x87, "format 7, compressed");
    b[20_000..24_096].fill(0);
    let p = written(dir.path(), "zeroed.laz", &b);
    convert_fails(&p, "(points 0 to 49999) is corrupt or truncated");
}
