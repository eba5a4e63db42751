//! Building `hierarchy.bin` from a complete tree, in either layout.

use crate::hierarchy::page_size;
use crate::{
    DatasetId, ENTRY_SIZE, EntryKind, HIERARCHY_MAGIC_1_0, HierarchyHead, Layout, NodeKey,
    PageEntry,
};
use std::collections::{BTreeMap, VecDeque};

/// The per-node facts the hierarchy records.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeRecord {
    pub point_count: u32,
    pub offset: u64,
    pub size: u32,
    pub checksum: u32,
    pub child_mask: u8,
}

/// The pages of a hierarchy, laid out for a file whose head has `layout`'s size.
#[derive(Debug, Clone)]
pub struct BuiltHierarchy {
    pub layout: Layout,
    pub page_levels: u32,
    /// Every page, root page first, as they follow the head.
    pub pages: Vec<u8>,
    pub root_page_offset: u64,
    pub root_page_size: u64,
    pub page_count: usize,
}

impl BuiltHierarchy {
    /// The whole `hierarchy.bin`: the head (in 1.1 with `id`), then the pages.
    pub fn file(&self, id: DatasetId) -> Vec<u8> {
        let mut out = match self.layout {
            Layout::V1_0 => HIERARCHY_MAGIC_1_0.to_vec(),
            Layout::V1_1 => HierarchyHead {
                id,
                root_page_size: self.root_page_size as u32,
                page_levels: self.page_levels,
            }
            .encode(),
        };
        out.extend_from_slice(&self.pages);
        out
    }
}

/// The nodes of one page in breadth-first order, and which of them are proxies.
struct PagePlan {
    root: NodeKey,
    members: Vec<NodeKey>,
    proxies: Vec<NodeKey>,
}

/// Lays out the pages of a complete tree. Page roots: the root node, and every node with
/// children on a page's last level (relative depth `page_levels - 1`), which is a proxy there.
/// Pages follow the head in breadth-first order of their roots, root page first. In 1.1 a node
/// with no points gets offset, size and checksum 0, whatever `nodes` says.
pub fn build_hierarchy(
    nodes: &BTreeMap<NodeKey, NodeRecord>,
    page_levels: u32,
    layout: Layout,
) -> BuiltHierarchy {
    let empty = NodeRecord {
        point_count: 0,
        offset: 0,
        size: 0,
        checksum: 0,
        child_mask: 0,
    };
    let record = |k: &NodeKey| {
        let r = nodes.get(k).copied().unwrap_or(empty);
        if layout == Layout::V1_1 && r.point_count == 0 {
            NodeRecord {
                child_mask: r.child_mask,
                ..empty
            }
        } else {
            r
        }
    };
    // Pass 1: the nodes of each page, pages in breadth-first order of their roots.
    let mut plans: Vec<PagePlan> = Vec::new();
    let mut page_roots = VecDeque::from([NodeKey::ROOT]);
    while let Some(root) = page_roots.pop_front() {
        let mut plan = PagePlan {
            root,
            members: Vec::new(),
            proxies: Vec::new(),
        };
        let mut queue = VecDeque::from([root]);
        while let Some(k) = queue.pop_front() {
            plan.members.push(k);
            let rec = record(&k);
            let rel = (k.level - root.level) as u32;
            if rel + 1 >= page_levels {
                if rec.child_mask != 0 && k != root {
                    page_roots.push_back(k);
                    plan.proxies.push(k);
                }
            } else {
                for o in 0..8u8 {
                    if rec.child_mask & (1 << o) != 0 {
                        queue.push_back(k.child(o));
                    }
                }
            }
        }
        plans.push(plan);
    }
    // Pass 2: offsets, from page sizes.
    let head = layout.head_size(crate::DatasetFile::Hierarchy);
    let mut offset = head;
    let mut page_at: BTreeMap<NodeKey, (u64, u64)> = BTreeMap::new();
    for p in &plans {
        let size = match layout {
            Layout::V1_0 => (8 + p.members.len() * ENTRY_SIZE) as u64,
            Layout::V1_1 => page_size(p.members.len(), p.proxies.len()),
        };
        page_at.insert(p.root, (offset, size));
        offset += size;
    }
    // Pass 3: bytes. Child pages come later in the file but their checksums are needed by the
    // proxies that point at them, so encode bottom-up.
    let mut crcs: BTreeMap<NodeKey, u32> = BTreeMap::new();
    let mut encoded: Vec<Vec<u8>> = Vec::with_capacity(plans.len());
    for p in plans.iter().rev() {
        let (_, size) = page_at[&p.root];
        let mut page = Vec::with_capacity(size as usize);
        page.extend_from_slice(&(p.members.len() as u32).to_le_bytes());
        for k in &p.members {
            let rec = record(k);
            let proxy = *k != p.root && page_at.contains_key(k);
            let (offset, size, checksum) = match (proxy, layout) {
                (true, Layout::V1_0) => {
                    let (off, size) = page_at[k];
                    (off, size as u32, crcs[k])
                }
                _ => (rec.offset, rec.size, rec.checksum),
            };
            PageEntry {
                kind: if proxy {
                    EntryKind::Proxy
                } else {
                    EntryKind::Node
                },
                child_mask: rec.child_mask,
                point_count: rec.point_count,
                offset,
                size,
                checksum,
            }
            .write(&mut page);
        }
        if layout == Layout::V1_1 {
            for k in &p.proxies {
                let (off, size) = page_at[k];
                page.extend_from_slice(&off.to_le_bytes());
                page.extend_from_slice(&(size as u32).to_le_bytes());
                page.extend_from_slice(&crcs[k].to_le_bytes());
            }
        }
        let crc = crc32fast::hash(&page);
        page.extend_from_slice(&crc.to_le_bytes());
        crcs.insert(p.root, crc);
        encoded.push(page);
    }
    let (root_page_offset, root_page_size) = page_at[&NodeKey::ROOT];
    BuiltHierarchy {
        layout,
        page_levels,
        pages: encoded.into_iter().rev().flatten().collect(),
        root_page_offset,
        root_page_size,
        page_count: plans.len(),
    }
}
