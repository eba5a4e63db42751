//! Gathering each chunk's halo. Before indexing, every chunk writes its bands: for each
//! neighbour whose halo it reaches into, the rows that lie there, in a file of their own. A
//! chunk's halo is then read from the bands written for it, not from its neighbours' whole
//! chunk files (nor from rows near their other faces, which other chunks need), and the bands
//! outlive the chunk files, which indexing deletes as it commits.

use crate::chunk_step::{GridBox, Halo, row_in};
use crate::error::{ConvertError, Result, io_err, panic_message, spawn_worker};
use crate::prepare::Plan;
use crate::rowfile::{RowWriter, count_rows, for_each_block};
use crate::workdir::WorkDir;
use indicatif::ProgressBar;
use std::fs;
use std::path::Path;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

/// The most band files a worker writes at once.
const MAX_OPEN_BANDS: usize = 64;

pub struct Halos {
    /// The margin in quantization steps per axis; all 0 when the step needs no halo.
    margin: [i64; 3],
    /// The margin in real units, as the step asked for it.
    asked: f64,
    boxes: Vec<GridBox>,
    /// For each chunk, the chunks whose rows can lie in its halo.
    neighbours: Vec<Vec<usize>>,
    /// For each chunk, the chunks whose halo its rows can lie in: it writes a band for each.
    readers: Vec<Vec<usize>>,
    stride: usize,
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
        let mut readers = vec![Vec::new(); boxes.len()];
        for (i, n) in neighbours.iter().enumerate() {
            for &j in n {
                readers[j].push(i);
            }
        }
        Halos {
            readers,
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

    /// Whether any chunk can have a halo, so that bands are worth writing.
    pub fn needed(&self) -> bool {
        self.margin != [0; 3]
    }

    /// The rows chunk `chunk`'s halo will gather: its bands', counted from their headers.
    pub fn rows_for(&self, wd: &WorkDir, chunk: usize) -> Result<u64> {
        let bands = self.neighbours.get(chunk).map_or(&[][..], Vec::as_slice);
        bands
            .iter()
            .map(|&j| count_rows(&wd.chunk_band(j, chunk), self.stride))
            .sum()
    }

    /// The margin in real units, as the step asked for it.
    pub fn margin(&self) -> f64 {
        self.asked
    }

    pub fn rows_read(&self) -> u64 {
        self.rows_read.load(Ordering::Relaxed)
    }

    /// Writes the bands of each chunk from `first` on for the chunks from `first` on, those
    /// that do not exist yet (earlier chunks were committed by an interrupted run: theirs
    /// exist already, and bands for them are needed no more), `threads` at a time.
    pub fn write_bands(
        &self,
        wd: &WorkDir,
        first: usize,
        parts: usize,
        threads: usize,
        bar: &ProgressBar,
    ) -> Result<()> {
        let chunks: Vec<usize> = (first..self.boxes.len()).collect();
        self.write_bands_of(wd, &chunks, |reader| reader >= first, parts, threads, bar)
    }

    /// Writes the bands of `chunks` for the readers `wanted` picks, those that do not exist
    /// yet, `threads` at a time.
    pub fn write_bands_of(
        &self,
        wd: &WorkDir,
        chunks: &[usize],
        wanted: impl Fn(usize) -> bool + Sync,
        parts: usize,
        threads: usize,
        bar: &ProgressBar,
    ) -> Result<()> {
        let dir = wd.bands();
        fs::create_dir_all(&dir).map_err(io_err(&dir, "cannot create work directory"))?;
        let next = AtomicUsize::new(0);
        let results: Vec<Result<()>> = std::thread::scope(|scope| {
            let workers: Vec<_> = (0..threads.max(1))
                .map(|k| {
                    spawn_worker(scope, "writing chunk bands", k, || {
                        loop {
                            let Some(&i) = chunks.get(next.fetch_add(1, Ordering::SeqCst)) else {
                                return Ok(());
                            };
                            self.write_band(wd, i, &wanted, parts)?;
                            bar.inc(1);
                        }
                    })
                })
                .collect();
            workers
                .into_iter()
                .map(|w| {
                    w?.join().unwrap_or_else(|p| {
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

    /// Writes chunk `chunk`'s band for each reader `wanted` picks, unless all exist already.
    fn write_band(
        &self,
        wd: &WorkDir,
        chunk: usize,
        wanted: &impl Fn(usize) -> bool,
        parts: usize,
    ) -> Result<()> {
        let readers: Vec<usize> = self.readers[chunk]
            .iter()
            .copied()
            .filter(|&r| wanted(r))
            .collect();
        if readers.iter().all(|&r| wd.chunk_band(chunk, r).exists()) {
            return Ok(());
        }
        // No other chunk's halo reaches this far in: most rows are tested once.
        let inner = self.boxes[chunk].grown(self.margin.map(|m| -m));
        // A coarse chunk beside many fine ones has many readers: their files are written a
        // group at a time, so that a worker holds no more than this many open.
        for group in readers.chunks(MAX_OPEN_BANDS) {
            let reaches: Vec<GridBox> = group.iter().map(|&r| self.reach(r)).collect();
            let mut outs = group
                .iter()
                .map(|&r| {
                    RowWriter::create_small(
                        &wd.chunk_band(chunk, r).with_extension("part"),
                        self.stride,
                    )
                })
                .collect::<Result<Vec<_>>>()?;
            for part in 0..parts {
                let src = wd.chunk_part(chunk, part);
                for_each_row(&src, self.stride, |row| {
                    if row_in(&inner, row) {
                        return Ok(());
                    }
                    // A row near a corner lies in several halos.
                    for (reach, out) in reaches.iter().zip(&mut outs) {
                        if row_in(reach, row) {
                            out.write(row)?;
                        }
                    }
                    Ok(())
                })?;
            }
            // Every band is a file, rows or none, so that a missing one is known for lost.
            for (out, &r) in outs.into_iter().zip(group) {
                out.finish()?;
                let path = wd.chunk_band(chunk, r);
                // Renamed only once whole, so a resumed run never takes a cut band for a full
                // one.
                fs::rename(path.with_extension("part"), &path)
                    .map_err(io_err(&path, "cannot write"))?;
            }
        }
        Ok(())
    }

    /// Removes the bands written for chunk `committed`, now that it has committed. An
    /// interrupted run resumes after its last committed chunk, so it never needs them.
    pub fn release(&self, wd: &WorkDir, committed: usize) -> Result<()> {
        if !self.needed() {
            return Ok(());
        }
        for &j in &self.neighbours[committed] {
            let path = wd.chunk_band(j, committed);
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
            let band = wd.chunk_band(j, chunk);
            if !band.exists() {
                return Err(ConvertError::input(
                    &band,
                    format!(
                        "chunk {j}'s band for chunk {chunk} is missing from the work directory: it was removed, or the work was begun by another version of strata; convert again from the start"
                    ),
                ));
            }
            for_each_row(&band, self.stride, |row| {
                read += 1;
                // Written for this chunk: every row lies in its reach (checked all the same,
                // as the halo's promise to the step).
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
        // Each chunk read the rows of its halo and no others.
        assert_eq!(halos.rows_read(), 8 * (10 * 10 * 10 - 8 * 8 * 8));
        // Each octant touches the 7 others; a chunk's bands go when it commits.
        let band = |j: usize, r: usize| wd.chunk_band(j, r).exists();
        for i in 0..8 {
            assert!((0..8).filter(|&j| j != i).all(|j| band(j, i)), "before {i}");
            halos.release(&wd, i).expect("release");
            assert!((0..8).all(|j| !band(j, i)), "after {i}");
            assert!((0..8).filter(|&j| j != i).all(|j| band(i, j) == (j > i)));
        }
    }

    #[test]
    fn a_missing_band_is_an_error_not_an_empty_halo() {
        let dir = tempfile::tempdir().expect("tempdir");
        let wd = WorkDir::for_output(&dir.path().join("ds"));
        let plan = octants(&wd);
        let halos = Halos::new(&plan, 12, 1.0);
        halos
            .write_bands(&wd, 0, 1, 2, &ProgressBar::hidden())
            .expect("bands");
        std::fs::remove_file(wd.chunk_band(3, 5)).expect("remove");
        let mut halo = Halo::default();
        let e = halos.gather(&wd, 5, &mut halo).expect_err("missing band");
        let text = e.to_string();
        assert!(
            text.contains("chunk 3's band for chunk 5 is missing"),
            "{text}"
        );
        // Written again where missing.
        halos
            .write_bands(&wd, 0, 1, 2, &ProgressBar::hidden())
            .expect("bands");
        halos.gather(&wd, 5, &mut halo).expect("gather");
        assert_eq!(halo.len(), 10 * 10 * 10 - 8 * 8 * 8);
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
