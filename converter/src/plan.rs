//! Phase 2: count points on a coarse grid and cut the cube into chunks that fit in memory.

use crate::error::{ConvertError, Result, panic_message, spawn_worker};
use crate::quantize::Quantization;
use crate::rows::RowInput;
use indicatif::ProgressBar;
use serde::{Deserialize, Serialize};
use strata_format::{Cube, GRID_CELLS_LOG2, NodeKey, row_position};

/// The counting grid has 2^7 = 128 cells per axis (16 MiB of u64 counters, one grid a counting
/// worker; see `count_workers`).
pub const COUNT_GRID_LOG2: u32 = 7;

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Chunk {
    pub level: u8,
    pub x: u32,
    pub y: u32,
    pub z: u32,
    pub points: u64,
}

impl Chunk {
    pub fn key(&self) -> NodeKey {
        NodeKey {
            level: self.level,
            x: self.x,
            y: self.y,
            z: self.z,
        }
    }
}

/// The integer cube holding every quantized position.
pub fn cube_for(q: &Quantization, min: [f64; 3], max: [f64; 3]) -> Cube {
    let lo = q.quantize(&min);
    let hi = q.quantize(&max);
    let extent = (0..3)
        .map(|a| hi[a] as i64 - lo[a] as i64 + 1)
        .max()
        .unwrap_or(1);
    let mut bits = 0u32;
    while (1i64 << bits) < extent {
        bits += 1;
    }
    Cube {
        min: [lo[0] as i64, lo[1] as i64, lo[2] as i64],
        bits: bits.max(1),
    }
}

/// Counting-grid level and per-axis shift for a cube.
pub fn grid_shape(cube: &Cube) -> (u32, u32) {
    let level = COUNT_GRID_LOG2.min(cube.bits);
    (level, cube.bits - level)
}

#[inline]
pub fn grid_cell(p: [i32; 3], cube: &Cube, level: u32, shift: u32) -> usize {
    let c = |a: usize| ((p[a] as i64 - cube.min[a]) >> shift) as usize;
    (c(0) << (2 * level)) | (c(1) << level) | c(2)
}

/// `grid_cell` of a position that may lie outside the cube (rows a plan edited since does
/// not hold): `None` there.
#[inline]
pub fn grid_cell_checked(p: [i32; 3], cube: &Cube, level: u32, shift: u32) -> Option<usize> {
    let mut cell = 0usize;
    for (&v, min) in p.iter().zip(cube.min) {
        // Checked: a cube read from a file may be anywhere (`check_cube` bounds its min).
        let c = i64::from(v).checked_sub(min)? >> shift.min(63);
        if !(0..1i64 << level).contains(&c) {
            return None;
        }
        cell = (cell << level) | c as usize;
    }
    Some(cell)
}

/// What the count phase learns: points per grid cell, and the extent of the positions.
#[derive(Debug, Clone)]
pub struct Counts {
    pub cells: Vec<u64>,
    pub min: [i32; 3],
    pub max: [i32; 3],
    cube: Cube,
    level: u32,
    shift: u32,
}

impl Counts {
    pub fn new(cube: &Cube) -> Self {
        let (level, shift) = grid_shape(cube);
        Counts {
            cells: vec![0; 1 << (3 * level)],
            min: [i32::MAX; 3],
            max: [i32::MIN; 3],
            cube: *cube,
            level,
            shift,
        }
    }

    /// Counts a position inside the cube.
    #[inline]
    pub fn add(&mut self, p: [i32; 3]) {
        for (a, &v) in p.iter().enumerate() {
            self.min[a] = self.min[a].min(v);
            self.max[a] = self.max[a].max(v);
        }
        self.cells[grid_cell(p, &self.cube, self.level, self.shift)] += 1;
    }

    pub fn merge(&mut self, other: &Counts) {
        for (a, b) in self.cells.iter_mut().zip(&other.cells) {
            *a += b;
        }
        for a in 0..3 {
            self.min[a] = self.min[a].min(other.min[a]);
            self.max[a] = self.max[a].max(other.max[a]);
        }
    }
}

/// Workers that may count at once within `memory_limit`: each holds a grid of counters (16
/// MiB) until all are merged into the total's, and the grids together take at most half the
/// limit (one worker at least), however many threads were asked for.
fn count_workers(memory_limit: u64, threads: usize) -> usize {
    let grid = (std::mem::size_of::<u64>() as u64) << (3 * COUNT_GRID_LOG2);
    // One of the grids is the total's.
    usize::try_from((memory_limit / 2 / grid).saturating_sub(1))
        .unwrap_or(usize::MAX)
        .clamp(1, threads.max(1))
}

/// Counts the rows of `inputs` per grid cell into `total`, with up to `threads` workers (as
/// many as `memory_limit` holds grids for, see `count_workers`), each taking a part of every
/// input. The counts do not depend on how many workers there were.
pub fn count(
    inputs: &[&RowInput],
    total: &mut Counts,
    threads: usize,
    memory_limit: u64,
    bar: &ProgressBar,
) -> Result<()> {
    let threads = count_workers(memory_limit, threads);
    let cube = total.cube;
    let parts: Vec<Result<Counts>> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|t| {
                spawn_worker(scope, "counting points", t, move || {
                    let mut c = Counts::new(&cube);
                    for input in inputs {
                        input.for_each_raw(input.part(t, threads), |raw, first| {
                            for (i, rec) in raw.chunks_exact(input.record_len).enumerate() {
                                let p = match &input.convert {
                                    Some(conv) => conv.position(rec, first + i as u64)?,
                                    None => row_position(rec),
                                };
                                c.add(p);
                            }
                            bar.inc((raw.len() / input.record_len) as u64);
                            Ok(())
                        })?;
                    }
                    Ok(c)
                })
            })
            .collect();
        workers
            .into_iter()
            .map(|w| {
                w?.join().unwrap_or_else(|p| {
                    Err(ConvertError::internal(
                        "counting points",
                        panic_message(p.as_ref()),
                    ))
                })
            })
            .collect()
    });
    for part in parts {
        total.merge(&part?);
    }
    Ok(())
}

/// Splits the cube top-down until every chunk holds at most `max_points` (or is one grid cell).
/// Returns the chunks, largest first, and a lookup table from grid cell to chunk index.
pub fn plan_chunks(counts: &[u64], cube: &Cube, max_points: u64) -> Result<(Vec<Chunk>, Vec<u32>)> {
    let (level, _) = grid_shape(cube);
    // Sum counts of the cells under node `k` (level <= grid level).
    let sum = |k: &NodeKey| -> u64 {
        let span = 1u32 << (level - k.level as u32);
        let mut total = 0;
        for x in k.x * span..(k.x + 1) * span {
            for y in k.y * span..(k.y + 1) * span {
                let base = ((x as usize) << (2 * level)) | ((y as usize) << level);
                let z0 = (k.z * span) as usize;
                total += counts[base + z0..base + z0 + span as usize]
                    .iter()
                    .sum::<u64>();
            }
        }
        total
    };
    let mut chunks = Vec::new();
    let mut stack = vec![(NodeKey::ROOT, counts.iter().sum::<u64>())];
    while let Some((k, n)) = stack.pop() {
        if n == 0 {
            continue;
        }
        if n <= max_points || k.level as u32 == level {
            chunks.push(Chunk {
                level: k.level,
                x: k.x,
                y: k.y,
                z: k.z,
                points: n,
            });
        } else {
            for o in 0..8 {
                let c = k.child(o);
                let cn = sum(&c);
                stack.push((c, cn));
            }
        }
    }
    chunks.sort_by(|a, b| b.points.cmp(&a.points).then(a.key().cmp(&b.key())));
    let lut =
        chunk_lut(&chunks, cube).map_err(|e| ConvertError::internal("planning the chunks", e))?;
    Ok((chunks, lut))
}

/// The most bits a cube may span, as the format's metadata allows.
pub const MAX_CUBE_BITS: u32 = 32;

/// What is wrong with a cube read from a file, if anything: positions are i32, and the cube
/// decides the counting grid every table is sized by.
pub fn check_cube(cube: &Cube) -> std::result::Result<(), String> {
    if !(1..=MAX_CUBE_BITS).contains(&cube.bits) {
        return Err(format!(
            "cube.bits is {}, outside 1 to {MAX_CUBE_BITS}",
            cube.bits
        ));
    }
    if let Some(a) = (0..3).find(|&a| i32::try_from(cube.min[a]).is_err()) {
        return Err(format!(
            "cube.min[{a}] is {}, outside the range of positions",
            cube.min[a]
        ));
    }
    Ok(())
}

/// The lookup table from counting-grid cell to chunk index (`u32::MAX` for cells of no
/// chunk): the chunks alone decide it, so a task rebuilds it from the plan. Chunks read from a
/// file may be anything: one off the grid, or over another's cells, is refused with what is
/// wrong with it.
pub fn chunk_lut(chunks: &[Chunk], cube: &Cube) -> std::result::Result<Vec<u32>, String> {
    check_cube(cube)?;
    let (level, _) = grid_shape(cube);
    if chunks.len() >= u32::MAX as usize {
        return Err(format!("it has {} chunks, too many", chunks.len()));
    }
    let mut lut = vec![u32::MAX; 1 << (3 * level)];
    for (i, c) in chunks.iter().enumerate() {
        let fault = |what: String| format!("chunk {i}'s {what}");
        let Some(depth) = level.checked_sub(u32::from(c.level)) else {
            return Err(fault(format!(
                "level {} is deeper than the counting grid's {level}",
                c.level
            )));
        };
        if let Some((axis, v)) = [("x", c.x), ("y", c.y), ("z", c.z)]
            .into_iter()
            .find(|&(_, v)| u64::from(v) >= 1u64 << c.level)
        {
            return Err(fault(format!(
                "{axis} {v} lies outside its level {}, whose cells number {} an axis",
                c.level,
                1u64 << c.level
            )));
        }
        // Within the grid now: every cell below fits its axis's `level` bits.
        let span = 1u32 << depth;
        for x in c.x * span..(c.x + 1) * span {
            for y in c.y * span..(c.y + 1) * span {
                for z in c.z * span..(c.z + 1) * span {
                    let cell = ((x as usize) << (2 * level)) | ((y as usize) << level) | z as usize;
                    if lut[cell] != u32::MAX {
                        return Err(fault(format!("cells overlap chunk {}'s", lut[cell])));
                    }
                    lut[cell] = i as u32;
                }
            }
        }
    }
    Ok(lut)
}

/// What is wrong with a plan's chunks read from a file, if anything: where they lie (see
/// `chunk_lut`) and how many points they hold, which must add up to the plan's.
pub fn check_chunks(chunks: &[Chunk], cube: &Cube, points: u64) -> std::result::Result<(), String> {
    chunk_lut(chunks, cube)?;
    let sum = chunks
        .iter()
        .try_fold(0u64, |sum, c| sum.checked_add(c.points));
    match sum {
        Some(sum) if sum == points => Ok(()),
        Some(sum) => Err(format!(
            "its chunks' points add up to {sum}, not the plan's {points}"
        )),
        None => Err("its chunks' points add up to more than 2^64".to_string()),
    }
}

/// Points per chunk that keep indexing inside `memory_limit` with `threads` workers.
/// Each worker holds its chunk's rows, index arrays and compressed output, and what the
/// per-chunk step needs (`step_bytes` a point); finished chunks wait for their in-order commit,
/// `threads + 1` of them at most (those ahead of the commit and the one being written), whose
/// compressed output is within the rows' share (the 40 % the formula leaves is room for it).
pub fn max_chunk_points(
    memory_limit: u64,
    threads: usize,
    stride: usize,
    step_bytes: usize,
) -> u64 {
    let per_point = index_bytes_per_point(stride, step_bytes);
    let n = index_share(memory_limit) / (threads.max(1) as u64 * per_point);
    // A floor keeps chunks from getting absurdly many, but only up to 64 MiB of rows: wide
    // rows (thousands of attributes) would otherwise make one chunk gigabytes. Where the
    // floor wins, `index_workers` runs fewer workers at once.
    n.max(((64 << 20) / per_point).clamp(1, 1 << 16))
}

/// Workers that may index at once within `memory_limit` when the largest chunk holds
/// `largest_chunk` points and the largest halo `largest_halo`: as many as `threads` unless
/// chunks at `max_chunk_points`' floor would take more than the limit's share for them, or
/// halos as wide as chunks, or wider, would take more than the limit (one worker at least).
/// `Err` holds the bytes one worker needs where even one does not fit.
pub fn index_workers(
    memory_limit: u64,
    threads: usize,
    stride: usize,
    step_bytes: usize,
    largest_chunk: u64,
    largest_halo: u64,
) -> std::result::Result<usize, u64> {
    let chunk = largest_chunk.max(1) * index_bytes_per_point(stride, step_bytes);
    // A halo's rows go to the step with the chunk's, not through the tree's build.
    let one = chunk + largest_halo * (stride + step_bytes) as u64;
    if largest_halo > 0 && one > index_room(memory_limit) {
        return Err(one);
    }
    let workers = (index_share(memory_limit) / chunk).min(index_room(memory_limit) / one);
    Ok(usize::try_from(workers)
        .unwrap_or(usize::MAX)
        .clamp(1, threads.max(1)))
}

/// Bytes an indexing worker holds per point of its chunk: rows three times over (read,
/// sorted, written), index arrays, and the per-chunk step's.
fn index_bytes_per_point(stride: usize, step_bytes: usize) -> u64 {
    (3 * stride + 48 + step_bytes) as u64
}

/// The part of `memory_limit` the indexing workers' chunks may take.
fn index_share(memory_limit: u64) -> u64 {
    index_room(memory_limit) * 6 / 10
}

/// What `memory_limit` leaves for indexing: the rest of the program takes about 96 MiB.
pub fn index_room(memory_limit: u64) -> u64 {
    const RESERVED: u64 = 96 << 20;
    memory_limit.saturating_sub(RESERVED).max(32 << 20)
}

/// Root spacing in real units.
pub fn root_spacing(cube: &Cube, scale: f64) -> f64 {
    scale * (1u64 << cube.bits) as f64 / (1u64 << GRID_CELLS_LOG2) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counting_grids_take_at_most_half_the_memory_limit() {
        let grid = 8u64 << (3 * COUNT_GRID_LOG2);
        for (limit, threads) in [
            (64u64 << 20, 16),
            (512 << 20, 16),
            (8 << 30, 16),
            (1 << 20, 4),
        ] {
            let workers = count_workers(limit, threads);
            assert!((1..=threads).contains(&workers), "{limit} {threads}");
            // One worker at least, however small the limit; else its grids and the total's
            // within half of it.
            assert!(
                workers == 1 || (workers as u64 + 1) * grid <= limit / 2,
                "{limit} {threads}"
            );
        }
        assert_eq!(count_workers(64 << 20, 16), 1);
        assert_eq!(count_workers(512 << 20, 16), 15);
        assert_eq!(
            count_workers(8 << 30, 16),
            16,
            "a large limit keeps every thread"
        );
        assert_eq!(count_workers(1 << 20, 0), 1);
    }

    #[test]
    fn chunks_at_the_floor_run_fewer_workers_at_once() {
        let (stride, step) = (40, 24);
        let per_point = index_bytes_per_point(stride, step);
        for (limit, threads) in [
            (64u64 << 20, 64),
            (256 << 20, 64),
            (2 << 30, 8),
            (1 << 20, 4),
        ] {
            let chunk = max_chunk_points(limit, threads, stride, step);
            let workers = index_workers(limit, threads, stride, step, chunk, 0).unwrap_or(0);
            assert!((1..=threads).contains(&workers), "{limit} {threads}");
            assert!(
                workers == 1 || workers as u64 * chunk * per_point <= index_share(limit),
                "{limit} {threads}: {workers} workers of {chunk} points"
            );
        }
        // Chunks below the floor keep every thread; the floor's chunks under 64 MiB, few.
        let chunk = max_chunk_points(2 << 30, 8, stride, step);
        assert_eq!(
            index_workers(2 << 30, 8, stride, step, chunk, chunk / 4),
            Ok(8)
        );
        assert!(index_workers(64 << 20, 64, stride, step, 1 << 16, 0).is_ok_and(|w| w <= 3));
        assert_eq!(index_workers(64 << 20, 64, stride, step, 0, 0), Ok(64));
        // Halos as wide as the data: fewer workers, and none where one does not fit.
        let halo_bytes = (stride + step) as u64;
        let wide = index_room(2 << 30) / 3 / halo_bytes;
        assert_eq!(index_workers(2 << 30, 8, stride, step, 1000, wide), Ok(2));
        let over = index_room(2 << 30) / halo_bytes;
        assert!(index_workers(2 << 30, 8, stride, step, 1000, over).is_err());
    }

    #[test]
    fn chunks_off_the_grid_or_overlapping_are_refused() {
        let cube = Cube {
            min: [0; 3],
            bits: 10,
        };
        let chunk = |level, x, y, z, points| Chunk {
            level,
            x,
            y,
            z,
            points,
        };
        let good = vec![chunk(1, 0, 0, 0, 5), chunk(1, 1, 1, 1, 6)];
        assert_eq!(check_chunks(&good, &cube, 11), Ok(()));
        let refused = |chunks: &[Chunk], cube: &Cube, points| {
            check_chunks(chunks, cube, points).expect_err("refused")
        };
        let e = refused(&[chunk(200, 0, 0, 0, 11)], &cube, 11);
        assert!(e.contains("chunk 0's level 200"), "{e}");
        let e = refused(&[good[0].clone(), chunk(1, 0, 2, 0, 6)], &cube, 11);
        assert!(e.contains("chunk 1's y 2"), "{e}");
        let e = refused(&[good[0].clone(), chunk(2, 1, 1, 0, 6)], &cube, 11);
        assert!(e.contains("chunk 1's cells overlap chunk 0's"), "{e}");
        let e = refused(&good, &cube, 12);
        assert!(e.contains("add up to 11, not the plan's 12"), "{e}");
        let e = refused(&[good[0].clone(), chunk(1, 1, 1, 1, u64::MAX)], &cube, 11);
        assert!(e.contains("more than 2^64"), "{e}");
        for bits in [0, 33, 99] {
            let e = refused(&good, &Cube { min: [0; 3], bits }, 11);
            assert!(e.contains(&format!("cube.bits is {bits}")), "{e}");
        }
        let e = refused(
            &good,
            &Cube {
                min: [0, 1 << 40, 0],
                bits: 10,
            },
            11,
        );
        assert!(e.contains("cube.min[1]"), "{e}");
    }

    #[test]
    fn counts_do_not_depend_on_how_many_workers_the_limit_allows() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rows.bin");
        let records = 5000u64;
        let mut bytes = Vec::new();
        for i in 0..records as i32 {
            for v in [i % 64, i * 7 % 61, i * 13 % 59] {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
        std::fs::write(&path, &bytes).unwrap();
        let input = RowInput {
            path,
            start: 0,
            record_len: 12,
            records,
            convert: None,
            blocks: None,
        };
        let cube = Cube {
            min: [0; 3],
            bits: 6,
        };
        let counted = |limit: u64| {
            let mut c = Counts::new(&cube);
            count(&[&input], &mut c, 8, limit, &ProgressBar::hidden()).unwrap();
            (c.cells, c.min, c.max)
        };
        // One worker, four, and all eight.
        let one = counted(64 << 20);
        assert_eq!(one.0.iter().sum::<u64>(), records);
        assert_eq!((one.1, one.2), ([0; 3], [63, 60, 58]));
        assert_eq!(counted(160 << 20), one);
        assert_eq!(counted(8 << 30), one);
    }
}
