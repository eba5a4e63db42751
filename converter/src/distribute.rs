//! Phase 3: stream every input's rows into chunk files. Each of the `threads` workers takes
//! the same part of every input and writes its own file per chunk, so a chunk's rows are its
//! part files read in order: the input order, whatever the timing.

use crate::error::{ConvertError, Result, panic_message};
use crate::plan::{grid_cell, grid_shape};
use crate::rowfile::{Scratch, append_block};
use crate::rows::RowInput;
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};
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
    /// Bytes of row buffers, all workers together.
    pub buffer_budget: u64,
    pub threads: usize,
    /// Byte of the classification in a row, where the rows have one: its points per code are
    /// counted on the way.
    pub class_at: Option<usize>,
}

/// Points per classification code.
pub type ClassCounts = [u64; 256];

/// Distributes every row into its chunk's files; returns the points per classification code.
pub fn distribute(d: &Distribution, bar: &ProgressBar) -> Result<ClassCounts> {
    in_parts(d.threads, "distributing points", |part| {
        distribute_part(d, part, bar)
    })
}

/// Runs `part(0..parts)` on threads of their own and adds up their class counts; a panicking
/// part is an internal error naming `what`.
pub(crate) fn in_parts(
    parts: usize,
    what: &str,
    part: impl Fn(usize) -> Result<ClassCounts> + Sync,
) -> Result<ClassCounts> {
    let part = &part;
    let results: Vec<Result<ClassCounts>> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..parts).map(|k| scope.spawn(move || part(k))).collect();
        workers
            .into_iter()
            .map(|w| {
                w.join().unwrap_or_else(|p| {
                    Err(ConvertError::internal(what, panic_message(p.as_ref())))
                })
            })
            .collect()
    });
    let mut total = [0u64; 256];
    for r in results {
        for (t, c) in total.iter_mut().zip(r?) {
            *t += c;
        }
    }
    Ok(total)
}

fn distribute_part(d: &Distribution, part: usize, bar: &ProgressBar) -> Result<ClassCounts> {
    let mut classes = [0u64; 256];
    let (level, shift) = grid_shape(d.cube);
    let per_chunk = (d.buffer_budget / (d.chunk_count.max(1) * d.threads.max(1)) as u64)
        .clamp(16 << 10, 4 << 20) as usize;
    let mut buffers: Vec<Vec<u8>> = vec![Vec::new(); d.chunk_count];
    let mut scratch = Scratch::default();
    for input in d.inputs {
        input.consume_rows(input.part(part, d.threads), d.stride, |rows| {
            for row in rows.chunks_exact(d.stride) {
                let chunk = d.lut[grid_cell(row_position(row), d.cube, level, shift)] as usize;
                if let Some(&c) = d.class_at.and_then(|at| row.get(at)) {
                    classes[c as usize] += 1;
                }
                let buf = &mut buffers[chunk];
                buf.extend_from_slice(row);
                if buf.len() >= per_chunk {
                    flush(
                        &chunk_path(d.chunk_dir, chunk, part),
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
            &chunk_path(d.chunk_dir, i, part),
            buf,
            d.stride,
            &mut scratch,
        )?;
    }
    Ok(classes)
}
