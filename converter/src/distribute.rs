//! Phase 3: stream every input's rows into chunk files. Each of `threads` parts is the same
//! part of every input and writes its own file per chunk, so a chunk's rows are its part files
//! read in order: the input order, whatever the timing or how many workers take the parts. A
//! plan's tasks distribute in shares (`Share`): share s of n takes the s-th n-th of each part
//! and writes part files numbered so that, read in order, they are the same rows in the same
//! order.

use crate::error::{ConvertError, Result, panic_message, spawn_worker};
use crate::plan::{grid_cell_checked, grid_shape};
use crate::rowfile::{Scratch, append_block};
use crate::rows::RowInput;
use indicatif::ProgressBar;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use strata_format::{Cube, row_position};

/// The file holding part `part` of chunk `index`.
pub fn chunk_path(dir: &Path, index: usize, part: usize) -> PathBuf {
    dir.join(format!("c{index}_{part}.bin"))
}

/// Appends buffered rows to a chunk part file as one compressed block (`rowfile`).
fn flush(path: &Path, buf: &mut Vec<u8>, stride: usize, scratch: &mut Scratch) -> Result<()> {
    if buf.is_empty() {
        return Ok(());
    }
    append_block(path, buf, stride, scratch)?;
    buf.clear();
    Ok(())
}

pub struct Distribution<'a> {
    pub inputs: &'a [RowInput],
    pub stride: usize,
    pub cube: &'a Cube,
    pub lut: &'a [u32],
    pub chunk_count: usize,
    pub chunk_dir: &'a Path,
    /// Bytes of row buffers, all workers together, where blocks of `MIN_BLOCK` a chunk allow.
    pub buffer_budget: u64,
    /// Bytes the workers' row buffers may take at most (`distribute_room`): fewer work at once
    /// where a block per chunk for each would take more.
    pub room: u64,
    pub threads: usize,
    /// Byte of the classification in a row, where the rows have one: its points per code are
    /// counted on the way.
    pub class_at: Option<usize>,
    pub share: Share,
}

/// Which share of the rows a distribution takes: all of them (a conversion), or share `index`
/// of `count` (a plan's tasks, each distributing one).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Share {
    pub index: usize,
    pub count: usize,
}

impl Share {
    pub const WHOLE: Share = Share { index: 0, count: 1 };

    /// The share's runs of a worker's `ranges` of records, one per input: the worker reads
    /// the inputs one after the other, so the share is a slice of that sequence (of one
    /// input's range a share may hold all, some or nothing).
    pub fn of(&self, ranges: &[Range<u64>]) -> Vec<Range<u64>> {
        let total: u64 = ranges.iter().map(|r| r.end - r.start).sum();
        let at = |k: usize| (total as u128 * k as u128 / self.count.max(1) as u128) as u64;
        let (lo, hi) = (at(self.index), at(self.index + 1));
        let mut seen = 0;
        ranges
            .iter()
            .map(|r| {
                let (len, from) = (r.end - r.start, seen);
                let cut = |v: u64| r.start + v.clamp(from, from + len) - from;
                seen += len;
                cut(lo)..cut(hi)
            })
            .collect()
    }

    /// The part file worker `part` writes: a worker's shares in order, then the next worker's.
    pub fn file_part(&self, part: usize) -> usize {
        part * self.count + self.index
    }

    /// Part files of a chunk, all shares together, for `threads` workers.
    pub fn parts(count: usize, threads: usize) -> usize {
        count.max(1) * threads
    }
}

/// Points per classification code.
pub type ClassCounts = [u64; 256];

/// Distributes every row into its chunk's files; returns the points per classification code.
pub fn distribute(d: &Distribution, bar: &ProgressBar, memory: &RowBuffers) -> Result<ClassCounts> {
    let workers = distribute_workers(d);
    in_parts(d.threads, workers, "distributing points", |part, worker| {
        let Some(Ok(mut buffers)) = memory.0.get(worker).map(|m| m.lock()) else {
            return Err(ConvertError::internal(
                "distributing points",
                format!("no row buffers for worker {worker}"),
            ));
        };
        distribute_part(d, part, workers, bar, &mut buffers)
    })
}

/// Bytes a chunk's row buffer holds at least before it is written: smaller blocks compress
/// poorly and make many small writes.
const MIN_BLOCK: u64 = 16 << 10;

/// Workers that distribute at once: one per part, or fewer where a block per chunk for each
/// would not fit the room (one at least): parts are input ranges, not memory.
fn distribute_workers(d: &Distribution) -> usize {
    workers_for_blocks(d.room, d.chunk_count, d.threads)
}

fn workers_for_blocks(room: u64, chunks: usize, threads: usize) -> usize {
    let per_worker = chunks.max(1) as u64 * MIN_BLOCK;
    usize::try_from(room / per_worker)
        .unwrap_or(usize::MAX)
        .clamp(1, threads.max(1))
}

/// The workers' row buffers, one per chunk, kept from one distribution to the next: a task
/// that distributes several shares fills the same memory again rather than touching new.
pub struct RowBuffers(Vec<Mutex<Vec<Vec<u8>>>>);

impl RowBuffers {
    pub fn new(workers: usize) -> Self {
        RowBuffers((0..workers).map(|_| Mutex::new(Vec::new())).collect())
    }
}

/// Runs `part(0..parts, worker)` on `workers` threads of their own, each taking the next part
/// left, and adds up their class counts; the first error stops the others at their next part,
/// and a panicking part is an internal error naming `what`.
pub(crate) fn in_parts(
    parts: usize,
    workers: usize,
    what: &str,
    part: impl Fn(usize, usize) -> Result<ClassCounts> + Sync,
) -> Result<ClassCounts> {
    let (part, next, failed) = (&part, &AtomicUsize::new(0), &AtomicBool::new(false));
    let work = move |worker: usize| -> Result<ClassCounts> {
        let mut total = [0u64; 256];
        loop {
            let k = next.fetch_add(1, Ordering::SeqCst);
            if k >= parts || failed.load(Ordering::SeqCst) {
                return Ok(total);
            }
            let counts = part(k, worker).inspect_err(|_| failed.store(true, Ordering::SeqCst))?;
            add_counts(&mut total, &counts);
        }
    };
    let results: Vec<Result<ClassCounts>> = std::thread::scope(|scope| {
        let started: Vec<_> = (0..workers.clamp(1, parts.max(1)))
            .map(|w| spawn_worker(scope, what, w, move || work(w)))
            .collect();
        started
            .into_iter()
            .map(|w| {
                w?.join().unwrap_or_else(|p| {
                    Err(ConvertError::internal(what, panic_message(p.as_ref())))
                })
            })
            .collect()
    });
    let mut total = [0u64; 256];
    for r in results {
        add_counts(&mut total, &r?);
    }
    Ok(total)
}

fn add_counts(total: &mut ClassCounts, counts: &ClassCounts) {
    for (t, c) in total.iter_mut().zip(counts) {
        *t += c;
    }
}

fn distribute_part(
    d: &Distribution,
    part: usize,
    workers: usize,
    bar: &ProgressBar,
    buffers: &mut Vec<Vec<u8>>,
) -> Result<ClassCounts> {
    let mut classes = [0u64; 256];
    let (level, shift) = grid_shape(d.cube);
    // The batches read take as much again as the row buffers: many workers under a small
    // limit read fewer records at a time.
    let batch_bytes =
        usize::try_from(d.buffer_budget / workers.max(1) as u64).unwrap_or(usize::MAX);
    let per_chunk = (d.buffer_budget / (d.chunk_count.max(1) * workers.max(1)) as u64)
        .clamp(MIN_BLOCK, 4 << 20) as usize;
    // Emptied (one that failed may have left rows), keeping their memory.
    buffers.resize_with(d.chunk_count, Vec::new);
    buffers.iter_mut().for_each(Vec::clear);
    let mut scratch = Scratch::default();
    let file_part = d.share.file_part(part);
    // A share may be distributed again (its task was stopped): its staging rows must stay.
    let release = d.share == Share::WHOLE;
    let ranges: Vec<Range<u64>> = d.inputs.iter().map(|i| i.part(part, d.threads)).collect();
    for (input, range) in d.inputs.iter().zip(d.share.of(&ranges)) {
        input.for_each_rows(range, d.stride, release, batch_bytes, |rows| {
            for row in rows.chunks_exact(d.stride) {
                // The plan's chunks hold every row it counted; a plan edited since may not.
                let chunk = grid_cell_checked(row_position(row), d.cube, level, shift)
                    .and_then(|cell| d.lut.get(cell))
                    .map(|&c| c as usize)
                    .filter(|&c| c < d.chunk_count && c < buffers.len());
                let Some(chunk) = chunk else {
                    return Err(ConvertError::input(
                        &input.path,
                        "a row lies in none of the plan's chunks: the plan was changed since it was made; make it again",
                    ));
                };
                if let Some(&c) = d.class_at.and_then(|at| row.get(at)) {
                    classes[c as usize] += 1;
                }
                let buf = &mut buffers[chunk];
                // Sized once to the block, not grown by doubling past it: the worker count
                // counts a block a chunk.
                if buf.capacity() == 0 {
                    buf.reserve_exact(per_chunk + d.stride);
                }
                buf.extend_from_slice(row);
                if buf.len() >= per_chunk {
                    flush(
                        &chunk_path(d.chunk_dir, chunk, file_part),
                        buf,
                        d.stride,
                        &mut scratch,
                    )?;
                }
            }
            bar.inc((rows.len() / d.stride) as u64);
            Ok(())
        })?;
    }
    for (i, buf) in buffers.iter_mut().enumerate() {
        flush(
            &chunk_path(d.chunk_dir, i, file_part),
            buf,
            d.stride,
            &mut scratch,
        )?;
    }
    Ok(classes)
}

#[cfg(test)]
mod tests {
    use super::{MIN_BLOCK, Share, workers_for_blocks};

    /// A block a chunk for every worker within the room; all threads where it holds them (a
    /// large input at the default limit: 2,200 chunks), one at least.
    #[test]
    fn workers_take_a_block_a_chunk_within_the_room() {
        let room = crate::prepare::distribute_room(2 << 30);
        assert_eq!(workers_for_blocks(room, 2200, 16), 16);
        let few = workers_for_blocks(room, 50_000, 16);
        assert!(few < 16 && few as u64 * 50_000 * MIN_BLOCK <= room, "{few}");
        assert_eq!(workers_for_blocks(1 << 20, 50_000, 16), 1);
    }

    /// A worker's records of every input, its shares in order: each record once, in order.
    #[test]
    fn shares_cut_a_workers_inputs_in_reading_order() {
        let ranges = [10..15, 100..100, 40..47, 0..1];
        let sequence = |rs: &[std::ops::Range<u64>]| -> Vec<(usize, u64)> {
            rs.iter()
                .enumerate()
                .flat_map(|(i, r)| r.clone().map(move |v| (i, v)))
                .collect()
        };
        let whole = sequence(&ranges);
        for count in [1, 2, 3, 5, 13, 20] {
            let mut joined = Vec::new();
            for index in 0..count {
                let runs = Share { index, count }.of(&ranges);
                assert_eq!(runs.len(), ranges.len());
                joined.extend(sequence(&runs));
            }
            assert_eq!(joined, whole, "{count} shares");
        }
        assert_eq!(Share::WHOLE.of(&ranges), ranges.to_vec());
        assert_eq!(Share { index: 2, count: 3 }.file_part(4), 14);
    }
}
