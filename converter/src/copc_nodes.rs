//! Which points go into which COPC node. Where the dataset has one scale for x, y and z, its
//! integer cube is a cube in real units too and each Strata node is the COPC node of the same
//! key. Where the scales differ (PLY and E57 inputs pick one per axis), the real cube is COPC's
//! larger one: the points of each level are keyed again within it, a COPC node taking the
//! points of the Strata nodes of its level whose boxes meet it (at most two per axis).

use std::collections::BTreeMap;
use strata_format::{Metadata, NodeInfo};

/// One COPC node to write: its key (level, x, y, z), the Strata nodes its points come from,
/// and whether they must be picked out of them by position.
pub struct CopcNode {
    pub key: [i32; 4],
    pub sources: Vec<NodeInfo>,
    pub pick: bool,
}

/// COPC's cube in real units, and how a stored position finds its node in it.
#[derive(Debug, Clone, Copy)]
pub struct Grid {
    /// The cube's lowest corner and edge, in real units.
    pub min: [f64; 3],
    pub edge: f64,
    scale: [f64; 3],
    offset: [f64; 3],
}

impl Grid {
    pub fn of(meta: &Metadata) -> Grid {
        let s = meta.scale;
        let side = (1u64 << meta.cube.bits) as f64;
        Grid {
            min: std::array::from_fn(|k| meta.offset[k] + s[k] * meta.cube.min[k] as f64),
            edge: s.iter().fold(0.0f64, |m, v| m.max(*v)) * side,
            scale: s,
            offset: meta.offset,
        }
    }

    /// The node at `level` holding the stored position `p`.
    pub fn key_of(&self, level: u8, p: [i32; 3]) -> [i32; 4] {
        let cells = (1u64 << level) as f64;
        let index = |k: usize| {
            let real = self.offset[k] + self.scale[k] * p[k] as f64;
            let i = ((real - self.min[k]) / self.edge * cells).floor();
            i.clamp(0.0, cells - 1.0) as i32
        };
        [level as i32, index(0), index(1), index(2)]
    }

    /// The nodes at the Strata node `n`'s level that its box meets, as index ranges per axis.
    fn keys_met(&self, n: &NodeInfo, bits: u32, cube_min: [i64; 3]) -> [(i32, i32); 3] {
        let (min, side) = n.key.int_bounds(cube_min, bits);
        let cells = (1u64 << n.key.level) as f64;
        std::array::from_fn(|k| {
            let at = |int: i64| {
                let real = self.offset[k] + self.scale[k] * int as f64;
                ((real - self.min[k]) / self.edge * cells)
                    .floor()
                    .clamp(0.0, cells - 1.0) as i32
            };
            (at(min[k]), at(min[k] + side - 1))
        })
    }
}

/// The COPC nodes of `nodes` (the dataset's, with points), in key order within each level.
pub fn plan(meta: &Metadata, nodes: Vec<NodeInfo>) -> Vec<CopcNode> {
    let s = meta.scale;
    if s[0] == s[1] && s[1] == s[2] {
        return nodes
            .into_iter()
            .map(|n| CopcNode {
                key: [
                    n.key.level as i32,
                    n.key.x as i32,
                    n.key.y as i32,
                    n.key.z as i32,
                ],
                sources: vec![n],
                pick: false,
            })
            .collect();
    }
    let grid = Grid::of(meta);
    let mut met: BTreeMap<[i32; 4], Vec<NodeInfo>> = BTreeMap::new();
    for n in nodes {
        let r = grid.keys_met(&n, meta.cube.bits, meta.cube.min);
        for x in r[0].0..=r[0].1 {
            for y in r[1].0..=r[1].1 {
                for z in r[2].0..=r[2].1 {
                    met.entry([n.key.level as i32, x, y, z])
                        .or_default()
                        .push(n);
                }
            }
        }
    }
    met.into_iter()
        .map(|(key, sources)| CopcNode {
            key,
            sources,
            pick: true,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_position_lands_in_the_cell_of_the_larger_cube() {
        // x and z at 1e-9, y at 1e-8: the real cube is y's, ten times x's and z's extent.
        let g = Grid {
            min: [0.0; 3],
            edge: 1e-8 * 1024.0,
            scale: [1e-9, 1e-8, 1e-9],
            offset: [0.0; 3],
        };
        assert_eq!(g.key_of(0, [1023, 1023, 0]), [0, 0, 0, 0]);
        assert_eq!(g.key_of(1, [1023, 1023, 0]), [1, 0, 1, 0]);
        assert_eq!(g.key_of(3, [1023, 0, 1023]), [3, 0, 0, 0]);
        assert_eq!(g.key_of(5, [1023, 512, 0]), [5, 3, 16, 0]);
    }
}
