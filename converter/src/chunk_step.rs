//! The per-chunk step: what runs on a chunk's rows between reading them and building its tree
//! (per-point computations such as normals). A step that needs to see across the chunk's faces
//! asks for a margin and gets the halo: the points of the other chunks within that margin.

use crate::error::Result;
use crate::plan::Chunk;
use crate::prepare::Plan;
use strata_format::{Attribute, Cube, Metadata, RowLayout, row_position};

/// Sums a step reports for one chunk; a conversion adds them up over its chunks (and keeps
/// them in the journal, so a resumed run has them too).
pub type StepTotals = Vec<f64>;

/// A per-chunk computation. It runs on several chunks at once, each on a worker of its own.
pub trait ChunkStep: Sync {
    /// What tells this step's output apart from another's, so that `--resume` does not mix
    /// chunks made with other settings. Empty for a step that changes nothing.
    fn fingerprint(&self) -> String {
        String::new()
    }

    /// Attributes the step writes that the inputs lack, appended to the dataset's attributes
    /// (rows start with them zero). `inputs` are the inputs' attributes.
    fn attributes(&self, _inputs: &[Attribute]) -> Result<Vec<Attribute>> {
        Ok(Vec::new())
    }

    /// Bytes a point of the chunk (or its halo) takes in the step's own working memory at its
    /// peak, rows of `stride` bytes, so that chunks are cut small enough for `--memory-limit`.
    fn bytes_per_point(&self, _stride: usize) -> usize {
        0
    }

    /// How far beyond its chunk's bounds, in the dataset's real units, the step needs to see
    /// points. 0 (the default) reads nothing beyond the chunk. It must depend on nothing but
    /// the plan and the step's settings: a resumed run asks again.
    fn halo_margin(&self, _plan: &Plan) -> f64 {
        0.0
    }

    /// Runs on a chunk's rows just read. It may rewrite the rows' attributes but must keep
    /// every row, its position and the layout: the tree and the output depend on them.
    fn process(&self, chunk: &mut ChunkRows, halo: &Halo) -> Result<StepTotals>;

    /// Records what the step did, from the totals over every chunk, in the metadata.
    fn record(&self, _totals: &[f64], _meta: &mut Metadata) {}

    /// What the user should know of the result, from the same totals: one sentence each.
    fn warnings(&self, _totals: &[f64]) -> Vec<String> {
        Vec::new()
    }
}

/// The step of a plain conversion: nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoStep;

impl ChunkStep for NoStep {
    fn process(&self, _chunk: &mut ChunkRows, _halo: &Halo) -> Result<StepTotals> {
        Ok(Vec::new())
    }
}

/// Adds one chunk's totals into the running ones.
pub fn add_totals(into: &mut StepTotals, chunk: &[f64]) {
    if into.len() < chunk.len() {
        into.resize(chunk.len(), 0.0);
    }
    for (a, b) in into.iter_mut().zip(chunk) {
        *a += b;
    }
}

/// One chunk's rows as the step sees them.
pub struct ChunkRows<'a> {
    /// The chunk's index in the plan.
    pub index: usize,
    /// Every row's position lies in here.
    pub bounds: GridBox,
    /// Real position = offset + scale * quantized position, per axis.
    pub scale: [f64; 3],
    pub offset: [f64; 3],
    pub layout: &'a RowLayout,
    /// Rows of `layout.stride` bytes, in no particular order.
    pub rows: &'a mut Vec<u8>,
    /// Where the scanners stood, in real coordinates, for inputs that say so (E57 poses).
    pub scanners: &'a [[f64; 3]],
}

/// The rows of other chunks that lie within the step's margin of a chunk: inside `reach`, the
/// chunk's bounds grown by the margin, and outside the chunk.
#[derive(Debug, Default)]
pub struct Halo {
    pub(crate) rows: Vec<u8>,
    pub(crate) stride: usize,
    pub(crate) reach: GridBox,
    pub(crate) margin: f64,
}

impl Halo {
    pub fn rows(&self) -> impl Iterator<Item = &[u8]> {
        self.rows.chunks_exact(self.stride.max(1))
    }

    pub fn len(&self) -> usize {
        self.rows.len() / self.stride.max(1)
    }

    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// The margin the step asked for, in real units: every point within it of the chunk
    /// (by Euclidean distance) is in the chunk or the halo.
    pub fn margin(&self) -> f64 {
        self.margin
    }

    /// The box the halo was gathered from: the chunk's bounds grown by the margin (equal to
    /// them when the step asks for none).
    pub fn reach(&self) -> GridBox {
        self.reach
    }
}

/// An axis-aligned box of quantized positions: `min` inclusive, `max` exclusive.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GridBox {
    pub min: [i64; 3],
    pub max: [i64; 3],
}

impl GridBox {
    /// The part of `cube` that chunk `chunk` covers.
    pub fn of_chunk(chunk: &Chunk, cube: &Cube) -> Self {
        let shift = cube.bits.saturating_sub(chunk.level as u32);
        let at = [chunk.x, chunk.y, chunk.z];
        GridBox {
            min: [0, 1, 2].map(|a| cube.min[a] + ((at[a] as i64) << shift)),
            max: [0, 1, 2].map(|a| cube.min[a] + ((at[a] as i64 + 1) << shift)),
        }
    }

    /// Grown by `by[a]` on both sides along axis `a`; a negative `by` shrinks it.
    pub fn grown(&self, by: [i64; 3]) -> Self {
        GridBox {
            min: [0, 1, 2].map(|a| self.min[a] - by[a]),
            max: [0, 1, 2].map(|a| self.max[a] + by[a]),
        }
    }

    pub fn contains(&self, p: [i32; 3]) -> bool {
        (0..3).all(|a| self.min[a] <= p[a] as i64 && (p[a] as i64) < self.max[a])
    }

    pub fn intersects(&self, other: &GridBox) -> bool {
        (0..3).all(|a| self.min[a] < other.max[a] && other.min[a] < self.max[a])
    }
}

/// Whether `row`'s position lies in `b`.
pub(crate) fn row_in(b: &GridBox, row: &[u8]) -> bool {
    b.contains(row_position(row))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunk_boxes_tile_the_cube() {
        let cube = Cube {
            min: [-8, 0, 100],
            bits: 4,
        };
        let chunk = |level, x, y, z| Chunk {
            level,
            x,
            y,
            z,
            points: 1,
        };
        assert_eq!(
            GridBox::of_chunk(&chunk(0, 0, 0, 0), &cube),
            GridBox {
                min: [-8, 0, 100],
                max: [8, 16, 116]
            }
        );
        let b = GridBox::of_chunk(&chunk(2, 3, 0, 1), &cube);
        assert_eq!(b.min, [4, 0, 104]);
        assert_eq!(b.max, [8, 4, 108]);
        assert!(b.contains([4, 0, 104]) && !b.contains([8, 0, 104]));
        let neighbour = GridBox::of_chunk(&chunk(2, 3, 1, 1), &cube);
        assert!(!b.intersects(&neighbour));
        assert!(b.grown([0, 1, 0]).intersects(&neighbour));
    }
}
