//! A dataset with a damaged node: a render keeps no image with a hole in it, and a pick in
//! that view gives no answer that could be another node's point. A dataset cut short while it
//! is open fails the nodes past its new end, without bringing the process down.

use super::*;

/// A copy of the autzen fixture in `dir`, to damage.
fn autzen_copy(dir: &Path) -> PathBuf {
    let src = fixtures().join("autzen.strata");
    let dataset = dir.join("autzen.strata");
    std::fs::create_dir_all(&dataset).expect("dir");
    for f in ["metadata.json", "hierarchy.bin", "octree.bin"] {
        std::fs::copy(src.join(f), dataset.join(f)).expect("copy");
    }
    dataset
}

/// Flips a byte in the middle of a level-1 node's payload; the node.
fn corrupt_a_level_1_node(dataset: &Path) -> strata_format::NodeInfo {
    let ds = strata_format::LocalDataset::open(dataset).expect("opens");
    let victim = ds
        .all_nodes()
        .expect("nodes")
        .into_iter()
        .find(|n| n.key.level == 1)
        .expect("a level-1 node");
    drop(ds);
    let mut octree = std::fs::read(dataset.join("octree.bin")).expect("read");
    octree[victim.offset as usize + victim.size as usize / 2] ^= 0x5a;
    std::fs::write(dataset.join("octree.bin"), octree).expect("write");
    victim
}

#[test]
fn a_corrupt_node_fails_the_render_and_leaves_no_image() {
    let dir = fixtures().join("corrupt-node");
    let dataset = autzen_copy(&dir);
    let victim = corrupt_a_level_1_node(&dataset);

    let out = dir.join("corrupt.png");
    let st = dir.join("corrupt.json");
    let _ = std::fs::remove_file(&out);
    let o = gpu_run(&[
        "render",
        s(&dataset),
        "-o",
        s(&out),
        "--stats",
        s(&st),
        "--wait-complete",
        "--size",
        "200x150",
    ]);
    let v = stats(&st);
    assert_eq!(v["frames"][0]["nodes_failed"], 1);
    assert!(v["frames"][0]["points_drawn"].as_u64().unwrap_or(0) > 0);
    let errors = v["errors"].to_string();
    assert!(
        errors.contains(&victim.key.name()),
        "errors {errors} do not name node {}",
        victim.key
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains("checksum"), "{err}");
    assert!(
        err.contains("1 node(s) and 0 hierarchy page(s) could not be loaded"),
        "{err}"
    );
    // The image would show a hole where the node's points belong.
    assert!(!out.exists(), "an image with a hole was kept");
    // A pick in that view could answer with another node's point.
    let o = gpu_run(&[
        "pick",
        s(&dataset),
        "--pixel",
        "100,75",
        "--size",
        "200x150",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("could not be loaded, so a pick could name the wrong point"),
        "{err}"
    );
}

/// `octree.bin` truncated after the dataset was opened (a conversion or a copy writing over it
/// while the window shows it): the nodes past the cut fail with an error naming the file. Its
/// pages were memory-mapped, and the first read past the cut killed the process (SIGBUS).
#[test]
fn a_dataset_cut_short_while_open_fails_its_nodes_without_a_crash() {
    let dataset = autzen_copy(&fixtures().join("cut-short"));
    let ds = StreamDataset::open_path(&dataset).expect("opens");
    let nodes = strata_format::LocalDataset::open(&dataset)
        .expect("opens")
        .all_nodes()
        .expect("nodes");
    // Not the root, which the dataset kept from its opening.
    let last = *nodes
        .iter()
        .filter(|n| n.key.level > 0)
        .max_by_key(|n| n.offset)
        .expect("a node below the root");
    let octree = std::fs::OpenOptions::new()
        .write(true)
        .open(dataset.join("octree.bin"))
        .expect("open to cut");
    octree.set_len(last.offset + 1).expect("cut short");
    let err = match ds.load_node(&last, Default::default(), &Default::default()) {
        Ok(_) => panic!("a node past the end loaded"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains("octree.bin"), "{err}");
}

/// The window names the nodes that failed and why (in its panel, and once each on stderr for
/// the log), where it showed only their count.
#[test]
fn the_window_says_which_nodes_failed_and_why() {
    if !common::have_xvfb() {
        return;
    }
    let dir = fixtures().join("window-failures");
    let dataset = autzen_copy(&dir);
    let victim = corrupt_a_level_1_node(&dataset);
    let shot = dir.join("window.png");
    let backend = std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "vulkan".into());
    let o = std::process::Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1400x900x24"])
        .arg(env!("CARGO_BIN_EXE_strata"))
        .args(["view", s(&dataset), "--size", "800x500", "--screenshot"])
        .arg(&shot)
        .args(["--screenshot-after", "20"])
        .env("WGPU_BACKEND", backend)
        .output()
        .expect("xvfb-run runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "view failed: {err}");
    assert_eq!(err.matches("warning:").count(), 1, "{err}");
    assert!(err.contains(&victim.key.name()), "{err}");
    assert!(err.contains("checksum"), "{err}");
}
