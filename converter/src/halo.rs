//! Gathering each chunk's halo. Before indexing, every chunk writes its band: its rows within
//! the margin of its own faces, the only ones another chunk's halo can hold. A chunk's halo is
//! then read from its neighbours' bands, not their whole chunk files, and the bands outlive the
//! chunk files, which indexing deletes as it commits.

use crate::chunk_step::{GridBox, Halo, row_in};
use crate::error::{ConvertError, Result, io_err, panic_message};
use crate::prepare::Plan;
use crate::rowfile::{RowWriter, for_each_block};
use crate::workdir::WorkDir;
use indicatif::ProgressBar;
use std::fs;
use std::path::Path;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

pub struct Halos {
    /// The margin in quantization steps per axis; all 0 when the step needs no halo.
    margin: [i64; 3],
    /// The margin in real units, as the step asked for it.
    asked: f64,
    boxes: Vec<GridBox>,
    /// For each chunk, the chunks whose band can reach into its halo.
    neighbours: Vec<Vec<usize>>,
    stride: usize,
    /// For each chunk, the bands no chunk after it reads: removed once it commits.
    release_at: Vec<Vec<usize>>,
    /// Rows read from bands, all chunks together.
    rows_read: AtomicU64,
}

impl Halos {
    /// The halos for a step asking for `margin` real units around each chunk.
    pub fn new(plan: &Plan, stride: usize, margin: f64) -> Self {
        let margin_real = margin;
        // Whole quantization steps, rounding down: a point one more step out is beyond the
        // margin. The tolerance keeps e.g. 0.3 / 0.001 from landing just under 300.
        let margin = [0, 1, 2].map(|a| {
            let steps = margin / plan.scale[a].abs() * (1.0 + 1e-12);
            if steps.is_finite() && steps >= 1.0 {
                steps.floor().min(i64::MAX as f64 / 4.0) as i64
            } else {
                0
            }
        });
        let boxes: Vec<GridBox> = plan
            .chunks
            .iter()
            .map(|c| GridBox::of_chunk(c, &plan.cube))
            .collect();
        let mut neighbours = vec![Vec::new(); boxes.len()];
        if margin != [0; 3] {
            for (i, b) in boxes.iter().enumerate() {
                let reach = b.grown(margin);
                neighbours[i] = (0..boxes.len())
                    .filter(|&j| j != i && reach.intersects(&boxes[j]))
                    .collect();
            }
        }
        // A band is read by its own chunk's neighbours only (and written from its own chunk).
        let mut release_at = vec![Vec::new(); boxes.len()];
        for (j, n) in neighbours.iter().enumerate() {
            let last = n.iter().copied().max().unwrap_or(j).max(j);
            release_at[last].push(j);
        }
        Halos {
            release_at,
            margin,
            asked: margin_real,
            boxes,
            neighbours,
            stride,
            rows_read: AtomicU64::new(0),
        }
    }

    /// The chunks whose bands chunk `chunk`'s halo is gathered from.
    pub fn neighbours(&self, chunk: usize) -> &[usize] {
        &self.neighbours[chunk]
    }

    /// Chunk `chunk`'s box grown by the margin: its halo lies in here.
    pub fn reach(&self, chunk: usize) -> GridBox {
        self.boxes[chunk].grown(self.margin)
    }

    /// Chunk `chunk`'s box shrunk by the margin: no other chunk's halo reaches in here, so its
    /// band holds the rest.
    pub fn inner(&self, chunk: usize) -> GridBox {
        self.boxes[chunk].grown(self.margin.map(|m| -m))
    }

    /// Whether any chunk can have a halo, so that bands are worth writing.
    pub fn needed(&self) -> bool {
        self.margin != [0; 3]
    }

    pub fn rows_read(&self) -> u64 {
        self.rows_read.load(Ordering::Relaxed)
    }

    /// Writes the band of each chunk from `first` on that has none yet (earlier ones were
    /// committed by an interrupted run, so theirs exist already), `threads` at a time.
    pub fn write_bands(
        &self,
        wd: &WorkDir,
        first: usize,
        parts: usize,
        threads: usize,
        bar: &ProgressBar,
    ) -> Result<()> {
        let chunks: Vec<usize> = (first..self.boxes.len()).collect();
        self.write_bands_of(wd, &chunks, parts, threads, bar)
    }

    /// Writes the bands of `chunks` that have none yet, `threads` at a time.
    pub fn write_bands_of(
        &self,
        wd: &WorkDir,
        chunks: &[usize],
        parts: usize,
        threads: usize,
        bar: &ProgressBar,
    ) -> Result<()> {
        let dir = wd.bands();
        fs::create_dir_all(&dir).map_err(io_err(&dir, "cannot create work directory"))?;
        let next = AtomicUsize::new(0);
        let results: Vec<Result<()>> = std::thread::scope(|scope| {
            let workers: Vec<_> = (0..threads.max(1))
                .map(|_| {
                    scope.spawn(|| {
                        loop {
                            let Some(&i) = chunks.get(next.fetch_add(1, Ordering::SeqCst)) else {
                                return Ok(());
                            };
                            self.write_band(wd, i, parts)?;
                            bar.inc(1);
                        }
                    })
                })
                .collect();
            workers
                .into_iter()
                .map(|w| {
                    w.join().unwrap_or_else(|p| {
                        Err(ConvertError::internal(
                            "writing chunk bands",
                            panic_message(p.as_ref()),
                        ))
                    })
                })
                .collect()
        });
        results.into_iter().collect()
    }

    fn write_band(&self, wd: &WorkDir, chunk: usize, parts: usize) -> Result<()> {
        let path = wd.chunk_band(chunk);
        if path.exists() {
            return Ok(());
        }
        let inner = self.inner(chunk);
        let part_path = path.with_extension("part");
        let mut out = RowWriter::create(&part_path, self.stride)?;
        for part in 0..parts {
            let src = wd.chunk_part(chunk, part);
            for_each_row(&src, self.stride, |row| {
                if !row_in(&inner, row) {
                    out.write(row)?;
                }
                Ok(())
            })?;
        }
        out.finish()?;
        // Renamed only once whole, so a resumed run never takes a cut band for a full one.
        fs::rename(&part_path, &path).map_err(io_err(&path, "cannot write"))
    }

    /// Removes the bands no chunk after `committed` reads, now that it has committed. An
    /// interrupted run resumes after its last committed chunk, so it never needs them.
    pub fn release(&self, wd: &WorkDir, committed: usize) -> Result<()> {
        if !self.needed() {
            return Ok(());
        }
        for &j in &self.release_at[committed] {
            let path = wd.chunk_band(j);
            match fs::remove_file(&path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(ConvertError::io(&path, "cannot remove band file", e));
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// Fills `halo` with chunk `chunk`'s halo; reads nothing when no halo is needed.
    pub fn gather(&self, wd: &WorkDir, chunk: usize, halo: &mut Halo) -> Result<()> {
        halo.rows.clear();
        halo.stride = self.stride;
        halo.margin = self.asked;
        halo.reach = self.reach(chunk);
        let reach = halo.reach;
        let mut read = 0u64;
        for &j in &self.neighbours[chunk] {
            for_each_row(&wd.chunk_band(j), self.stride, |row| {
                read += 1;
                if row_in(&reach, row) {
                    halo.rows.extend_from_slice(row);
                }
                Ok(())
            })?;
        }
        self.rows_read.fetch_add(read, Ordering::Relaxed);
        Ok(())
    }
}

/// Calls `each` on every row of the compressed row file at `path`; no file, no rows (a chunk
/// part with no rows has no file).
fn for_each_row(
    path: &Path,
    stride: usize,
    mut each: impl FnMut(&[u8]) -> Result<()>,
) -> Result<()> {
    for_each_block(path, stride, |rows| {
        rows.chunks_exact(stride).try_for_each(&mut each)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::Chunk;
    use strata_format::Cube;

    /// A 16-unit cube cut into its eight octants, holding one point at every integer
    /// position, each chunk's rows in part 0.
    fn octants(wd: &WorkDir) -> Plan {
        let cube = Cube {
            min: [0; 3],
            bits: 4,
        };
        let chunks: Vec<Chunk> = (0..8)
            .map(|o| Chunk {
                level: 1,
                x: o >> 2,
                y: (o >> 1) & 1,
                z: o & 1,
                points: 512,
            })
            .collect();
        let mut rows = vec![Vec::new(); 8];
        for x in 0..16i32 {
            for y in 0..16i32 {
                for z in 0..16i32 {
                    let o = ((x >> 3) << 2 | (y >> 3) << 1 | (z >> 3)) as usize;
                    for v in [x, y, z] {
                        rows[o].extend_from_slice(&v.to_le_bytes());
                    }
                }
            }
        }
        fs::create_dir_all(wd.chunks()).expect("chunk dir");
        for (i, r) in rows.iter().enumerate() {
            crate::rowfile::append_block(&wd.chunk_part(i, 0), r, 12, &mut Default::default())
                .expect("chunk file");
        }
        Plan {
            fingerprint: String::new(),
            attributes: Vec::new(),
            points: 4096,
            scale: [0.5; 3],
            offset: [0.0; 3],
            coarsened: false,
            warnings: Vec::new(),
            min: [0.0; 3],
            max: [7.5; 3],
            cube,
            chunks,
            classes: Vec::new(),
            spacing_quantiles: [0.0; 3],
            scanners: Vec::new(),
            scanner_inputs: Vec::new(),
            crs: None,
        }
    }

    #[test]
    fn halo_is_every_other_point_within_the_margin() {
        let dir = tempfile::tempdir().expect("tempdir");
        let wd = WorkDir::for_output(&dir.path().join("ds"));
        let plan = octants(&wd);
        // 1.0 real unit is 2 steps of 0.5.
        let halos = Halos::new(&plan, 12, 1.0);
        assert!(halos.needed());
        halos
            .write_bands(&wd, 0, 1, 2, &ProgressBar::hidden())
            .expect("bands");
        let mut halo = Halo::default();
        for (i, chunk) in plan.chunks.iter().enumerate() {
            halos.gather(&wd, i, &mut halo).expect("gather");
            let own = GridBox::of_chunk(chunk, &plan.cube);
            assert_eq!(halo.reach(), own.grown([2; 3]));
            // Inside the cube, an octant's 8^3 box grown by 2 toward the centre only: 10^3.
            assert_eq!(halo.len(), 10 * 10 * 10 - 8 * 8 * 8, "chunk {i}");
            for row in halo.rows() {
                let p = strata_format::row_position(row);
                assert!(!own.contains(p) && halo.reach().contains(p), "{p:?}");
            }
        }
        // Each chunk read the bands of its 7 neighbours: all but the 4^3 inner rows of each.
        assert_eq!(halos.rows_read(), 8 * 7 * (512 - 64));
        // Every octant touches chunk 7, the last: no band can go before it commits.
        for i in 0..7 {
            halos.release(&wd, i).expect("release");
            assert!((0..8).all(|j| wd.chunk_band(j).exists()), "after {i}");
        }
        halos.release(&wd, 7).expect("release");
        assert!((0..8).all(|j| !wd.chunk_band(j).exists()));
    }

    #[test]
    fn no_margin_reads_nothing() {
        let dir = tempfile::tempdir().expect("tempdir");
        let wd = WorkDir::for_output(&dir.path().join("ds"));
        let plan = octants(&wd);
        // Below one step of the grid, no point can be within the margin.
        for margin in [0.0, 0.4, -1.0, f64::NAN] {
            let halos = Halos::new(&plan, 12, margin);
            assert!(!halos.needed());
            let mut halo = Halo::default();
            for i in 0..plan.chunks.len() {
                halos.gather(&wd, i, &mut halo).expect("gather");
                assert!(halo.is_empty());
                assert_eq!(halo.reach(), GridBox::of_chunk(&plan.chunks[i], &plan.cube));
            }
            assert_eq!(halos.rows_read(), 0);
        }
        assert!(!wd.bands().exists());
    }
}
