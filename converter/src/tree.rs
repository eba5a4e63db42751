//! Building a layered octree over rows held in memory: leaves keep all their points, and each
//! inner node takes its subsample from its children, so every point is stored exactly once.

use crate::morton::{SortScratch, sort_keys, sort_positions};
use crate::sampling::{Sampling, select_ordered};
use strata_format::{Cube, GRID_CELLS_LOG2, NodeKey, RowLayout, encode_node_rows, row_position};

/// Nodes hold at most this many points before they split.
pub const LEAF_MAX: usize = 20_000;
/// Deepest level; a node this deep (or one integer unit wide) never splits.
pub const MAX_LEVEL: u8 = 30;

/// A node whose parent has taken its sample: final, encoded, ready to store.
#[derive(Debug, Clone)]
pub struct FinishedNode {
    pub key: NodeKey,
    pub point_count: u32,
    pub child_mask: u8,
    pub payload: Vec<u8>,
    pub crc: u32,
}

/// A node whose own points may still be taken by its parent.
#[derive(Debug, Clone)]
pub struct OpenNode {
    pub key: NodeKey,
    pub points: Vec<u32>,
    pub child_mask: u8,
}

/// The big buffers of one chunk's build, kept by a worker from chunk to chunk so the kernel
/// need not hand out (and zero) fresh pages for every chunk.
#[derive(Debug, Default)]
pub struct ChunkMemory {
    /// The chunk's rows, as read.
    pub rows: Vec<u8>,
    sorted: Vec<u8>,
    pos: Vec<[i32; 3]>,
    order: Vec<u32>,
    sort: SortScratch,
}

/// Nodes are built over `pos`, the rows' positions, which sorting reorders (with `order`, the
/// row each entry came from).
pub struct TreeBuilder<'a> {
    pub rows: Vec<u8>,
    pub pos: Vec<[i32; 3]>,
    pub order: Vec<u32>,
    spare_rows: Vec<u8>,
    sort: SortScratch,
    pub layout: &'a RowLayout,
    pub cube: Cube,
    pub sampling: Sampling,
    pub finished: Vec<FinishedNode>,
}

impl<'a> TreeBuilder<'a> {
    /// A builder over `memory.rows`, reusing the rest of `memory`.
    pub fn with_memory(
        memory: ChunkMemory,
        layout: &'a RowLayout,
        cube: Cube,
        sampling: Sampling,
    ) -> Self {
        let ChunkMemory {
            rows,
            sorted,
            mut pos,
            mut order,
            sort,
        } = memory;
        pos.clear();
        pos.extend(rows.chunks_exact(layout.stride).map(row_position));
        order.clear();
        order.extend(0..pos.len() as u32);
        TreeBuilder {
            rows,
            pos,
            order,
            spare_rows: sorted,
            sort,
            layout,
            cube,
            sampling,
            finished: Vec::new(),
        }
    }

    /// Builds the subtree of chunk `key` over all rows; every node below `key` is finished,
    /// `key` itself is returned open. The rows are reordered (Morton order) on the way.
    pub fn build_chunk(&mut self, key: NodeKey) -> OpenNode {
        let n = self.pos.len();
        let (min, _) = key.int_bounds(self.cube.min, self.cube.bits);
        let bits = self.cube.bits - key.level as u32;
        let shift = sort_keys(&self.pos, min, bits, &mut self.sort);
        // The rows themselves go into Morton order, so that every later gather (sampling,
        // encoding) is a forward scan; the positions are then read from them again rather than
        // permuted through a copy, which would double the memory a chunk touches.
        let stride = self.layout.stride;
        let sorted = &mut self.spare_rows;
        sorted.clear();
        sorted.reserve(n * stride);
        for i in self.sort.sorted_indices() {
            let at = i * stride;
            sorted.extend_from_slice(&self.rows[at..at + stride]);
        }
        std::mem::swap(&mut self.rows, sorted);
        self.pos.clear();
        self.pos
            .extend(self.rows.chunks_exact(stride).map(row_position));
        self.order
            .iter_mut()
            .enumerate()
            .for_each(|(j, o)| *o = j as u32);
        self.build(key, 0, n, shift)
    }

    /// Builds the subtree of `key` over rows `start..end`, which are in Morton order at
    /// resolution `shift` (positions differing only below bit `shift` may be in any order).
    fn build(&mut self, key: NodeKey, start: usize, end: usize, shift: u32) -> OpenNode {
        let node_bits = self.cube.bits - key.level as u32;
        if end - start <= LEAF_MAX || node_bits == 0 || key.level >= MAX_LEVEL {
            return OpenNode {
                key,
                points: (start as u32..end as u32).collect(),
                child_mask: 0,
            };
        }
        let (min, _) = key.int_bounds(self.cube.min, self.cube.bits);
        let mut shift = shift;
        // This node's sampling cells and its children must be runs of the order; a chunk
        // wider than the key's 21 bits per axis reorders its deep nodes on their own.
        if shift > node_bits.saturating_sub(GRID_CELLS_LOG2) {
            let (pos, order) = (&mut self.pos[start..end], &mut self.order[start..end]);
            shift = sort_positions(pos, order, min, node_bits, &mut self.sort);
        }
        let half = node_bits - 1;
        let octant = |p: [i32; 3]| {
            let b = |a: usize| (((p[a] as i64 - min[a]) >> half) & 1) as u8;
            (b(0) << 2) | (b(1) << 1) | b(2)
        };
        let mut children = Vec::new();
        let mut lo = start;
        for o in 0..8u8 {
            // The first row past octant `o`: octants rise along the order.
            let (mut a, mut b) = (lo, end);
            while a < b {
                let mid = (a + b) / 2;
                if octant(self.pos[mid]) <= o {
                    a = mid + 1;
                } else {
                    b = mid;
                }
            }
            if a > lo {
                children.push(self.build(key.child(o), lo, a, shift));
            }
            lo = a;
        }
        self.adopt(key, children)
    }

    /// Gives `key` its sample of its children's points (in Morton order, see `build`, so
    /// sampling is one pass), then finishes the children.
    pub fn adopt(&mut self, key: NodeKey, mut children: Vec<OpenNode>) -> OpenNode {
        let node_bits = self.cube.bits - key.level as u32;
        let (min, _) = key.int_bounds(self.cube.min, self.cube.bits);
        let candidates: Vec<u32> = children
            .iter()
            .flat_map(|c| c.points.iter().copied())
            .collect();
        let keep = select_ordered(&self.pos, &candidates, min, node_bits, self.sampling);
        let mut points = Vec::new();
        let mut at = 0;
        for c in &mut children {
            let mut rest = Vec::with_capacity(c.points.len());
            for &p in &c.points {
                if keep[at] {
                    points.push(p);
                } else {
                    rest.push(p);
                }
                at += 1;
            }
            c.points = rest;
        }
        let mut child_mask = 0u8;
        for c in children {
            if c.points.is_empty() && c.child_mask == 0 {
                continue;
            }
            child_mask |= 1 << c.key.octant();
            self.finish(c);
        }
        OpenNode {
            key,
            points,
            child_mask,
        }
    }

    /// Encodes a node whose points are final.
    pub fn finish(&mut self, node: OpenNode) {
        let which: Vec<u32> = node
            .points
            .iter()
            .map(|&j| self.order[j as usize])
            .collect();
        let (payload, crc) = encode_node_rows(&self.rows, &which, self.layout);
        self.finished.push(FinishedNode {
            key: node.key,
            point_count: node.points.len() as u32,
            child_mask: node.child_mask,
            payload,
            crc,
        });
    }

    /// The buffers back, for the next chunk.
    pub fn into_memory(self) -> ChunkMemory {
        ChunkMemory {
            rows: self.rows,
            sorted: self.spare_rows,
            pos: self.pos,
            order: self.order,
            sort: self.sort,
        }
    }

    /// The rows of an open node, copied out.
    pub fn rows_of(&self, node: &OpenNode) -> Vec<u8> {
        let stride = self.layout.stride;
        let mut out = Vec::with_capacity(node.points.len() * stride);
        for &j in &node.points {
            let at = self.order[j as usize] as usize * stride;
            out.extend_from_slice(&self.rows[at..at + stride]);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::Rng;
    use strata_format::decode_node;

    /// A chunk of a 2^30-unit cube whose points crowd into a corner a few thousand units wide:
    /// nodes far below the chunk hold more than LEAF_MAX points, finer than the chunk's sort
    /// key can tell apart, so they must sort their own rows again.
    #[test]
    fn deep_dense_nodes_keep_every_point_once_and_sample_one_per_cell() {
        let layout = RowLayout::new(Vec::new());
        let cube = Cube {
            min: [0, 0, 0],
            bits: 30,
        };
        let mut rng = Rng::new(11, 0, 0);
        let points: Vec<[i32; 3]> = (0..60_000)
            .map(|_| [0, 1, 2].map(|_| (rng.unit() * 4096.0) as i32))
            .collect();
        let rows: Vec<u8> = points
            .iter()
            .flat_map(|p| p.iter().flat_map(|v| v.to_le_bytes()))
            .collect();
        for sampling in [Sampling::Poisson, Sampling::Random] {
            let memory = ChunkMemory {
                rows: rows.clone(),
                ..ChunkMemory::default()
            };
            let mut builder = TreeBuilder::with_memory(memory, &layout, cube, sampling);
            let root = builder.build_chunk(NodeKey::ROOT);
            builder.finish(root);
            let mut seen = Vec::new();
            let mut deepest = 0;
            for n in &builder.finished {
                let cols = decode_node(&n.payload, n.point_count as usize, n.crc, &layout)
                    .expect("decodes");
                let (min, edge) = n.key.int_bounds(cube.min, cube.bits);
                let cell = (edge >> GRID_CELLS_LOG2).max(1);
                let mut cells = std::collections::HashSet::new();
                for i in 0..cols.count {
                    let p = cols.position(i);
                    assert!(
                        (0..3).all(|a| (p[a] as i64) >= min[a] && (p[a] as i64) < min[a] + edge)
                    );
                    if n.child_mask != 0 {
                        let c = [0, 1, 2].map(|a| (p[a] as i64 - min[a]) / cell);
                        assert!(cells.insert(c), "{:?}: two points in one cell", n.key);
                    }
                    seen.push(p);
                }
                deepest = deepest.max(n.key.level);
            }
            // 4096 units of a 2^30 cube: leaves sit below level 18, past the 12-bit key.
            assert!(deepest > 18, "deepest level {deepest}");
            let mut expect = points.clone();
            expect.sort();
            seen.sort();
            assert_eq!(seen, expect, "{sampling:?}");
        }
    }
}
