//! What `--overwrite` replaces (a dataset, never a folder holding anything else, nor a file),
//! and what it keeps: the views and measurements the window saved in the dataset it replaces.

mod common;
use common::*;

#[test]
fn existing_output_needs_overwrite() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("ds");
    std::fs::create_dir(&out).expect("mkdir");
    std::fs::write(out.join("keep.txt"), b"mine").expect("write");
    let o = run(&["convert", s(&data("autzen_trim.las")), "-o", s(&out)]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("already exists (pass --overwrite"));
    assert!(
        out.join("keep.txt").exists(),
        "nothing replaced without --overwrite"
    );
    // --overwrite replaces a dataset, never a folder holding anything else, nor a file (the
    // input itself, say), in either output format.
    for format in ["strata", "potree2"] {
        let o = run(&[
            "convert",
            s(&data("autzen_trim.las")),
            "-o",
            s(&out),
            "--overwrite",
            "--format",
            format,
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success(),
            "{format}: a folder of the user's replaced"
        );
        assert!(err.contains("holds \"keep.txt\""), "{err}");
        assert!(
            out.join("keep.txt").exists(),
            "{format}: the user's file was removed"
        );
    }
    let input = dir.path().join("in.las");
    std::fs::copy(data("autzen_trim.las"), &input).expect("copy");
    let o = run(&["convert", s(&input), "-o", s(&input), "--overwrite"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("is a file, not a folder"));
    assert_eq!(
        std::fs::metadata(&input).expect("input").len(),
        std::fs::metadata(data("autzen_trim.las"))
            .expect("autzen")
            .len()
    );
    std::fs::remove_file(out.join("keep.txt")).expect("rm");
    for _ in 0..2 {
        run_ok(&[
            "convert",
            s(&data("autzen_trim.las")),
            "-o",
            s(&out),
            "--overwrite",
            "-q",
        ]);
        run_ok(&["verify", s(&out)]);
    }
    let o = run(&[
        "export",
        s(&out),
        "-o",
        s(dir.path()),
        "--format",
        "potree2",
        "--overwrite",
    ]);
    assert!(
        !o.status.success(),
        "export replaced a folder of the user's"
    );
    assert!(input.exists() && out.join("metadata.json").exists());
    // A --stats file that cannot be written is refused before the conversion, not after.
    let fresh = dir.path().join("fresh");
    let o = run(&[
        "convert",
        s(&data("autzen_trim.las")),
        "-o",
        s(&fresh),
        "--stats",
        s(&dir.path().join("no/such/folder/s.json")),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("cannot write the --stats file"));
    assert!(!fresh.exists());
    // Inside the output, which exists only at the end, it is written then.
    let stats = fresh.join("stats.json");
    run_ok(&[
        "convert",
        s(&data("autzen_trim.las")),
        "-o",
        s(&fresh),
        "--stats",
        s(&stats),
        "-q",
    ]);
    assert!(
        std::fs::read_to_string(&stats)
            .expect("stats")
            .contains("\"points\"")
    );
    // An input, or one of the dataset's own files, was written over and the run said ok.
    let input = dir.path().join("in.las");
    std::fs::copy(data("autzen_trim.las"), &input).expect("copy");
    let again = dir.path().join("again");
    for stats in [input.clone(), again.join("metadata.json")] {
        common::refused(
            &["convert", s(&input), "-o", s(&again), "--stats", s(&stats)],
            &["the --stats file would be written over"],
        );
        assert!(!again.exists());
    }
    assert_eq!(
        std::fs::read(&input).expect("read"),
        std::fs::read(data("autzen_trim.las")).expect("read")
    );
}

/// The views and measurements the window saved in a dataset's folder are the user's, of the
/// scene: converting it again over itself keeps them, where `--overwrite` deleted them.
#[test]
fn overwriting_a_dataset_keeps_the_views_and_measurements_saved_in_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("ds");
    run_ok(&["convert", s(&data("autzen_trim.las")), "-o", s(&out), "-q"]);
    let saved = [
        ("bookmarks.json", "{\"views\": []}\n"),
        (
            "measurements.geojson",
            "{\"type\": \"FeatureCollection\", \"features\": []}\n",
        ),
    ];
    for (name, body) in saved {
        std::fs::write(out.join(name), body).expect("save");
    }
    run_ok(&[
        "convert",
        s(&data("autzen_trim.las")),
        "-o",
        s(&out),
        "-q",
        "--overwrite",
        "--normals",
    ]);
    for (name, body) in saved {
        let kept = std::fs::read_to_string(out.join(name)).expect("kept");
        assert_eq!(kept, body, "{name}");
    }
    run_ok(&["verify", s(&out)]);
}
