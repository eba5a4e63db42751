//! A flipped byte anywhere in a node or the hierarchy is found, and the damaged part named.

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
    let fifo = std::process::Command::new("mkfifo")
        .arg(ds.join("metadata.json"))
        .status()
        .expect("mkfifo");
    assert!(fifo.success());
    verify_fails_naming(&ds, "not a regular file");
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

#[test]
fn an_export_of_a_dataset_whose_count_is_wrong_leaves_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dataset(dir.path());
    let meta_path = ds.join("metadata.json");
    let mut meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&meta_path).expect("read")).expect("json");
    let points = meta["points"].as_u64().expect("points");
    meta["points"] = (points + 1).into();
    std::fs::write(&meta_path, meta.to_string()).expect("write");
    for name in ["out.ply", "out.las"] {
        let out = dir.path().join(name);
        let o = run(&["export", s(&ds), "-o", s(&out)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{name}: exported");
        assert!(
            err.contains(&format!(
                "metadata.json: says the dataset holds {} points, but its nodes hold {points}",
                points + 1
            )),
            "{err}"
        );
        let leftovers: Vec<_> = std::fs::read_dir(dir.path())
            .expect("list")
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with("out"))
            .collect();
        assert!(leftovers.is_empty(), "{leftovers:?}");
    }
}
