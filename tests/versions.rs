//! Format 1.1 as SPEC.md states it, on real converted datasets: nodes without points have no
//! payload, the root page follows the hierarchy head, proxies locate both their node and their
//! page, the three files carry one dataset id and a mix is refused, totals count every node
//! once, 1.0 datasets still open, verify and read, and a newer minor version is refused.

mod common;
use common::*;
use std::path::{Path, PathBuf};
use strata_format::{
    HIERARCHY_HEAD_SIZE, HierarchyHead, Layout, LocalDataset, NodeInfo, ROOT_PAGE_OFFSET,
    decode_page, verify_dataset,
};
use strata_viewer::{HttpOptions, StreamDataset};

fn deep() -> PathBuf {
    deep_dataset("versions")
}

/// A copy of dataset `src` at `dst`, for tests that damage it.
fn copy_dataset(src: &Path, dst: &Path) -> PathBuf {
    let _ = std::fs::remove_dir_all(dst);
    std::fs::create_dir_all(dst).expect("dir");
    for f in ["metadata.json", "hierarchy.bin", "octree.bin"] {
        std::fs::copy(src.join(f), dst.join(f)).expect("copy");
    }
    dst.to_path_buf()
}

fn scratch(name: &str) -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("versions")
        .join(name)
}

/// Every page of a dataset, read from the root.
fn pages(ds: &LocalDataset) -> Vec<strata_format::HierarchyPage> {
    let mut out = Vec::new();
    let mut todo = vec![ds.root_page()];
    while let Some(p) = todo.pop() {
        let page = ds.load_page(&p).expect("page");
        todo.extend(page.child_pages());
        out.push(page);
    }
    out
}

#[test]
fn nodes_without_points_have_no_payload_and_every_total_counts_them() {
    let ds = LocalDataset::open(&deep()).expect("opens");
    let nodes = ds.all_nodes().expect("nodes");
    let empty: Vec<&NodeInfo> = nodes.iter().filter(|n| n.point_count == 0).collect();
    assert!(
        !empty.is_empty(),
        "the deep fixture has inner nodes without points"
    );
    for n in &empty {
        assert_eq!((n.offset, n.size, n.checksum), (0, 0, 0), "node {}", n.key);
        assert_eq!(ds.read_node(n).expect("reads").count, 0);
    }
    let meta = ds.metadata();
    assert_eq!(nodes.len() as u64, meta.nodes);
    let report = verify_dataset(&deep());
    assert!(report.is_ok(), "{:?}", report.faults);
    assert_eq!(report.nodes_checked, meta.nodes);
    assert_eq!(report.empty_nodes, empty.len() as u64);
    let out = run_ok(&["verify", s(&deep())]);
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        said.contains(&format!(
            "{} nodes ({} without points)",
            meta.nodes,
            empty.len()
        )),
        "{said}"
    );
}

#[test]
fn the_root_page_follows_the_head_which_states_its_size() {
    let dir = deep();
    let ds = LocalDataset::open(&dir).expect("opens");
    let meta = ds.metadata();
    assert_eq!(meta.version, [1, 1]);
    let file = std::fs::read(dir.join("hierarchy.bin")).expect("read");
    assert_eq!(&file[..8], b"STRHY1.1");
    let head = HierarchyHead::decode(&file).expect("head");
    assert_eq!(Some(head.id), meta.id);
    assert_eq!(meta.hierarchy.root_page_offset, ROOT_PAGE_OFFSET);
    assert_eq!(ROOT_PAGE_OFFSET, HIERARCHY_HEAD_SIZE);
    assert_eq!(head.root_page_size as u64, meta.hierarchy.root_page_size);
    // A reader with only the file's first bytes (no metadata.json) decodes the root page.
    let root = strata_format::PageRef {
        root: strata_format::NodeKey::ROOT,
        offset: ROOT_PAGE_OFFSET,
        size: head.root_page_size as u64,
        checksum: None,
    };
    let end = (ROOT_PAGE_OFFSET + head.root_page_size as u64) as usize;
    let page = decode_page(&file[32..end], &root, head.page_levels, Layout::V1_1).expect("page");
    assert_eq!(
        page.root_node().map(|n| n.point_count),
        Some(pages(&ds)[0].entries[0].1.point_count)
    );
    let octree = std::fs::read(dir.join("octree.bin")).expect("read");
    assert_eq!(&octree[..8], b"STROC1.1");
    assert_eq!(&octree[8..24], &head.id.0);
    let info = run_ok(&["info", s(&dir)]);
    let said = String::from_utf8_lossy(&info.stdout);
    assert!(
        said.contains("strata-lpc 1.1") && said.contains(&head.id.to_string()),
        "{said}"
    );
}

#[test]
fn a_proxy_locates_its_node_and_its_page_so_both_can_be_read_at_once() {
    let ds = LocalDataset::open(&deep()).expect("opens");
    let all = pages(&ds);
    let mut proxies = 0;
    for page in &all {
        for proxy in page.proxies() {
            proxies += 1;
            let node = proxy.node.expect("1.1 proxies carry their node");
            // The node's payload, read without its page...
            let cols = ds
                .read_node(&node)
                .expect("payload reads from the proxy alone");
            assert_eq!(cols.count, node.point_count as usize);
            // ...and its page, which starts with the same node.
            let below = ds.load_page(&proxy.page).expect("page");
            assert_eq!(below.root_node(), Some(node), "{}", proxy.key);
        }
    }
    assert!(
        proxies >= 2,
        "the deep fixture spans several pages ({proxies} proxies)"
    );
    assert!(
        ds.metadata().depth >= 9,
        "two levels of pages below the root"
    );
}

#[test]
fn files_of_another_dataset_are_refused_by_every_reader() {
    let other = converted("versions", "autzen_trim.las", "autzen");
    for file in ["octree.bin", "hierarchy.bin"] {
        let mixed = copy_dataset(&deep(), &scratch(&format!("mixed-{file}")));
        std::fs::copy(other.join(file), mixed.join(file)).expect("copy");
        let id = |d: &Path| {
            LocalDataset::open(d)
                .expect("opens")
                .metadata()
                .id
                .expect("id")
                .to_string()
        };
        let want = format!(
            "{file}: belongs to another dataset (id {}, metadata.json says {})",
            id(&other),
            id(&deep())
        );
        for args in [["info", s(&mixed)], ["verify", s(&mixed)]] {
            let o = run(&args);
            let err = String::from_utf8_lossy(&o.stderr);
            assert!(!o.status.success(), "{args:?}");
            assert!(err.contains(&want), "{args:?} said {err}");
        }
        let viewer = StreamDataset::open(s(&mixed), HttpOptions::default());
        let err = viewer.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(err.contains(&want), "the viewer said {err}");
    }
}

#[test]
fn files_of_the_other_layout_are_refused_naming_both_versions() {
    let old = scratch("layout-1.0");
    let _ = std::fs::remove_dir_all(&old);
    strata_format::v1_0::rewrite_as_1_0(&deep(), &old).expect("rewrites");
    let mixed = copy_dataset(&deep(), &scratch("layout-mixed"));
    std::fs::copy(old.join("hierarchy.bin"), mixed.join("hierarchy.bin")).expect("copy");
    let o = run(&["info", s(&mixed)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("hierarchy.bin: is a format 1.0 file but metadata.json says format 1.1"),
        "{err}"
    );
}

#[test]
fn a_1_0_dataset_still_opens_verifies_and_reads_the_same_points() {
    let old = scratch("deep-1.0");
    let _ = std::fs::remove_dir_all(&old);
    strata_format::v1_0::rewrite_as_1_0(&deep(), &old).expect("rewrites");
    assert_eq!(
        &std::fs::read(old.join("hierarchy.bin")).expect("read")[..8],
        b"STRATAHY"
    );
    let info = run_ok(&["info", s(&old)]);
    assert!(String::from_utf8_lossy(&info.stdout).contains("strata-lpc 1.0"));
    let verify = run_ok(&["verify", s(&old)]);
    assert!(String::from_utf8_lossy(&verify.stdout).contains("format 1.0, no id"));
    let (a, b) = (
        LocalDataset::open(&deep()).expect("1.1"),
        LocalDataset::open(&old).expect("1.0"),
    );
    assert_eq!(b.metadata().layout(), Layout::V1_0);
    let (na, nb) = (a.all_nodes().expect("1.1"), b.all_nodes().expect("1.0"));
    assert_eq!(na.len(), nb.len());
    let viewer_old = StreamDataset::open_path(&old).expect("the viewer opens 1.0");
    let viewer_new = StreamDataset::open_path(&deep()).expect("the viewer opens 1.1");
    for (x, y) in na.iter().zip(&nb) {
        assert_eq!(
            (x.key, x.point_count, x.child_mask),
            (y.key, y.point_count, y.child_mask)
        );
        let (cx, cy) = (
            a.read_node(x).expect("1.1 node"),
            b.read_node(y).expect("1.0 node"),
        );
        assert_eq!(cx.bytes, cy.bytes, "node {}", x.key);
        let (gx, gy) = (
            viewer_new
                .load_node(
                    x,
                    strata_viewer::dataset::ColourWord::Stored,
                    &Default::default(),
                )
                .expect("viewer 1.1"),
            viewer_old
                .load_node(
                    y,
                    strata_viewer::dataset::ColourWord::Stored,
                    &Default::default(),
                )
                .expect("viewer 1.0"),
        );
        assert_eq!(gx.points, gy.points, "node {}", x.key);
    }
    // The viewer's hierarchy: a 1.0 proxy is known only once its page is read.
    let root_old = viewer_old.root_hierarchy_page();
    assert!(root_old.proxies().all(|p| p.node.is_none()));
    let export = old.with_extension("las");
    run_ok(&["export", s(&old), "-o", s(&export), "--overwrite"]);
}

#[test]
fn a_newer_minor_version_is_refused_naming_it() {
    let newer = copy_dataset(&deep(), &scratch("newer-minor"));
    let meta_path = newer.join("metadata.json");
    let mut v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&meta_path).expect("read")).expect("json");
    v["version"] = serde_json::json!([1, 2]);
    std::fs::write(&meta_path, v.to_string()).expect("write");
    let want = "metadata.json: dataset format version 1.2 is not supported by this reader (it reads 1.0 to 1.1)";
    for args in [["info", s(&newer)], ["verify", s(&newer)]] {
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(want), "{args:?}: {err}");
    }
    let viewer = StreamDataset::open_path(&newer)
        .err()
        .map(|e| e.to_string());
    assert!(viewer.unwrap_or_default().contains(want));
}
