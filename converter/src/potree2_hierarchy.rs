//! Potree 2's `hierarchy.bin`: the octree's nodes in chunks of `STEP` levels, each chunk its
//! nodes in breadth-first order (children by index, x the high bit, z the low), 22 bytes each.
//! A node `STEP` levels below its chunk's root that has children is listed there as a proxy
//! (type 2) pointing at its own chunk, whose first entry is the node again with its points.
//! This is the order Potree's loader rebuilds the tree in: entry i's children are the next
//! unclaimed entries, so the order is the format, not a choice.

use std::collections::BTreeMap;
use strata_format::NodeKey;

/// Levels per hierarchy chunk (PotreeConverter 2's `hierarchyStepSize`).
pub const STEP: u8 = 4;
/// Bytes of one entry: type u8, child mask u8, points u32, offset u64, size u64.
pub const ENTRY_BYTES: usize = 22;

const NORMAL: u8 = 0;
const LEAF: u8 = 1;
const PROXY: u8 = 2;

/// One node's points in `octree.bin`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct NodeData {
    pub points: u32,
    pub offset: u64,
    pub size: u64,
}

/// Potree's index of `key` among its parent's children: x the high bit, z the low.
pub fn child_index(key: NodeKey) -> u8 {
    ((key.x & 1) << 2 | (key.y & 1) << 1 | (key.z & 1)) as u8
}

/// Potree's name of `key`: `r`, then the child index of each level below the root.
pub fn node_name(key: NodeKey) -> String {
    let mut name = String::with_capacity(key.level as usize + 1);
    name.push('r');
    for l in 1..=key.level {
        let up = key.level - l;
        let at = NodeKey {
            level: l,
            x: key.x >> up,
            y: key.y >> up,
            z: key.z >> up,
        };
        name.push(char::from(b'0' + child_index(at)));
    }
    name
}

fn parent(key: NodeKey) -> NodeKey {
    NodeKey {
        level: key.level - 1,
        x: key.x >> 1,
        y: key.y >> 1,
        z: key.z >> 1,
    }
}

/// The encoded hierarchy: its bytes, the first chunk's size, and the deepest level.
pub struct Hierarchy {
    pub bytes: Vec<u8>,
    pub first_chunk_size: u64,
    pub depth: u8,
}

/// Encodes the hierarchy of `nodes` (every node of the dataset with its place in
/// `octree.bin`). Ancestors missing from `nodes` are listed without points, so that every
/// node is reachable from the root.
pub fn encode(nodes: &BTreeMap<NodeKey, NodeData>) -> Hierarchy {
    let mut all = nodes.clone();
    for key in nodes.keys() {
        let mut k = *key;
        while k.level > 0 {
            k = parent(k);
            if all.contains_key(&k) {
                break;
            }
            all.insert(k, NodeData::default());
        }
    }
    all.entry(NodeKey::ROOT).or_default();
    // Children by index, as the loader creates them.
    let mut children: BTreeMap<NodeKey, [Option<NodeKey>; 8]> = BTreeMap::new();
    for key in all.keys().filter(|k| k.level > 0) {
        children.entry(parent(*key)).or_insert([None; 8])[child_index(*key) as usize] = Some(*key);
    }
    let kids = |k: NodeKey| {
        children
            .get(&k)
            .map(|c| c.iter().flatten().copied().collect::<Vec<_>>())
    };
    let mask = |k: NodeKey| {
        children.get(&k).map_or(0u8, |c| {
            c.iter()
                .enumerate()
                .filter(|(_, c)| c.is_some())
                .fold(0, |m, (i, _)| m | 1 << i)
        })
    };

    // Each chunk's entries: (key, is a proxy), breadth first.
    let mut chunks: Vec<(NodeKey, Vec<(NodeKey, bool)>)> = Vec::new();
    let mut roots = vec![NodeKey::ROOT];
    while let Some(root) = roots.pop() {
        let mut entries = vec![(root, false)];
        let mut i = 0;
        while i < entries.len() {
            let (key, proxy) = entries[i];
            i += 1;
            if proxy {
                continue;
            }
            for child in kids(key).unwrap_or_default() {
                let at_edge = child.level - root.level == STEP;
                let proxy = at_edge && children.contains_key(&child);
                if proxy {
                    roots.push(child);
                }
                entries.push((child, proxy));
            }
        }
        chunks.push((root, entries));
    }
    // Chunks follow the first in the order they were found; a proxy points at its chunk.
    let mut chunk_at: BTreeMap<NodeKey, (u64, u64)> = BTreeMap::new();
    let mut at = 0u64;
    for (root, entries) in &chunks {
        let size = (entries.len() * ENTRY_BYTES) as u64;
        chunk_at.insert(*root, (at, size));
        at += size;
    }
    let mut bytes = Vec::with_capacity(at as usize);
    for (_, entries) in &chunks {
        for &(key, proxy) in entries {
            let data = all.get(&key).copied().unwrap_or_default();
            let m = mask(key);
            let (kind, offset, size) = if proxy {
                let (o, s) = chunk_at.get(&key).copied().unwrap_or_default();
                (PROXY, o, s)
            } else if m == 0 {
                (LEAF, data.offset, data.size)
            } else {
                (NORMAL, data.offset, data.size)
            };
            bytes.push(kind);
            bytes.push(m);
            bytes.extend_from_slice(&data.points.to_le_bytes());
            bytes.extend_from_slice(&offset.to_le_bytes());
            bytes.extend_from_slice(&size.to_le_bytes());
        }
    }
    Hierarchy {
        bytes,
        first_chunk_size: chunks
            .first()
            .map_or(0, |(_, e)| (e.len() * ENTRY_BYTES) as u64),
        depth: all.keys().map(|k| k.level).max().unwrap_or(0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(level: u8, x: u32, y: u32, z: u32) -> NodeKey {
        NodeKey { level, x, y, z }
    }

    /// Walks the bytes as Potree's loader does, from the root's chunk, loading every proxy's
    /// chunk: each node's name and data.
    fn walk(h: &Hierarchy) -> BTreeMap<String, NodeData> {
        let mut found = BTreeMap::new();
        let mut todo = vec![("r".to_string(), 0u64, h.first_chunk_size)];
        while let Some((name, offset, size)) = todo.pop() {
            let chunk = &h.bytes[offset as usize..(offset + size) as usize];
            let mut names = vec![name];
            for (i, e) in chunk.chunks_exact(ENTRY_BYTES).enumerate() {
                let n = names[i].clone();
                let u64_at = |a: usize| u64::from_le_bytes(e[a..a + 8].try_into().expect("8"));
                let points = u32::from_le_bytes(e[2..6].try_into().expect("4"));
                if e[0] == PROXY {
                    todo.push((n, u64_at(6), u64_at(14)));
                    continue;
                }
                let data = NodeData {
                    points,
                    offset: u64_at(6),
                    size: u64_at(14),
                };
                assert!(found.insert(n.clone(), data).is_none(), "{n} twice");
                assert_eq!(e[0] == LEAF, e[1] == 0, "{n}: type and mask disagree");
                for c in 0..8 {
                    if e[1] & (1 << c) != 0 {
                        names.push(format!("{n}{c}"));
                    }
                }
            }
            assert_eq!(
                names.len(),
                chunk.len() / ENTRY_BYTES,
                "every child has an entry"
            );
        }
        found
    }

    #[test]
    fn names_put_x_in_the_high_bit() {
        assert_eq!(node_name(NodeKey::ROOT), "r");
        assert_eq!(node_name(key(1, 1, 0, 0)), "r4");
        assert_eq!(node_name(key(1, 0, 0, 1)), "r1");
        assert_eq!(node_name(key(2, 3, 2, 1)), "r65");
    }

    #[test]
    fn every_node_is_found_once_through_chunks_and_proxies() {
        // A chain eleven levels deep with side branches: three chunks deep, proxies at 4 and 8.
        let mut nodes = BTreeMap::new();
        for level in 0..=11u8 {
            let n = (1u32 << level) - 1;
            for k in [key(level, n, 0, n), key(level, 0, n, 0)] {
                let i = nodes.len() as u64;
                nodes.insert(
                    k,
                    NodeData {
                        points: level as u32 + 1,
                        offset: 100 * i,
                        size: 10 + i,
                    },
                );
            }
        }
        let h = encode(&nodes);
        assert_eq!(h.depth, 11);
        let found = walk(&h);
        assert_eq!(found.len(), nodes.len());
        for (k, d) in &nodes {
            assert_eq!(found.get(&node_name(*k)), Some(d), "{k:?}");
        }
        // The root's chunk stops at level 4: its proxies point further.
        assert!(h.first_chunk_size < h.bytes.len() as u64);
        assert_eq!(h.first_chunk_size as usize % ENTRY_BYTES, 0);
    }

    #[test]
    fn missing_ancestors_are_listed_without_points() {
        let mut nodes = BTreeMap::new();
        let deep = key(3, 5, 1, 7);
        nodes.insert(
            deep,
            NodeData {
                points: 9,
                offset: 0,
                size: 90,
            },
        );
        let found = walk(&encode(&nodes));
        assert_eq!(found.len(), 4);
        assert_eq!(found["r"].points, 0);
        assert_eq!(found[&node_name(deep)].points, 9);
    }
}
