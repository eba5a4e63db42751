//! Format versions over HTTP: a dataset whose files belong to two datasets is refused at open,
//! a 1.0 dataset and one with nodes without points render over HTTP as from disk.

use super::{Server, fixtures, render_pair, root};
use crate::common::deep_dataset;
use std::path::{Path, PathBuf};
use strata_format::LocalDataset;
use strata_viewer::{HttpOptions, StreamDataset};

/// A directory to serve holding `name` made by `make`, once.
fn served(name: &str, make: impl FnOnce(&Path)) -> PathBuf {
    let dir = fixtures().join("versions-root");
    let ds = dir.join(name);
    if !ds.exists() {
        std::fs::create_dir_all(&dir).expect("dir");
        make(&ds);
    }
    dir
}

fn copy_dataset(src: &Path, dst: &Path) {
    std::fs::create_dir_all(dst).expect("dir");
    for f in ["metadata.json", "hierarchy.bin", "octree.bin"] {
        std::fs::copy(src.join(f), dst.join(f)).expect("copy");
    }
}

fn id(dir: &Path) -> String {
    let ds = LocalDataset::open(dir).expect("opens");
    ds.metadata().id.map(|i| i.to_string()).unwrap_or_default()
}

#[test]
fn files_of_two_datasets_are_refused_over_http() {
    let dir = served("mixed.strata", |ds| {
        copy_dataset(&root().join("city.strata"), ds);
        std::fs::copy(
            root().join("autzen.strata/octree.bin"),
            ds.join("octree.bin"),
        )
        .expect("copy");
    });
    let server = Server::start_in(&dir, &["--quiet"]);
    let err = StreamDataset::open(&server.url("mixed.strata"), HttpOptions::default())
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    let want = format!(
        "/mixed.strata/octree.bin: belongs to another dataset (id {}, metadata.json says {})",
        id(&root().join("autzen.strata")),
        id(&root().join("city.strata"))
    );
    assert!(err.contains(&want), "the viewer said {err}");
}

#[test]
fn a_1_0_dataset_and_nodes_without_points_render_over_http_as_from_disk() {
    served("city-1.0.strata", |ds| {
        strata_format::v1_0::rewrite_as_1_0(&root().join("city.strata"), ds).expect("rewrites");
    });
    let dir = served("deep.strata", |ds| copy_dataset(&deep_dataset("serve"), ds));
    let server = Server::start_in(&dir, &["--quiet"]);
    render_pair(
        &server.url("city-1.0.strata"),
        &dir.join("city-1.0.strata"),
        "v1.0",
        &[],
    );
    render_pair(
        &server.url("deep.strata"),
        &dir.join("deep.strata"),
        "deep",
        &[],
    );
}
