//! Hierarchy pages: the octree's node table, split into subtrees of `page_levels` levels so a
//! reader loads only the pages of the part of the tree it visits. Decoding for both layouts;
//! building is in `page_build.rs`.

use crate::{Layout, NodeKey};
use std::collections::VecDeque;

/// Levels per page written by this version (a page's root and four levels below it).
pub const PAGE_LEVELS: u32 = 5;
/// Bytes per entry in a page.
pub const ENTRY_SIZE: usize = 24;
/// The deepest level a node can have (a cube of 2^32 units split down to single units).
pub const MAX_LEVEL: u32 = 32;
/// Bytes per child-page reference in the table that ends a 1.1 page.
pub const PAGE_REF_SIZE: usize = 16;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EntryKind {
    /// A node whose children, if any, are in the same page: offset, size and checksum locate
    /// its payload in `octree.bin`.
    Node = 0,
    /// A node on a page's last level whose children are in another page. In 1.1, offset, size
    /// and checksum locate its payload like a node's, and the page's reference table locates
    /// the other page; in 1.0 they locate the other page (which holds the node's entry).
    Proxy = 1,
}

/// One 24-byte entry of a hierarchy page.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PageEntry {
    pub kind: EntryKind,
    pub child_mask: u8,
    pub point_count: u32,
    pub offset: u64,
    pub size: u32,
    pub checksum: u32,
}

impl PageEntry {
    pub(crate) fn write(&self, out: &mut Vec<u8>) {
        out.push(self.kind as u8);
        out.push(self.child_mask);
        out.extend_from_slice(&0u16.to_le_bytes());
        out.extend_from_slice(&self.point_count.to_le_bytes());
        out.extend_from_slice(&self.offset.to_le_bytes());
        out.extend_from_slice(&self.size.to_le_bytes());
        out.extend_from_slice(&self.checksum.to_le_bytes());
    }

    /// Reads 24 bytes; refuses an unknown kind and nonzero reserved bytes.
    fn read(b: &[u8], key: NodeKey) -> Result<PageEntry, String> {
        let kind = match b[0] {
            0 => EntryKind::Node,
            1 => EntryKind::Proxy,
            k => return Err(format!("entry for {key} has unknown kind {k}")),
        };
        let reserved = u16::from_le_bytes([b[2], b[3]]);
        if reserved != 0 {
            return Err(format!(
                "entry for {key} has reserved bytes {reserved:#06x} (must be 0)"
            ));
        }
        Ok(PageEntry {
            kind,
            child_mask: b[1],
            point_count: u32_at(b, 4),
            offset: u64_at(b, 8),
            size: u32_at(b, 16),
            checksum: u32_at(b, 20),
        })
    }
}

fn u32_at(b: &[u8], i: usize) -> u32 {
    u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]])
}

fn u64_at(b: &[u8], i: usize) -> u64 {
    let mut v = [0u8; 8];
    v.copy_from_slice(&b[i..i + 8]);
    u64::from_le_bytes(v)
}

/// Where a page lies in `hierarchy.bin`, and which node is its root.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PageRef {
    pub root: NodeKey,
    pub offset: u64,
    pub size: u64,
    pub checksum: Option<u32>,
}

/// A node as the hierarchy describes it: where its payload is, and its children.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeInfo {
    pub key: NodeKey,
    pub point_count: u32,
    pub offset: u64,
    pub size: u32,
    pub checksum: u32,
    pub child_mask: u8,
}

impl NodeInfo {
    fn of(key: NodeKey, e: &PageEntry) -> NodeInfo {
        NodeInfo {
            key,
            point_count: e.point_count,
            offset: e.offset,
            size: e.size,
            checksum: e.checksum,
            child_mask: e.child_mask,
        }
    }
}

/// A proxy: a node whose children are in another page.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Proxy {
    pub key: NodeKey,
    /// The node's own payload (1.1): a reader may fetch it and `page` at the same time. `None`
    /// in 1.0, where only `page` tells it.
    pub node: Option<NodeInfo>,
    pub page: PageRef,
}

/// A decoded page: its entries with the node each belongs to, in the page's breadth-first
/// order, and the pages below it.
#[derive(Debug, Clone)]
pub struct HierarchyPage {
    pub root: NodeKey,
    pub layout: Layout,
    pub entries: Vec<(NodeKey, PageEntry)>,
    /// The page below each proxy, in entry order.
    pub children: Vec<PageRef>,
}

impl HierarchyPage {
    /// The pages this page points to.
    pub fn child_pages(&self) -> impl Iterator<Item = PageRef> + '_ {
        self.children.iter().copied()
    }

    /// Every node whose payload this page locates: its `Node` entries, and in 1.1 its proxies.
    pub fn nodes(&self) -> impl Iterator<Item = NodeInfo> + '_ {
        let proxies_too = self.layout != Layout::V1_0;
        self.entries
            .iter()
            .filter(move |(_, e)| proxies_too || e.kind == EntryKind::Node)
            .map(|(k, e)| NodeInfo::of(*k, e))
    }

    /// The nodes this page owns (its `Node` entries): over all pages, each node exactly once,
    /// since a proxied node is owned by the page it roots.
    pub fn own_nodes(&self) -> impl Iterator<Item = NodeInfo> + '_ {
        self.entries
            .iter()
            .filter(|(_, e)| e.kind == EntryKind::Node)
            .map(|(k, e)| NodeInfo::of(*k, e))
    }

    /// The page's root node (its first entry).
    pub fn root_node(&self) -> Option<NodeInfo> {
        self.entries.first().map(|(k, e)| NodeInfo::of(*k, e))
    }

    /// Each proxy with its page and (1.1) its node's payload.
    pub fn proxies(&self) -> impl Iterator<Item = Proxy> + '_ {
        let with_node = self.layout != Layout::V1_0;
        self.entries
            .iter()
            .filter(|(_, e)| e.kind == EntryKind::Proxy)
            .zip(&self.children)
            .map(move |((k, e), page)| Proxy {
                key: *k,
                node: with_node.then(|| NodeInfo::of(*k, e)),
                page: *page,
            })
    }
}

/// Decodes the page at `page` from its bytes in `layout`, checking its checksum and shape.
pub fn decode_page(
    bytes: &[u8],
    page: &PageRef,
    page_levels: u32,
    layout: Layout,
) -> Result<HierarchyPage, String> {
    let impossible = || format!("page has an impossible size of {} bytes", bytes.len());
    if bytes.len() < 8 + ENTRY_SIZE {
        return Err(impossible());
    }
    if layout == Layout::V1_0 && !(bytes.len() - 8).is_multiple_of(ENTRY_SIZE) {
        return Err(impossible());
    }
    let (body, tail) = bytes.split_at(bytes.len() - 4);
    let stored = u32_at(tail, 0);
    let computed = crc32fast::hash(body);
    if stored != computed {
        return Err(format!(
            "page checksum mismatch (stored {stored:#010x}, computed {computed:#010x})"
        ));
    }
    if let Some(expected) = page.checksum
        && expected != computed
    {
        return Err(format!(
            "page checksum {computed:#010x} differs from {expected:#010x} recorded by its parent page"
        ));
    }
    let count = u32_at(body, 0) as usize;
    let entries_end = count
        .checked_mul(ENTRY_SIZE)
        .and_then(|n| n.checked_add(4))
        .filter(|&end| count > 0 && end <= body.len())
        .ok_or_else(|| format!("page entry count {count} does not match its size"))?;
    let mut entries = Vec::with_capacity(count);
    let mut keys = VecDeque::from([page.root]);
    for raw in body[4..entries_end].chunks_exact(ENTRY_SIZE) {
        let key = keys
            .pop_front()
            .ok_or_else(|| "page has more entries than its child masks describe".to_string())?;
        let entry = PageEntry::read(raw, key)?;
        let rel = key.level.saturating_sub(page.root.level) as u32;
        let last_level = rel + 1 >= page_levels;
        match entry.kind {
            EntryKind::Proxy if !last_level || entry.child_mask == 0 || entries.is_empty() => {
                return Err(format!("proxy entry for {key} in the wrong place"));
            }
            EntryKind::Node if last_level && entry.child_mask != 0 => {
                return Err(format!(
                    "node {key} on a page's last level has children but no page"
                ));
            }
            EntryKind::Node if entry.child_mask != 0 && key.level as u32 >= MAX_LEVEL => {
                return Err(format!(
                    "node {key} has children below level {MAX_LEVEL}, the deepest possible"
                ));
            }
            EntryKind::Node => {
                for o in 0..8u8 {
                    if entry.child_mask & (1 << o) != 0 {
                        keys.push_back(key.child(o));
                    }
                }
            }
            EntryKind::Proxy => {}
        }
        if layout != Layout::V1_0 {
            check_payload_1_1(key, &entry)?;
        }
        // 1.0's proxies give their page's size, not a payload's.
        if layout != Layout::V1_0 || entry.kind == EntryKind::Node {
            check_count_fits(key, &entry)?;
        }
        entries.push((key, entry));
    }
    if !keys.is_empty() {
        return Err(format!(
            "page ends with {} children announced but not listed",
            keys.len()
        ));
    }
    let proxies = || entries.iter().filter(|(_, e)| e.kind == EntryKind::Proxy);
    let children: Vec<PageRef> = match layout {
        Layout::V1_0 => {
            if entries_end != body.len() {
                return Err(format!("page entry count {count} does not match its size"));
            }
            proxies()
                .map(|(k, e)| PageRef {
                    root: *k,
                    offset: e.offset,
                    size: e.size as u64,
                    checksum: Some(e.checksum),
                })
                .collect()
        }
        Layout::V1_1 => {
            let table = &body[entries_end..];
            if table.len() != proxies().count() * PAGE_REF_SIZE {
                return Err(format!(
                    "page of {count} entries and {} proxies should be {} bytes, not {}",
                    proxies().count(),
                    page_size(count, proxies().count()),
                    bytes.len()
                ));
            }
            proxies()
                .zip(table.chunks_exact(PAGE_REF_SIZE))
                .map(|((k, _), r)| PageRef {
                    root: *k,
                    offset: u64_at(r, 0),
                    size: u32_at(r, 8) as u64,
                    checksum: Some(u32_at(r, 12)),
                })
                .collect()
        }
    };
    Ok(HierarchyPage {
        root: page.root,
        layout,
        entries,
        children,
    })
}

/// Bytes of a 1.1 page of `entries` entries, `proxies` of them proxies.
pub fn page_size(entries: usize, proxies: usize) -> u64 {
    (8 + entries * ENTRY_SIZE + proxies * PAGE_REF_SIZE) as u64
}

/// A node's rows hold at least its 12 bytes of position, and LZ4 shrinks bytes at most about
/// 255-fold: a count its payload cannot hold is damage (a reader that plans by the counts,
/// such as `profile --max-read`, would stop early on it without a word).
fn check_count_fits(key: NodeKey, e: &PageEntry) -> Result<(), String> {
    let most = (e.size as u64).saturating_mul(256).saturating_add(4096) / 12;
    if e.point_count as u64 > most && e.size > 0 {
        return Err(format!(
            "entry for {key} has {} points, more than its {}-byte payload can hold",
            e.point_count, e.size
        ));
    }
    Ok(())
}

/// 1.1: a node with no points has offset, size and checksum 0; any other has a payload.
fn check_payload_1_1(key: NodeKey, e: &PageEntry) -> Result<(), String> {
    match (e.point_count, e.size) {
        (0, _) if (e.offset, e.size, e.checksum) != (0, 0, 0) => Err(format!(
            "entry for {key} has no points but offset {}, size {} and checksum {:#010x} (all must be 0)",
            e.offset, e.size, e.checksum
        )),
        (n, 0) if n > 0 => Err(format!("entry for {key} has {n} points but no payload")),
        _ => Ok(()),
    }
}
