//! `strata info` on a Potree 2.0 folder (ours and PotreeConverter 2's), and the refusal of a
//! Potree 2.0 output named as a point file.

use super::common;
use common::s;
use serde_json::Value;

/// `strata info` reads a Potree 2.0 dataset's metadata.json as it reads a Strata dataset's: the
/// points, depth, bounds and attributes it states; a damaged field is named in one sentence. A
/// Potree 2.0 output named as a point file (`city.las`) is refused.
#[test]
fn info_describes_a_potree2_dataset_and_a_folder_named_as_a_point_file_is_refused() {
    let dataset = common::converted("potree2-fixture", "autzen_trim.laz", "autzen");
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("autzen");
    common::run_ok(&["export", s(&dataset), "-o", s(&out), "--format", "potree2"]);
    let meta: Value =
        serde_json::from_slice(&std::fs::read(out.join("metadata.json")).expect("metadata"))
            .expect("JSON");
    let text = String::from_utf8_lossy(&common::run_ok(&["info", s(&out)]).stdout).to_string();
    assert!(text.contains("Potree 2.0"), "{text}");
    assert!(
        text.contains(&format!("points    {}", meta["points"])),
        "{text}"
    );
    assert!(text.contains("classification"), "{text}");
    let json: Value =
        serde_json::from_slice(&common::run_ok(&["info", s(&out), "--json"]).stdout).expect("JSON");
    assert_eq!(json["format"], "potree 2.0");
    assert_eq!(json["points"], meta["points"]);
    assert_eq!(json["depth"], meta["hierarchy"]["depth"]);
    assert_eq!(
        json["attributes"].as_array().map(Vec::len),
        meta["attributes"].as_array().map(Vec::len)
    );
    // The points' own bounds lie within the octree's cube.
    assert!(json["bounds"]["min"].is_array(), "{json}");
    for k in 0..3 {
        let (lo, hi) = (&json["bounds"]["min"][k], &json["bounds"]["max"][k]);
        assert!(lo.as_f64() >= json["cube"]["min"][k].as_f64(), "{json}");
        assert!(hi.as_f64() <= json["cube"]["max"][k].as_f64(), "{json}");
    }
    // A folder named as a point file is refused before anything is written, by export and by
    // convert alike.
    for args in [
        vec!["export", s(&dataset), "-o", "NAME", "--format", "potree2"],
        // An input that does not exist: refused for the name before the input is read.
        vec!["convert", "IN", "-o", "NAME", "--format", "potree2"],
    ] {
        let named = dir.path().join("city.LAS");
        let input = dir.path().join("missing.laz");
        let args: Vec<&str> = args
            .iter()
            .map(|a| match *a {
                "NAME" => s(&named),
                "IN" => s(&input),
                a => a,
            })
            .collect();
        let o = common::run(&args);
        let err = String::from_utf8_lossy(&o.stderr).to_string();
        assert!(!o.status.success(), "{args:?}");
        assert!(err.contains(".las") && err.contains("folder"), "{err}");
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .expect("dir")
            .filter_map(|e| e.ok().map(|e| e.file_name()))
            .filter(|n| n.to_string_lossy().contains("city"))
            .collect();
        assert!(left.is_empty(), "{args:?} left {left:?}");
    }
    let mut damaged = meta.clone();
    damaged["points"] = "many".into();
    std::fs::write(out.join("metadata.json"), damaged.to_string()).expect("write");
    let o = common::run(&["info", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(!o.status.success());
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains("metadata.json") && err.contains("\"points\""),
        "{err}"
    );
}

/// `strata info` on PotreeConverter 2's metadata as it writes it (BROTLI, a projection, a
/// histogram, per-attribute scale), given by its folder or its metadata.json; a metadata.json
/// that is a pipe is refused, not waited on.
#[test]
fn info_reads_potree_converter_metadata_and_refuses_a_pipe() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("converted");
    std::fs::create_dir(&ds).expect("folder");
    let meta = serde_json::json!({
        "version": "2.0", "name": "converted", "description": "", "points": 1234,
        "projection": "+proj=utm +zone=10", "hierarchy": {"firstChunkSize": 22, "stepSize": 4, "depth": 0},
        "offset": [1.0, 2.0, 3.0], "scale": [0.001, 0.001, 0.001], "spacing": 0.5,
        "boundingBox": {"min": [1.0, 2.0, 3.0], "max": [11.0, 12.0, 13.0]}, "encoding": "BROTLI",
        "attributes": [
            {"name": "position", "description": "", "size": 12, "numElements": 3, "elementSize": 4,
             "type": "int32", "min": [1.5, 2.5, 3.5], "max": [9.0, 10.0, 4.0]},
            {"name": "intensity", "description": "", "size": 2, "numElements": 1, "elementSize": 2,
             "type": "uint16", "min": [0], "max": [65535], "scale": [1], "offset": [0],
             "histogram": [1, 2, 3]}
        ]
    });
    std::fs::write(ds.join("metadata.json"), meta.to_string()).expect("write");
    for target in [ds.clone(), ds.join("metadata.json")] {
        let text =
            String::from_utf8_lossy(&common::run_ok(&["info", s(&target)]).stdout).to_string();
        for want in [
            "Potree 2.0, BROTLI",
            "points    1234",
            "+proj=utm",
            "intensity",
            "1.500 2.500 3.500",
            // Only the metadata was written here.
            "hierarchy.bin and octree.bin missing",
        ] {
            assert!(text.contains(want), "{want} not in {text}");
        }
    }
    let piped = dir.path().join("piped");
    std::fs::create_dir(&piped).expect("folder");
    common::mkfifo(&piped.join("metadata.json"));
    // Under `timeout 60`: a run that waits on the pipe ends with 124, not a refusal.
    let o = common::run_bounded(&["info", s(&piped)]);
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert_ne!(o.status.code(), Some(124), "strata info waited on a pipe");
    assert!(!o.status.success());
    assert!(err.contains("not a regular file"), "{err}");
}
