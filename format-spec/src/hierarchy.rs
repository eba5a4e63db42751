//! Hierarchy pages: the octree's node table, split into subtrees of `PAGE_LEVELS` levels so a
//! reader loads only the pages of the part of the tree it visits.

use crate::NodeKey;
use std::collections::{BTreeMap, VecDeque};

/// The first 8 bytes of `hierarchy.bin`.
pub const HIERARCHY_MAGIC: &[u8; 8] = b"STRATAHY";
/// Levels per page (a page's root and four levels below it).
pub const PAGE_LEVELS: u32 = 5;
/// Bytes per entry in a page.
pub const ENTRY_SIZE: usize = 24;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EntryKind {
    /// A node: offset, size and checksum locate its payload in `octree.bin`.
    Node = 0,
    /// A node whose entry and subtree live in another page: offset, size and checksum locate
    /// that page in `hierarchy.bin`.
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
    fn write(&self, out: &mut Vec<u8>) {
        out.push(self.kind as u8);
        out.push(self.child_mask);
        out.extend_from_slice(&0u16.to_le_bytes());
        out.extend_from_slice(&self.point_count.to_le_bytes());
        out.extend_from_slice(&self.offset.to_le_bytes());
        out.extend_from_slice(&self.size.to_le_bytes());
        out.extend_from_slice(&self.checksum.to_le_bytes());
    }

    fn read(b: &[u8]) -> Result<PageEntry, String> {
        let kind = match b[0] {
            0 => EntryKind::Node,
            1 => EntryKind::Proxy,
            k => return Err(format!("unknown entry kind {k}")),
        };
        let u32_at = |i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        let mut off = [0u8; 8];
        off.copy_from_slice(&b[8..16]);
        Ok(PageEntry {
            kind,
            child_mask: b[1],
            point_count: u32_at(4),
            offset: u64::from_le_bytes(off),
            size: u32_at(16),
            checksum: u32_at(20),
        })
    }
}

/// Where a page lies in `hierarchy.bin`, and which node is its root.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PageRef {
    pub root: NodeKey,
    pub offset: u64,
    pub size: u64,
    pub checksum: Option<u32>,
}

/// A decoded page: its entries with the node each belongs to, in the page's breadth-first order.
#[derive(Debug, Clone)]
pub struct HierarchyPage {
    pub entries: Vec<(NodeKey, PageEntry)>,
}

impl HierarchyPage {
    /// The pages this page points to.
    pub fn child_pages(&self) -> impl Iterator<Item = PageRef> + '_ {
        self.entries
            .iter()
            .filter(|(_, e)| e.kind == EntryKind::Proxy)
            .map(|(k, e)| PageRef {
                root: *k,
                offset: e.offset,
                size: e.size as u64,
                checksum: Some(e.checksum),
            })
    }
}

/// Decodes the page at `page` from its bytes, checking its checksum and its shape.
pub fn decode_page(
    bytes: &[u8],
    page: &PageRef,
    page_levels: u32,
) -> Result<HierarchyPage, String> {
    if bytes.len() < 8 || !(bytes.len() - 8).is_multiple_of(ENTRY_SIZE) {
        return Err(format!(
            "page has an impossible size of {} bytes",
            bytes.len()
        ));
    }
    let body = &bytes[..bytes.len() - 4];
    let tail = &bytes[bytes.len() - 4..];
    let stored = u32::from_le_bytes([tail[0], tail[1], tail[2], tail[3]]);
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
    let count = u32::from_le_bytes([body[0], body[1], body[2], body[3]]) as usize;
    if count * ENTRY_SIZE != body.len() - 4 || count == 0 {
        return Err(format!("page entry count {count} does not match its size"));
    }
    let mut entries = Vec::with_capacity(count);
    let mut keys = VecDeque::from([page.root]);
    for raw in body[4..].chunks_exact(ENTRY_SIZE) {
        let entry = PageEntry::read(raw)?;
        let key = keys
            .pop_front()
            .ok_or_else(|| "page has more entries than its child masks describe".to_string())?;
        let rel = (key.level - page.root.level) as u32;
        let last_level = rel + 1 == page_levels;
        match entry.kind {
            EntryKind::Proxy if !last_level || entry.child_mask == 0 || entries.is_empty() => {
                return Err(format!("proxy entry for {key} in the wrong place"));
            }
            EntryKind::Node if last_level && entry.child_mask != 0 => {
                return Err(format!(
                    "node {key} on a page's last level has children but no page"
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
        entries.push((key, entry));
    }
    if !keys.is_empty() {
        return Err(format!(
            "page ends with {} children announced but not listed",
            keys.len()
        ));
    }
    Ok(HierarchyPage { entries })
}

/// The per-node facts the hierarchy records.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeRecord {
    pub point_count: u32,
    pub offset: u64,
    pub size: u32,
    pub checksum: u32,
    pub child_mask: u8,
}

/// Builds `hierarchy.bin` (magic, then pages) for a complete tree. Returns the file bytes and the
/// root page's (offset, size).
pub fn build_hierarchy(
    nodes: &BTreeMap<NodeKey, NodeRecord>,
    page_levels: u32,
) -> (Vec<u8>, u64, u64) {
    // Pass 1: the nodes of each page, pages in breadth-first order of their roots.
    let mut pages: Vec<(NodeKey, Vec<NodeKey>)> = Vec::new();
    let mut page_roots = VecDeque::from([NodeKey::ROOT]);
    while let Some(root) = page_roots.pop_front() {
        let mut members = Vec::new();
        let mut queue = VecDeque::from([root]);
        while let Some(k) = queue.pop_front() {
            members.push(k);
            let Some(rec) = nodes.get(&k) else { continue };
            let rel = (k.level - root.level) as u32;
            if rel + 1 == page_levels {
                if rec.child_mask != 0 {
                    page_roots.push_back(k);
                }
            } else {
                for o in 0..8u8 {
                    if rec.child_mask & (1 << o) != 0 {
                        queue.push_back(k.child(o));
                    }
                }
            }
        }
        pages.push((root, members));
    }
    // Pass 2: offsets, from page sizes.
    let mut offset = HIERARCHY_MAGIC.len() as u64;
    let mut page_at: BTreeMap<NodeKey, (u64, u64)> = BTreeMap::new();
    for (root, members) in &pages {
        let size = (8 + members.len() * ENTRY_SIZE) as u64;
        page_at.insert(*root, (offset, size));
        offset += size;
    }
    // Pass 3: bytes. Child pages come later in the file but their checksums are needed by the
    // proxies that point at them, so encode bottom-up.
    let mut encoded: BTreeMap<NodeKey, Vec<u8>> = BTreeMap::new();
    for (root, members) in pages.iter().rev() {
        let mut page = Vec::with_capacity(8 + members.len() * ENTRY_SIZE);
        page.extend_from_slice(&(members.len() as u32).to_le_bytes());
        for k in members {
            let rec = nodes.get(k).copied().unwrap_or(NodeRecord {
                point_count: 0,
                offset: 0,
                size: 0,
                checksum: 0,
                child_mask: 0,
            });
            let entry = if k != root && rec.child_mask != 0 && page_at.contains_key(k) {
                let (off, size) = page_at[k];
                let child = &encoded[k];
                let crc = u32::from_le_bytes([
                    child[child.len() - 4],
                    child[child.len() - 3],
                    child[child.len() - 2],
                    child[child.len() - 1],
                ]);
                PageEntry {
                    kind: EntryKind::Proxy,
                    child_mask: rec.child_mask,
                    point_count: rec.point_count,
                    offset: off,
                    size: size as u32,
                    checksum: crc,
                }
            } else {
                PageEntry {
                    kind: EntryKind::Node,
                    child_mask: rec.child_mask,
                    point_count: rec.point_count,
                    offset: rec.offset,
                    size: rec.size,
                    checksum: rec.checksum,
                }
            };
            entry.write(&mut page);
        }
        let crc = crc32fast::hash(&page);
        page.extend_from_slice(&crc.to_le_bytes());
        encoded.insert(*root, page);
    }
    let mut file = HIERARCHY_MAGIC.to_vec();
    for (root, _) in &pages {
        file.extend_from_slice(&encoded[root]);
    }
    let (root_off, root_size) = page_at[&NodeKey::ROOT];
    (file, root_off, root_size)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain of nodes 12 levels deep, with a sibling at each level, spans several pages.
    fn deep_tree() -> BTreeMap<NodeKey, NodeRecord> {
        let mut nodes = BTreeMap::new();
        let mut k = NodeKey::ROOT;
        for level in 0..12u32 {
            let mask = if level < 11 { 0b1000_0001 } else { 0 };
            nodes.insert(
                k,
                NodeRecord {
                    point_count: 100 + level,
                    offset: 8 + level as u64 * 1000,
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

    #[test]
    fn pages_round_trip_every_node() {
        let nodes = deep_tree();
        let (file, off, size) = build_hierarchy(&nodes, PAGE_LEVELS);
        assert_eq!(&file[..8], HIERARCHY_MAGIC);
        let mut found = BTreeMap::new();
        let mut pages = vec![PageRef {
            root: NodeKey::ROOT,
            offset: off,
            size,
            checksum: None,
        }];
        let mut n_pages = 0;
        while let Some(p) = pages.pop() {
            n_pages += 1;
            let bytes = &file[p.offset as usize..(p.offset + p.size) as usize];
            let page = decode_page(bytes, &p, PAGE_LEVELS).expect("page decodes");
            pages.extend(page.child_pages());
            for (k, e) in page.entries {
                if e.kind == EntryKind::Node {
                    found.insert(k, (e.point_count, e.offset, e.checksum, e.child_mask));
                }
            }
        }
        assert!(n_pages >= 3, "12 levels need at least 3 pages of 5");
        assert_eq!(found.len(), nodes.len());
        for (k, rec) in &nodes {
            assert_eq!(
                found[k],
                (rec.point_count, rec.offset, rec.checksum, rec.child_mask)
            );
        }
    }

    #[test]
    fn a_flipped_byte_anywhere_in_a_page_is_caught() {
        let nodes = deep_tree();
        let (file, off, size) = build_hierarchy(&nodes, PAGE_LEVELS);
        let root = PageRef {
            root: NodeKey::ROOT,
            offset: off,
            size,
            checksum: None,
        };
        let page = &file[off as usize..(off + size) as usize];
        for i in 0..page.len() {
            let mut bad = page.to_vec();
            bad[i] ^= 1;
            assert!(decode_page(&bad, &root, PAGE_LEVELS).is_err(), "byte {i}");
        }
    }
}
