//! The levels above the chunks, merged depth first: a chunk's root rows are loaded only when
//! its turn comes, and each node is handed out as soon as its parent has taken its sample, so
//! memory holds one path of open nodes, not every chunk root at once.

use crate::error::Result;
use crate::morton::{SortScratch, sort_positions};
use crate::sampling::{Sampling, select, select_ordered};
use crate::tree::FinishedNode;
use std::collections::{BTreeMap, BTreeSet};
use strata_format::{Cube, GRID_CELLS_LOG2, NodeKey, RowLayout, encode_node, row_position};

/// A node whose rows its parent may still take from.
struct Open {
    key: NodeKey,
    rows: Vec<u8>,
    child_mask: u8,
}

pub struct TopMerge<'a, L, E> {
    /// Chunk key to (chunk index, child mask of its root).
    roots: BTreeMap<NodeKey, (usize, u8)>,
    /// Every node strictly above a chunk root.
    above: BTreeSet<NodeKey>,
    layout: &'a RowLayout,
    cube: Cube,
    sampling: Sampling,
    scratch: SortScratch,
    /// Reads chunk `i`'s root rows.
    load: L,
    /// Takes each finished node, in the order they finish.
    emit: E,
}

impl<'a, L, E> TopMerge<'a, L, E>
where
    L: FnMut(usize) -> Result<Vec<u8>>,
    E: FnMut(FinishedNode) -> Result<()>,
{
    /// `roots`: each chunk's key and its root's child mask, by chunk index.
    pub fn new(
        roots: &[(NodeKey, u8)],
        layout: &'a RowLayout,
        cube: Cube,
        sampling: Sampling,
        load: L,
        emit: E,
    ) -> Self {
        let mut above = BTreeSet::new();
        for (k, _) in roots {
            let mut p = k.parent();
            while let Some(a) = p {
                above.insert(a);
                p = a.parent();
            }
        }
        TopMerge {
            roots: roots
                .iter()
                .enumerate()
                .map(|(i, &(k, mask))| (k, (i, mask)))
                .collect(),
            above,
            layout,
            cube,
            sampling,
            scratch: SortScratch::default(),
            load,
            emit,
        }
    }

    /// Merges everything up to the dataset root and emits it last.
    pub fn run(mut self) -> Result<()> {
        let root = self.merge(NodeKey::ROOT)?;
        self.finish(root)
    }

    fn merge(&mut self, key: NodeKey) -> Result<Open> {
        if let Some(&(i, child_mask)) = self.roots.get(&key) {
            return Ok(Open {
                key,
                rows: (self.load)(i)?,
                child_mask,
            });
        }
        let mut children = Vec::new();
        for o in 0..8 {
            let c = key.child(o);
            if self.roots.contains_key(&c) || self.above.contains(&c) {
                children.push(self.merge(c)?);
            }
        }
        self.adopt(key, children)
    }

    /// Gives `key` its sample of its children's rows, then finishes the children.
    fn adopt(&mut self, key: NodeKey, children: Vec<Open>) -> Result<Open> {
        let stride = self.layout.stride;
        let mut owner = Vec::new();
        let mut pos = Vec::new();
        for (ci, c) in children.iter().enumerate() {
            for row in c.rows.chunks_exact(stride) {
                owner.push(ci as u8);
                pos.push(row_position(row));
            }
        }
        let mut order: Vec<u32> = (0..pos.len() as u32).collect();
        let node_bits = self.cube.bits - key.level as u32;
        let (min, _) = key.int_bounds(self.cube.min, self.cube.bits);
        let shift = sort_positions(&mut pos, &mut order, min, node_bits, &mut self.scratch);
        let candidates: Vec<u32> = (0..pos.len() as u32).collect();
        let cell_shift = node_bits.saturating_sub(GRID_CELLS_LOG2);
        let pick = if shift <= cell_shift {
            select_ordered
        } else {
            select
        };
        let keep = pick(&pos, &candidates, min, node_bits, self.sampling);
        // Row `order[j]` of the children, counted across them, is at (child, offset).
        let mut first = Vec::with_capacity(children.len());
        let mut n = 0usize;
        for c in &children {
            first.push(n);
            n += c.rows.len() / stride;
        }
        let mut kept = Vec::new();
        let mut rest: Vec<Vec<u8>> = vec![Vec::new(); children.len()];
        for (j, &i) in order.iter().enumerate() {
            let ci = owner[i as usize] as usize;
            let at = (i as usize - first[ci]) * stride;
            let row = &children[ci].rows[at..at + stride];
            if keep[j] {
                kept.extend_from_slice(row);
            } else {
                rest[ci].extend_from_slice(row);
            }
        }
        let mut child_mask = 0u8;
        for (c, rows) in children.into_iter().zip(rest) {
            if rows.is_empty() && c.child_mask == 0 {
                continue;
            }
            child_mask |= 1 << c.key.octant();
            self.finish(Open { rows, ..c })?;
        }
        Ok(Open {
            key,
            rows: kept,
            child_mask,
        })
    }

    fn finish(&mut self, node: Open) -> Result<()> {
        let (payload, crc) = encode_node(&node.rows, self.layout);
        (self.emit)(FinishedNode {
            key: node.key,
            point_count: (node.rows.len() / self.layout.stride) as u32,
            child_mask: node.child_mask,
            payload,
            crc,
        })
    }
}
