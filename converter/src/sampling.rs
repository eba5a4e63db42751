//! Choosing a node's points from its children's: one point per cell of a 128^3 grid over the
//! node, so an inner node holds a spatially even subsample at its level's spacing.

use serde::{Deserialize, Serialize};
use strata_format::GRID_CELLS_LOG2;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Sampling {
    /// Per cell, the point nearest the cell's centre: even, Poisson-disk-like spacing.
    #[default]
    Poisson,
    /// Per cell, the first point met: faster, less even.
    Random,
}

impl Sampling {
    pub fn name(self) -> &'static str {
        match self {
            Sampling::Poisson => "poisson",
            Sampling::Random => "random",
        }
    }
}

/// A node's sampling grid: `2^shift`-unit cells from its corner.
struct CellGrid {
    min: [i64; 3],
    shift: u32,
    mask: i64,
    half: f32,
}

impl CellGrid {
    fn new(node_min: [i64; 3], node_bits: u32) -> Self {
        let shift = node_bits.saturating_sub(GRID_CELLS_LOG2);
        CellGrid {
            min: node_min,
            shift,
            mask: (1i64 << shift) - 1,
            half: if shift == 0 {
                0.0
            } else {
                (1u64 << shift) as f32 / 2.0
            },
        }
    }

    /// The cell (per axis) of `p`, and its squared distance from that cell's centre.
    #[inline]
    fn locate(&self, p: [i32; 3]) -> ([i64; 3], f32) {
        let r = [0, 1, 2].map(|a| p[a] as i64 - self.min[a]);
        let d = |a: usize| (r[a] & self.mask) as f32 + 0.5 - self.half;
        (
            r.map(|v| v >> self.shift),
            d(0) * d(0) + d(1) * d(1) + d(2) * d(2),
        )
    }
}

/// Marks which `candidates` (indices into `pos`) the node at integer corner `node_min` with
/// edge `2^node_bits` keeps. Returns one flag per candidate.
pub fn select(
    pos: &[[i32; 3]],
    candidates: &[u32],
    node_min: [i64; 3],
    node_bits: u32,
    method: Sampling,
) -> Vec<bool> {
    let grid = CellGrid::new(node_min, node_bits);
    let cell_bits = node_bits - grid.shift;
    let cell_of = |p: [i32; 3]| -> (u32, f32) {
        let (c, dist) = grid.locate(p);
        let c = c.map(|v| v as u32);
        ((c[0] << (2 * cell_bits)) | (c[1] << cell_bits) | c[2], dist)
    };
    let mut keep = vec![false; candidates.len()];
    match method {
        Sampling::Random => {
            let mut taken = vec![0u64; (1usize << (3 * cell_bits)).div_ceil(64)];
            for (i, &idx) in candidates.iter().enumerate() {
                let (cell, _) = cell_of(pos[idx as usize]);
                let (w, b) = ((cell >> 6) as usize, cell & 63);
                if taken[w] & (1 << b) == 0 {
                    taken[w] |= 1 << b;
                    keep[i] = true;
                }
            }
        }
        Sampling::Poisson => {
            // (cell << 32 | distance bits, candidate): non-negative f32 bits sort like the
            // floats, so sorting puts each cell's nearest-to-centre point first.
            let mut order: Vec<(u64, u32)> = candidates
                .iter()
                .enumerate()
                .map(|(i, &idx)| {
                    let (cell, dist) = cell_of(pos[idx as usize]);
                    (((cell as u64) << 32) | dist.to_bits() as u64, i as u32)
                })
                .collect();
            order.sort_unstable();
            let mut last = u64::MAX;
            for (k, i) in order {
                let cell = k >> 32;
                if cell != last {
                    keep[i as usize] = true;
                    last = cell;
                }
            }
        }
    }
    keep
}

/// `select` for candidates already in Morton order within the node (see `morton`), where each
/// sampling cell is one run: a single pass, no sort. Ties keep the first point met, as `select`.
pub fn select_ordered(
    pos: &[[i32; 3]],
    candidates: &[u32],
    node_min: [i64; 3],
    node_bits: u32,
    method: Sampling,
) -> Vec<bool> {
    let grid = CellGrid::new(node_min, node_bits);
    let mut keep = vec![false; candidates.len()];
    let mut last = [i64::MIN; 3];
    let mut best: Option<(usize, f32)> = None;
    for (i, &idx) in candidates.iter().enumerate() {
        let (cell, dist) = grid.locate(pos[idx as usize]);
        let new_cell = cell != last;
        if new_cell {
            if let Some((b, _)) = best.take() {
                keep[b] = true;
            }
            last = cell;
        }
        match method {
            Sampling::Random => {
                if new_cell {
                    keep[i] = true;
                }
            }
            Sampling::Poisson => {
                if best.is_none_or(|(_, bd)| dist < bd) {
                    best = Some((i, dist));
                }
            }
        }
    }
    if let Some((b, _)) = best {
        keep[b] = true;
    }
    keep
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_one_point_per_cell_nearest_the_centre() {
        // Node edge 2^10: cells of 8 units. Cell 0 centre is (4,4,4).
        let pts = [
            [0, 0, 0],
            [4, 4, 3],
            [7, 7, 7],
            [9, 0, 0],
            [1000, 1000, 1000],
        ];
        let r = pts;
        let idx: Vec<u32> = (0..pts.len() as u32).collect();
        let keep = select(&r, &idx, [0, 0, 0], 10, Sampling::Poisson);
        assert_eq!(keep, vec![false, true, false, true, true]);
        let keep = select(&r, &idx, [0, 0, 0], 10, Sampling::Random);
        assert_eq!(keep, vec![true, false, false, true, true]);
        // The same points are in Morton order already: cells 0, 0, 0, 1, far.
        for method in [Sampling::Poisson, Sampling::Random] {
            assert_eq!(
                select_ordered(&r, &idx, [0, 0, 0], 10, method),
                select(&r, &idx, [0, 0, 0], 10, method)
            );
        }
    }
}
