//! Files that are not what they seem: a device or a pipe where a small text file is named, and
//! a disk that fills while a file is written.

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
