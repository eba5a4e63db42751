//! Choosing a node's points from its children's: one point per cell of a 128^3 grid over the
//! node, so an inner node holds a spatially even subsample at its level's spacing.

use serde::{Deserialize, Serialize};
use strata_format::{GRID_CELLS_LOG2, row_position};

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

/// Marks which `candidates` (row indices) the node at integer corner `node_min` with edge
/// `2^node_bits` keeps. Returns one flag per candidate.
pub fn select(
    rows: &[u8],
    stride: usize,
    candidates: &[u32],
    node_min: [i64; 3],
    node_bits: u32,
    method: Sampling,
) -> Vec<bool> {
    let cell_shift = node_bits.saturating_sub(GRID_CELLS_LOG2);
    let cell_bits = node_bits - cell_shift;
    let cell_of = |p: [i32; 3]| -> (u32, [i64; 3]) {
        let r = [
            p[0] as i64 - node_min[0],
            p[1] as i64 - node_min[1],
            p[2] as i64 - node_min[2],
        ];
        let c = |a: usize| (r[a] >> cell_shift) as u32;
        ((c(0) << (2 * cell_bits)) | (c(1) << cell_bits) | c(2), r)
    };
    let mut keep = vec![false; candidates.len()];
    match method {
        Sampling::Random => {
            let mut taken = vec![0u64; (1usize << (3 * cell_bits)).div_ceil(64)];
            for (i, &idx) in candidates.iter().enumerate() {
                let at = idx as usize * stride;
                let (cell, _) = cell_of(row_position(&rows[at..at + 12]));
                let (w, b) = ((cell >> 6) as usize, cell & 63);
                if taken[w] & (1 << b) == 0 {
                    taken[w] |= 1 << b;
                    keep[i] = true;
                }
            }
        }
        Sampling::Poisson => {
            let half = if cell_shift == 0 {
                0.0
            } else {
                (1u64 << cell_shift) as f32 / 2.0
            };
            let mask = (1i64 << cell_shift) - 1;
            // (cell << 32 | distance bits, candidate): non-negative f32 bits sort like the
            // floats, so sorting puts each cell's nearest-to-centre point first.
            let mut order: Vec<(u64, u32)> = candidates
                .iter()
                .enumerate()
                .map(|(i, &idx)| {
                    let at = idx as usize * stride;
                    let (cell, r) = cell_of(row_position(&rows[at..at + 12]));
                    let d = |a: usize| (r[a] & mask) as f32 + 0.5 - half;
                    let dist = d(0) * d(0) + d(1) * d(1) + d(2) * d(2);
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

#[cfg(test)]
mod tests {
    use super::*;

    fn rows(points: &[[i32; 3]]) -> Vec<u8> {
        points
            .iter()
            .flat_map(|p| p.iter().flat_map(|v| v.to_le_bytes()))
            .collect()
    }

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
        let r = rows(&pts);
        let idx: Vec<u32> = (0..pts.len() as u32).collect();
        let keep = select(&r, 12, &idx, [0, 0, 0], 10, Sampling::Poisson);
        assert_eq!(keep, vec![false, true, false, true, true]);
        let keep = select(&r, 12, &idx, [0, 0, 0], 10, Sampling::Random);
        assert_eq!(keep, vec![true, false, false, true, true]);
    }
}
