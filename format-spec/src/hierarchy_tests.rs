//! Hierarchy pages in both layouts: every node round-trips, every flipped byte is caught, and
//! the 1.1 page carries what SPEC.md section 5 says it does.

use crate::*;
use std::collections::BTreeMap;

/// A chain of nodes 12 levels deep, with a sibling at each level, spans several pages; the
/// node at level 3 has no points.
fn deep_tree() -> BTreeMap<NodeKey, NodeRecord> {
    let mut nodes = BTreeMap::new();
    let mut k = NodeKey::ROOT;
    for level in 0..12u32 {
        let mask = if level < 11 { 0b1000_0001 } else { 0 };
        let points = if level == 3 { 0 } else { 100 + level };
        nodes.insert(
            k,
            NodeRecord {
                point_count: points,
                offset: 24 + level as u64 * 1000,
                size: 500,
                checksum: level,
                child_mask: mask,
            },
        );
        if level < 11 {
            nodes.insert(
                k.child(7),
                NodeRecord {
                    point_count: 1,
                    offset: 99,
                    size: 10,
                    checksum: 7,
                    child_mask: 0,
                },
            );
        }
        k = k.child(0);
    }
    nodes
}

fn root_ref(built: &BuiltHierarchy) -> PageRef {
    PageRef {
        root: NodeKey::ROOT,
        offset: built.root_page_offset,
        size: built.root_page_size,
        checksum: None,
    }
}

/// Every page of `file`, read from the root.
fn all_pages(file: &[u8], built: &BuiltHierarchy) -> Vec<HierarchyPage> {
    let mut out = Vec::new();
    let mut pages = vec![root_ref(built)];
    while let Some(p) = pages.pop() {
        let bytes = &file[p.offset as usize..(p.offset + p.size) as usize];
        let page = decode_page(bytes, &p, PAGE_LEVELS, built.layout).expect("page decodes");
        pages.extend(page.child_pages());
        out.push(page);
    }
    out
}

#[test]
fn pages_round_trip_every_node_once_in_both_layouts() {
    let nodes = deep_tree();
    for layout in [Layout::V1_0, Layout::V1_1] {
        let built = build_hierarchy(&nodes, PAGE_LEVELS, layout);
        let file = built.file(DatasetId([1; 16]));
        let pages = all_pages(&file, &built);
        assert!(pages.len() >= 3, "12 levels need at least 3 pages of 5");
        assert_eq!(pages.len(), built.page_count);
        let mut found = BTreeMap::new();
        for page in &pages {
            for n in page.own_nodes() {
                assert!(found.insert(n.key, n).is_none(), "{} twice", n.key);
            }
        }
        assert_eq!(found.len(), nodes.len(), "{layout:?}");
        for (k, rec) in &nodes {
            let n = found[k];
            assert_eq!(
                (n.point_count, n.child_mask),
                (rec.point_count, rec.child_mask)
            );
            if rec.point_count > 0 || layout == Layout::V1_0 {
                assert_eq!(
                    (n.offset, n.size, n.checksum),
                    (rec.offset, rec.size, rec.checksum)
                );
            }
        }
    }
}

#[test]
fn a_1_1_node_without_points_has_offset_size_and_checksum_zero() {
    let built = build_hierarchy(&deep_tree(), PAGE_LEVELS, Layout::V1_1);
    let file = built.file(DatasetId([1; 16]));
    let empty = all_pages(&file, &built)
        .iter()
        .flat_map(|p| p.own_nodes().collect::<Vec<_>>())
        .find(|n| n.point_count == 0)
        .expect("the level-3 node");
    assert_eq!((empty.offset, empty.size, empty.checksum), (0, 0, 0));
}

#[test]
fn the_1_1_root_page_follows_the_head_and_pages_have_their_stated_size() {
    let nodes = deep_tree();
    let built = build_hierarchy(&nodes, PAGE_LEVELS, Layout::V1_1);
    let id = DatasetId([9; 16]);
    let file = built.file(id);
    assert_eq!(built.root_page_offset, ROOT_PAGE_OFFSET);
    let head = HierarchyHead::decode(&file).expect("head");
    assert_eq!(head.id, id);
    assert_eq!(head.root_page_size as u64, built.root_page_size);
    assert_eq!(head.page_levels, PAGE_LEVELS);
    let pages = all_pages(&file, &built);
    let total: u64 = pages
        .iter()
        .map(|p| page_size(p.entries.len(), p.children.len()))
        .sum();
    assert_eq!(
        HIERARCHY_HEAD_SIZE + total,
        file.len() as u64,
        "pages fill the file"
    );
    // The chain's root page: levels 0-4, with the level-4 chain node its one proxy.
    let root = &pages[0];
    assert_eq!(root.entries.len(), 9);
    assert_eq!(root.children.len(), 1);
    assert_eq!(built.root_page_size, 8 + 9 * 24 + 16);
}

#[test]
fn a_1_1_proxy_locates_both_its_node_and_its_page() {
    let nodes = deep_tree();
    let built = build_hierarchy(&nodes, PAGE_LEVELS, Layout::V1_1);
    let file = built.file(DatasetId([1; 16]));
    let pages = all_pages(&file, &built);
    let proxy = pages[0].proxies().next().expect("a proxy on the root page");
    let chain4 = NodeKey::ROOT.child(0).child(0).child(0).child(0);
    assert_eq!(proxy.key, chain4);
    let node = proxy.node.expect("1.1 proxies carry their node");
    assert_eq!((node.offset, node.size), (nodes[&chain4].offset, 500));
    // The page it locates starts with the same node.
    let bytes = &file[proxy.page.offset as usize..(proxy.page.offset + proxy.page.size) as usize];
    let child = decode_page(bytes, &proxy.page, PAGE_LEVELS, Layout::V1_1).expect("child page");
    assert_eq!(child.root_node(), Some(node));
    // And a 1.0 proxy carries only the page.
    let built0 = build_hierarchy(&nodes, PAGE_LEVELS, Layout::V1_0);
    let file0 = built0.file(DatasetId::default());
    let proxy0 = all_pages(&file0, &built0)[0]
        .proxies()
        .next()
        .expect("a 1.0 proxy");
    assert_eq!(proxy0.node, None);
    assert_eq!(
        pages[0].nodes().count(),
        9,
        "1.1: proxies are nodes of their page"
    );
}

#[test]
fn a_flipped_byte_anywhere_in_a_page_is_caught() {
    let nodes = deep_tree();
    for layout in [Layout::V1_0, Layout::V1_1] {
        let built = build_hierarchy(&nodes, PAGE_LEVELS, layout);
        let file = built.file(DatasetId([1; 16]));
        let (off, size) = (built.root_page_offset, built.root_page_size);
        let page = &file[off as usize..(off + size) as usize];
        for i in 0..page.len() {
            let mut bad = page.to_vec();
            bad[i] ^= 1;
            let r = decode_page(&bad, &root_ref(&built), PAGE_LEVELS, layout);
            assert!(r.is_err(), "{layout:?} byte {i}");
        }
    }
}

/// A page with `edit` applied to its first entry and its checksum made to match again.
fn edited_root_page(edit: impl Fn(&mut [u8])) -> Result<HierarchyPage, String> {
    let built = build_hierarchy(&deep_tree(), PAGE_LEVELS, Layout::V1_1);
    let file = built.file(DatasetId([1; 16]));
    let (off, size) = (
        built.root_page_offset as usize,
        built.root_page_size as usize,
    );
    let mut page = file[off..off + size].to_vec();
    edit(&mut page[4..4 + ENTRY_SIZE]);
    let n = page.len();
    let crc = crc32fast::hash(&page[..n - 4]);
    page[n - 4..].copy_from_slice(&crc.to_le_bytes());
    decode_page(&page, &root_ref(&built), PAGE_LEVELS, Layout::V1_1)
}

#[test]
fn unknown_kinds_and_nonzero_reserved_bytes_are_refused() {
    assert!(edited_root_page(|_| {}).is_ok());
    let kind = edited_root_page(|e| e[0] = 2).err().unwrap_or_default();
    assert!(kind.contains("unknown kind 2"), "{kind}");
    let reserved = edited_root_page(|e| e[2] = 1).err().unwrap_or_default();
    assert!(reserved.contains("reserved"), "{reserved}");
    let empty = edited_root_page(|e| e[4..8].copy_from_slice(&0u32.to_le_bytes()))
        .err()
        .unwrap_or_default();
    assert!(empty.contains("no points"), "{empty}");
}

#[test]
fn a_count_no_payload_of_its_size_can_hold_is_refused() {
    // The root's payload is 500 bytes: at 12 bytes a row and LZ4's 255-fold at best, some
    // 11,000 rows at most.
    let count = |n: u32| edited_root_page(move |e| e[4..8].copy_from_slice(&n.to_le_bytes()));
    let huge = count(u32::MAX).err().unwrap_or_default();
    assert!(
        huge.contains("has 4294967295 points, more than its 500-byte payload can hold"),
        "{huge}"
    );
    assert!(count(11_000).is_ok());
}
