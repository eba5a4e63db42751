//! Which points go into which COPC node. COPC's octree is a cube in real units, centred and
//! sized as its info VLR says; a reader finds a node's bounds from that centre and half size.
//! Each point is keyed with the reader's own formula, at the level of the Strata node that
//! holds it, so that it lies within the bounds any reader computes for its node. Where the
//! dataset has one scale for x, y and z, Strata's integer cube is that cube and each Strata
//! node is one COPC node; where the scales differ (conversions before one step per axis did so
//! for PLY and E57 inputs), a COPC node takes the points of the Strata nodes of its level whose
//! boxes meet it (at most two per axis). Keys without points above keyed ones are listed
//! empty, as the hierarchy of a reader that walks it from the root needs.

use std::collections::{BTreeMap, BTreeSet};
use strata_format::{GRID_CELLS_LOG2, Metadata, NodeInfo};

/// One COPC node to write: its key (level, x, y, z) and the Strata nodes its points come from
/// (none for an empty node above others).
pub struct CopcNode {
    pub key: [i32; 4],
    pub sources: Vec<NodeInfo>,
}

/// COPC's cube in real units, and how a stored position finds its node in it.
#[derive(Debug, Clone, Copy)]
pub struct Grid {
    /// The cube's centre and half size, as the info VLR states them.
    pub centre: [f64; 3],
    pub half: f64,
    scale: [f64; 3],
    offset: [f64; 3],
}

/// The centre of a cube `half` either side of it whose low corner is `low` as a reader
/// computes it (centre - half): rounding put that above the cube's, and so above its lowest
/// point, by a hair, so the centre steps down until it is not.
fn centre_above(low: f64, half: f64) -> f64 {
    let mut centre = low + half;
    while centre - half > low {
        centre = centre.next_down();
    }
    centre
}

impl Grid {
    pub fn of(meta: &Metadata) -> Grid {
        let s = meta.scale;
        let edge = s.iter().fold(0.0f64, |m, v| m.max(*v)) * (1u64 << meta.cube.bits) as f64;
        let half = edge / 2.0;
        Grid {
            centre: std::array::from_fn(|k| {
                centre_above(meta.offset[k] + s[k] * meta.cube.min[k] as f64, half)
            }),
            half,
            scale: s,
            offset: meta.offset,
        }
    }

    /// The root's point spacing: its edge over the sampling grid's cells, as Strata's own.
    pub fn spacing(&self) -> f64 {
        2.0 * self.half / (1u64 << GRID_CELLS_LOG2) as f64
    }

    /// The lower bound, along axis `k`, of cell `i` of `cells`, as a reader computes it.
    fn low(&self, k: usize, cells: f64, i: f64) -> f64 {
        (self.centre[k] - self.half) + (2.0 * self.half / cells) * i
    }

    /// The cell of `cells` along axis `k` that holds `real` by the reader's bounds.
    fn cell(&self, k: usize, cells: f64, real: f64) -> i32 {
        let min = self.centre[k] - self.half;
        let mut i = ((real - min) / (2.0 * self.half) * cells)
            .floor()
            .clamp(0.0, cells - 1.0);
        // One step either way where the division rounded across a cell's edge.
        if i > 0.0 && real < self.low(k, cells, i) {
            i -= 1.0;
        } else if i < cells - 1.0 && real >= self.low(k, cells, i + 1.0) {
            i += 1.0;
        }
        i as i32
    }

    fn real(&self, k: usize, int: i64) -> f64 {
        self.offset[k] + self.scale[k] * int as f64
    }

    /// The node at `level` holding the stored position `p`.
    pub fn key_of(&self, level: u8, p: [i32; 3]) -> [i32; 4] {
        let cells = (1u64 << level) as f64;
        let c = |k: usize| self.cell(k, cells, self.real(k, p[k] as i64));
        [level as i32, c(0), c(1), c(2)]
    }

    /// The cells at the Strata node `n`'s level that its box meets, per axis.
    fn cells_met(&self, n: &NodeInfo, bits: u32, cube_min: [i64; 3]) -> [(i32, i32); 3] {
        let (min, side) = n.key.int_bounds(cube_min, bits);
        let cells = (1u64 << n.key.level) as f64;
        std::array::from_fn(|k| {
            let at = |int: i64| self.cell(k, cells, self.real(k, int));
            (at(min[k]), at(min[k] + side - 1))
        })
    }
}

/// The COPC nodes of the dataset's `nodes` (those with points), in key order, with the empty
/// ones above them.
pub fn plan(meta: &Metadata, nodes: Vec<NodeInfo>) -> Vec<CopcNode> {
    let grid = Grid::of(meta);
    let mut met: BTreeMap<[i32; 4], Vec<NodeInfo>> = BTreeMap::new();
    for n in nodes {
        let r = grid.cells_met(&n, meta.cube.bits, meta.cube.min);
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
    let mut above: BTreeSet<[i32; 4]> = BTreeSet::new();
    for key in met.keys() {
        let mut k = *key;
        while k[0] > 0 {
            k = [k[0] - 1, k[1] >> 1, k[2] >> 1, k[3] >> 1];
            if met.contains_key(&k) || !above.insert(k) {
                break;
            }
        }
    }
    for k in above {
        met.entry(k).or_default();
    }
    met.into_iter()
        .map(|(key, sources)| CopcNode { key, sources })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_position_lies_within_the_bounds_a_reader_gives_its_cell() {
        // x and z at 1e-9, y at 1e-8: the real cube is y's, ten times x's and z's extent.
        let g = Grid {
            centre: [0.5 * 1e-8 * 1024.0; 3],
            half: 0.5 * 1e-8 * 1024.0,
            scale: [1e-9, 1e-8, 1e-9],
            offset: [0.0; 3],
        };
        assert_eq!(g.key_of(0, [1023, 1023, 0]), [0, 0, 0, 0]);
        assert_eq!(g.key_of(1, [1023, 1023, 0]), [1, 0, 1, 0]);
        assert_eq!(g.key_of(5, [1023, 512, 0]), [5, 3, 16, 0]);
        // Odd scales and offsets: every position within its cell's bounds at every level.
        let g = Grid {
            centre: [636657.11, 849590.55, 1061.61],
            half: 655.36,
            scale: [0.01, 0.01, 0.025],
            offset: [0.0, 0.0, 3.3],
        };
        for int in (63_600_000i64..63_800_000).step_by(997) {
            let p = [
                int as i32,
                (int + 21_300_000) as i32,
                ((int - 63_600_000) / 9) as i32,
            ];
            for level in 0..12u8 {
                let key = g.key_of(level, p);
                let cells = (1u64 << level) as f64;
                for k in 0..3 {
                    let real = g.real(k, p[k] as i64);
                    let i = key[k + 1] as f64;
                    let inside = real >= g.low(k, cells, i) && real < g.low(k, cells, i + 1.0);
                    let at_ends = (i == 0.0 && real < g.low(k, cells, 1.0))
                        || (i == cells - 1.0 && real >= g.low(k, cells, i));
                    assert!(inside || at_ends, "{p:?} level {level} axis {k}: cell {i}");
                }
            }
        }
    }

    #[test]
    fn the_cube_a_reader_computes_holds_its_low_corner() {
        // 100.08 with a half of 0.01 * 2^19: centre - half was 100.0800000000745.
        for low in [100.08, 0.1, 1e6 + 0.07, -37.13, 3.3, 0.0] {
            for half in [0.01 * 524_288.0, 655.36, 1e-9 * 512.0] {
                let centre = centre_above(low, half);
                assert!(centre - half <= low, "{low} {half}");
                assert!(low + half - centre < 1e-9 * half.max(1.0), "{low} {half}");
            }
        }
    }
}
