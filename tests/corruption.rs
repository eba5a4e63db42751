//! A flipped byte anywhere in a node or the hierarchy is found, and the damaged part named,
//! once: not again as bounds the skipped node's points no longer reach. What `metadata.json`
//! says of the points (their classes, the spacing its cube gives) is checked against them.

mod common;
use common::*;
use std::path::Path;

fn dataset(dir: &Path) -> std::path::PathBuf {
    let ds = dir.join("ds");
    run_ok(&["convert", s(&data("autzen_trim.las")), "-o", s(&ds), "-q"]);
    ds
}

fn flip(path: &Path, at: u64) {
    let mut bytes = std::fs::read(path).expect("read");
    bytes[at as usize] ^= 0x10;
    std::fs::write(path, bytes).expect("write");
}

fn verify_fails_naming(ds: &Path, part: &str) {
    let o = run(&["verify", s(ds)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "verify must exit 1: {err}");
    assert!(
        err.contains(part),
        "verify should name {part:?}, said: {err}"
    );
    assert!(!err.contains("panicked"));
}

#[test]
fn every_node_payload_flip_is_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dataset(dir.path());
    let local = strata_format::LocalDataset::open(&ds).expect("opens");
    let nodes = local.all_nodes().expect("nodes");
    drop(local);
    assert!(nodes.len() > 5);
    for n in nodes.iter().filter(|n| n.size > 0) {
        for at in [
            n.offset,
            n.offset + n.size as u64 / 2,
            n.offset + n.size as u64 - 1,
        ] {
            flip(&ds.join("octree.bin"), at);
            verify_fails_naming(&ds, &format!("node {}", n.key));
            flip(&ds.join("octree.bin"), at);
        }
    }
    assert!(!dir.path().join("pipe.png").exists());
    run_ok(&["verify", s(&ds)]);
}

#[test]
fn every_octree_head_byte_flip_is_caught() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dataset(dir.path());
    for at in 0..strata_format::OCTREE_HEAD_SIZE {
        flip(&ds.join("octree.bin"), at);
        verify_fails_naming(&ds, "octree.bin");
        flip(&ds.join("octree.bin"), at);
    }
}

#[test]
fn every_hierarchy_byte_flip_is_caught() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dataset(dir.path());
    let path = ds.join("hierarchy.bin");
    let len = std::fs::metadata(&path).expect("meta").len();
    for at in 0..len {
        flip(&path, at);
        // The head (magic, dataset id, root page size, page levels) is checked against
        // metadata.json at open; the pages by their checksums.
        let part = if at < strata_format::HIERARCHY_HEAD_SIZE {
            "hierarchy.bin"
        } else {
            "hierarchy page"
        };
        verify_fails_naming(&ds, part);
        flip(&path, at);
    }
    // A page's fault names the file and the page once each.
    flip(&path, strata_format::HIERARCHY_HEAD_SIZE + 1);
    let o = run(&["verify", s(&ds)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.matches("hierarchy page at byte").count(), 1, "{err}");
    assert_eq!(err.matches("hierarchy.bin").count(), 1, "{err}");
}

#[test]
fn truncated_or_missing_files_are_reported() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dataset(dir.path());
    let octree = ds.join("octree.bin");
    let bytes = std::fs::read(&octree).expect("read");
    std::fs::write(&octree, &bytes[..bytes.len() - 100]).expect("write");
    verify_fails_naming(&ds, "octree.bin");
    std::fs::remove_file(ds.join("metadata.json")).expect("remove");
    verify_fails_naming(&ds, "metadata.json");
    // A device or a pipe in its place is refused, not read until memory runs out or a writer
    // comes.
    std::os::unix::fs::symlink("/dev/zero", ds.join("metadata.json")).expect("link");
    verify_fails_naming(&ds, "not a regular file");
    for cmd in ["info", "export"] {
        let out = dir.path().join("out.las");
        let o = run(&[cmd, s(&ds), "-o", s(&out)][..if cmd == "info" { 2 } else { 4 }]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains("metadata.json: is not a regular file"),
            "{cmd}: {err}"
        );
    }
    std::fs::remove_file(ds.join("metadata.json")).expect("remove");
    mkfifo(&ds.join("metadata.json"));
    verify_fails_naming(&ds, "not a regular file");
}

/// A hierarchy cut inside its head, its size in the metadata edited to match: said as a head
/// cut short, not as "8 bytes but metadata.json says 8".
#[test]
fn a_file_cut_inside_its_head_is_said_to_be() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dataset(dir.path());
    let hierarchy = ds.join("hierarchy.bin");
    let bytes = std::fs::read(&hierarchy).expect("read");
    for keep in [8, 20, 28] {
        std::fs::write(&hierarchy, &bytes[..keep]).expect("write");
        edit_metadata(&ds, |m| m["files"]["hierarchy"]["size"] = keep.into());
        verify_fails_naming(
            &ds,
            &format!("is {keep} bytes long, too short for the head"),
        );
    }
}

#[test]
fn data_files_that_are_pipes_are_refused_not_waited_on() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dataset(dir.path());
    for name in ["hierarchy.bin", "octree.bin"] {
        let copy = dir.path().join(format!("pipe-{name}"));
        run_ok(&["convert", s(&data("autzen_trim.las")), "-o", s(&copy), "-q"]);
        std::fs::remove_file(copy.join(name)).expect("remove");
        mkfifo(&copy.join(name));
        // Bounded: opening a pipe for reading waits for a writer that never comes.
        let png = dir.path().join("pipe.png");
        for cmd in ["verify", "info", "render"] {
            let mut args = vec![cmd, s(&copy)];
            if cmd == "render" {
                args.extend(["-o", s(&png), "--size", "64x48"]);
            }
            let o = run_bounded(&args);
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(1), "{cmd} on a pipe {name}: {err}");
            assert!(
                err.contains(&format!("{name}: is not a regular file")),
                "{cmd}: {err}"
            );
        }
    }
    run_ok(&["verify", s(&ds)]);
}

#[test]
fn newer_major_versions_are_refused_clearly() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dataset(dir.path());
    let meta_path = ds.join("metadata.json");
    let mut v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&meta_path).expect("read")).expect("json");
    v["version"] = serde_json::json!([2, 0]);
    std::fs::write(&meta_path, v.to_string()).expect("write");
    let o = run(&["info", s(&ds)]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("version 2.0 is not supported"));
}

/// Every export of `ds` fails with `says` in its message and leaves nothing named `out*`.
fn every_export_refuses(ds: &Path, dir: &Path, says: &str) {
    let targets: [(&str, &[&str]); 4] = [
        ("out.ply", &[]),
        ("out.las", &[]),
        ("out.copc.laz", &[]),
        ("out_potree", &["--format", "potree2"]),
    ];
    for (name, extra) in targets {
        let out = dir.join(name);
        let mut args = vec!["export", s(ds), "-o", s(&out)];
        args.extend_from_slice(extra);
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{name}: exported");
        assert!(err.contains(says), "{name}: {err}");
        let leftovers: Vec<_> = std::fs::read_dir(dir)
            .expect("list")
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with("out"))
            .collect();
        assert!(leftovers.is_empty(), "{name}: {leftovers:?}");
    }
}

fn edit_metadata(ds: &Path, edit: impl FnOnce(&mut serde_json::Value)) {
    let meta_path = ds.join("metadata.json");
    let mut meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&meta_path).expect("read")).expect("json");
    edit(&mut meta);
    std::fs::write(&meta_path, meta.to_string()).expect("write");
}

#[test]
fn an_export_of_a_dataset_whose_count_is_wrong_leaves_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dataset(dir.path());
    let mut points = 0;
    edit_metadata(&ds, |meta| {
        points = meta["points"].as_u64().expect("points");
        meta["points"] = (points + 1).into();
    });
    let says = format!(
        "metadata.json: says the dataset holds {} points, but its nodes hold {points}",
        points + 1
    );
    every_export_refuses(&ds, dir.path(), &says);
}

/// Points stored in nodes whose cubes do not hold them (here the cube moved): the exports
/// that place points by their node (COPC, Potree 2) would lose or misplace them.
#[test]
fn an_export_of_points_outside_their_nodes_leaves_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dataset(dir.path());
    // The bounds move with the cube, as a consistent metadata.json would say: the points
    // alone are out of place.
    edit_metadata(&ds, |meta| {
        let x = meta["cube"]["min"][0].as_i64().expect("cube min");
        meta["cube"]["min"][0] = (x + 1000).into();
        let shift = 1000.0 * meta["scale"][0].as_f64().expect("scale");
        for end in ["min", "max"] {
            let b = meta["bounds"][end][0].as_f64().expect("bounds");
            meta["bounds"][end][0] = (b + shift).into();
        }
    });
    verify_fails_naming(&ds, "lies outside the node's cube");
    for (name, says) in [
        ("out.copc.laz", "inside their nodes' cubes"),
        ("out_potree", "lies outside the node's cube"),
    ] {
        let out = dir.path().join(name);
        let mut args = vec!["export", s(&ds), "-o", s(&out)];
        if name == "out_potree" {
            args.extend(["--format", "potree2"]);
        }
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(says), "{name}: {err}");
        assert!(!out.exists());
    }
}

#[test]
fn an_attribute_of_an_unknown_encoding_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dataset(dir.path());
    edit_metadata(&ds, |meta| {
        meta["attributes"][0]["encoding"] = "zz".into();
    });
    verify_fails_naming(&ds, "has encoding \"zz\", which this reader does not know");
    let o = run(&["info", s(&ds)]);
    assert!(!o.status.success());
}

#[test]
fn bounds_other_than_the_points_extent_are_reported() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dataset(dir.path());
    edit_metadata(&ds, |meta| {
        let x = meta["bounds"]["max"][0].as_f64().expect("bounds");
        meta["bounds"]["max"][0] = (x - 10.0).into();
    });
    verify_fails_naming(&ds, "gives bounds");
}

/// Bounds no stored point could have (beyond the root cube): a view fitted to them would show
/// nothing, so the dataset is refused at open, by every command.
#[test]
fn bounds_beyond_the_root_cube_are_refused_at_open() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dataset(dir.path());
    edit_metadata(&ds, |meta| {
        meta["bounds"]["max"][0] = 1e308.into();
    });
    let says = "x bounds";
    for args in [vec!["info", s(&ds)], vec!["verify", s(&ds)]] {
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains(says) && err.contains("outside the root cube"),
            "{args:?}: {err}"
        );
    }
    every_export_refuses(&ds, dir.path(), "outside the root cube");
}

/// A damaged node is one fault: the points it could not give were counted as the bounds
/// falling short, a second fault against metadata.json.
#[test]
fn a_damaged_node_is_not_also_blamed_on_the_metadata() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dataset(dir.path());
    let local = strata_format::LocalDataset::open(&ds).expect("opens");
    let nodes = local.all_nodes().expect("nodes");
    drop(local);
    for n in nodes.iter().filter(|n| n.size > 0) {
        flip(&ds.join("octree.bin"), n.offset + n.size as u64 / 2);
        let o = run(&["verify", s(&ds)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("1 fault(s) found"), "{}: {err}", n.key);
        assert!(!err.contains("metadata.json"), "{}: {err}", n.key);
        flip(&ds.join("octree.bin"), n.offset + n.size as u64 / 2);
    }
}

/// Class counts and a spacing that are not the points' were passed as "ok" and printed by
/// `info`.
#[test]
fn metadata_that_misstates_the_classes_or_the_spacing_is_a_fault() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dataset(dir.path());
    let path = ds.join("metadata.json");
    let clean = std::fs::read(&path).expect("read");
    let doc: serde_json::Value = serde_json::from_slice(&clean).expect("json");
    assert!(doc["classes"].as_object().is_some_and(|c| !c.is_empty()));
    type Edit = fn(&mut serde_json::Value);
    let edits: [(&str, Edit); 3] = [
        ("counts the points by class", |d| {
            let (_, n) = d["classes"]
                .as_object_mut()
                .and_then(|c| c.iter_mut().next())
                .expect("a class");
            *n = serde_json::json!(n.as_u64().expect("a count") + 5);
        }),
        ("counts the points by class", |d| {
            d["classes"]["9"] = serde_json::json!(12345);
        }),
        ("gives spacing", |d| {
            let v = d["spacing"].as_f64().expect("spacing");
            d["spacing"] = serde_json::json!(v * 10.0);
        }),
    ];
    for (said, edit) in edits {
        let mut d = doc.clone();
        edit(&mut d);
        std::fs::write(&path, serde_json::to_vec(&d).expect("json")).expect("write");
        let o = run(&["verify", s(&ds)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains(said) && err.contains("metadata.json"), "{err}");
    }
    std::fs::write(&path, clean).expect("restore");
    run_ok(&["verify", s(&ds)]);
}
