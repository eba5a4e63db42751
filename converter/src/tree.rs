//! Building a layered octree over rows held in memory: leaves keep all their points, and each
//! inner node takes its subsample from its children, so every point is stored exactly once.

use crate::sampling::{Sampling, select};
use strata_format::{Cube, NodeKey, RowLayout, encode_node, row_position};

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

pub struct TreeBuilder<'a> {
    pub rows: &'a [u8],
    pub layout: &'a RowLayout,
    pub cube: Cube,
    pub sampling: Sampling,
    pub finished: Vec<FinishedNode>,
}

impl<'a> TreeBuilder<'a> {
    pub fn new(rows: &'a [u8], layout: &'a RowLayout, cube: Cube, sampling: Sampling) -> Self {
        TreeBuilder {
            rows,
            layout,
            cube,
            sampling,
            finished: Vec::new(),
        }
    }

    fn position(&self, idx: u32) -> [i32; 3] {
        let at = idx as usize * self.layout.stride;
        row_position(&self.rows[at..at + 12])
    }

    /// Builds the subtree of `key` over the rows `idx`; every node below `key` is finished,
    /// `key` itself is returned open.
    pub fn build(&mut self, key: NodeKey, idx: Vec<u32>) -> OpenNode {
        let node_bits = self.cube.bits - key.level as u32;
        if idx.len() <= LEAF_MAX || node_bits == 0 || key.level >= MAX_LEVEL {
            return OpenNode {
                key,
                points: idx,
                child_mask: 0,
            };
        }
        let (min, _) = key.int_bounds(self.cube.min, self.cube.bits);
        let half = node_bits - 1;
        let mut parts: [Vec<u32>; 8] = Default::default();
        for &i in &idx {
            let p = self.position(i);
            let b = |a: usize| (((p[a] as i64 - min[a]) >> half) & 1) as usize;
            parts[(b(0) << 2) | (b(1) << 1) | b(2)].push(i);
        }
        drop(idx);
        let mut children = Vec::new();
        for (o, part) in parts.into_iter().enumerate() {
            if !part.is_empty() {
                children.push(self.build(key.child(o as u8), part));
            }
        }
        self.adopt(key, children)
    }

    /// Gives `key` its sample of its children's points, then finishes the children.
    pub fn adopt(&mut self, key: NodeKey, mut children: Vec<OpenNode>) -> OpenNode {
        let node_bits = self.cube.bits - key.level as u32;
        let (min, _) = key.int_bounds(self.cube.min, self.cube.bits);
        let candidates: Vec<u32> = children
            .iter()
            .flat_map(|c| c.points.iter().copied())
            .collect();
        let keep = select(
            self.rows,
            self.layout.stride,
            &candidates,
            min,
            node_bits,
            self.sampling,
        );
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
        let stride = self.layout.stride;
        let mut gathered = Vec::with_capacity(node.points.len() * stride);
        for &i in &node.points {
            let at = i as usize * stride;
            gathered.extend_from_slice(&self.rows[at..at + stride]);
        }
        let (payload, crc) = encode_node(&gathered, self.layout);
        self.finished.push(FinishedNode {
            key: node.key,
            point_count: node.points.len() as u32,
            child_mask: node.child_mask,
            payload,
            crc,
        });
    }

    /// The rows of an open node, copied out.
    pub fn rows_of(&self, node: &OpenNode) -> Vec<u8> {
        let stride = self.layout.stride;
        let mut out = Vec::with_capacity(node.points.len() * stride);
        for &i in &node.points {
            let at = i as usize * stride;
            out.extend_from_slice(&self.rows[at..at + stride]);
        }
        out
    }
}

/// The top of the tree, above the chunks: each chunk's root rows and child mask go in, every
/// node from the chunk roots up to the dataset root comes out finished.
pub fn merge_top(
    roots: Vec<(NodeKey, Vec<u8>, u8)>,
    layout: &RowLayout,
    cube: Cube,
    sampling: Sampling,
) -> Vec<FinishedNode> {
    use std::collections::{BTreeMap, BTreeSet};
    let stride = layout.stride;
    let mut rows = Vec::new();
    let mut open: BTreeMap<NodeKey, OpenNode> = BTreeMap::new();
    for (key, r, mask) in roots {
        let first = (rows.len() / stride) as u32;
        let n = (r.len() / stride) as u32;
        rows.extend_from_slice(&r);
        open.insert(
            key,
            OpenNode {
                key,
                points: (first..first + n).collect(),
                child_mask: mask,
            },
        );
    }
    let mut ancestors: BTreeSet<NodeKey> = BTreeSet::new();
    for k in open.keys() {
        let mut p = k.parent();
        while let Some(a) = p {
            ancestors.insert(a);
            p = a.parent();
        }
    }
    let mut builder = TreeBuilder::new(&rows, layout, cube, sampling);
    let mut by_depth: Vec<NodeKey> = ancestors.into_iter().collect();
    by_depth.sort_by(|a, b| b.level.cmp(&a.level).then(a.cmp(b)));
    for key in by_depth {
        let children: Vec<OpenNode> = (0..8u8)
            .filter_map(|o| open.remove(&key.child(o)))
            .collect();
        let node = builder.adopt(key, children);
        open.insert(key, node);
    }
    if let Some(root) = open.remove(&NodeKey::ROOT) {
        builder.finish(root);
    }
    builder.finished
}
