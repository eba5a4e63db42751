//! A task's distribution: every input is read (as the whole conversion's distribution reads
//! it, one part per thread, so a chunk's rows come in the same order), and only the rows of
//! the task's chunks are kept, with those of other chunks that the task's halos reach. The
//! position is looked at first: a row of another task's chunk costs no conversion.

use crate::chunk_step::GridBox;
use crate::distribute::{ClassCounts, chunk_path};
use crate::error::{ConvertError, Result, panic_message};
use crate::plan::{grid_cell, grid_shape};
use crate::rowfile::{Scratch, append_block};
use crate::rows::RowInput;
use indicatif::ProgressBar;
use std::path::Path;
use strata_format::{Cube, row_position};

/// What a task does with the rows of one chunk.
#[derive(Debug, Clone)]
pub enum Role {
    /// Another task's chunk, out of reach of this task's halos.
    Skip,
    /// The task's own chunk: every row.
    Own,
    /// Another task's chunk next to the task's: its rows outside `inner` (its band) within one
    /// of `reaches` (the halos of the task's chunks next to it).
    Band {
        inner: GridBox,
        reaches: Vec<GridBox>,
    },
}

pub struct TaskDistribution<'a> {
    pub inputs: &'a [RowInput],
    pub stride: usize,
    pub cube: &'a Cube,
    pub lut: &'a [u32],
    pub roles: &'a [Role],
    pub chunk_dir: &'a Path,
    pub buffer_budget: u64,
    /// Parts of every input, each read by a worker of its own: the plan's threads.
    pub parts: usize,
    pub class_at: Option<usize>,
}

/// Distributes the task's rows into chunk part files; returns the points per classification
/// code of its own chunks.
pub fn distribute_task(d: &TaskDistribution, bar: &ProgressBar) -> Result<ClassCounts> {
    let results: Vec<Result<ClassCounts>> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..d.parts)
            .map(|part| scope.spawn(move || distribute_part(d, part, bar)))
            .collect();
        workers
            .into_iter()
            .map(|w| {
                w.join().unwrap_or_else(|p| {
                    Err(ConvertError::internal(
                        "distributing a task's points",
                        panic_message(p.as_ref()),
                    ))
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

fn distribute_part(d: &TaskDistribution, part: usize, bar: &ProgressBar) -> Result<ClassCounts> {
    let mut classes = [0u64; 256];
    let (level, shift) = grid_shape(d.cube);
    let kept = d.roles.iter().filter(|r| !matches!(r, Role::Skip)).count();
    let per_chunk =
        (d.buffer_budget / (kept.max(1) * d.parts.max(1)) as u64).clamp(16 << 10, 4 << 20) as usize;
    let mut buffers: Vec<Vec<u8>> = vec![Vec::new(); d.roles.len()];
    let mut scratch = Scratch::default();
    let mut converted = Vec::with_capacity(d.stride);
    for input in d.inputs {
        let len = input.record_len;
        input.for_each_raw(input.part(part, d.parts), |raw, first| {
            for (i, rec) in raw.chunks_exact(len).enumerate() {
                let index = first + i as u64;
                let p = match &input.convert {
                    Some(c) => c.position(rec, index)?,
                    None => row_position(rec),
                };
                let chunk = d.lut[grid_cell(p, d.cube, level, shift)] as usize;
                let own = match d.roles.get(chunk) {
                    None | Some(Role::Skip) => continue,
                    Some(Role::Own) => true,
                    Some(Role::Band { inner, reaches }) => {
                        if inner.contains(p) || !reaches.iter().any(|r| r.contains(p)) {
                            continue;
                        }
                        false
                    }
                };
                let row: &[u8] = match &input.convert {
                    Some(c) => {
                        c.convert(rec, len, index, &mut converted, d.stride)?;
                        &converted
                    }
                    None => rec,
                };
                if own && let Some(&c) = d.class_at.and_then(|at| row.get(at)) {
                    classes[c as usize] += 1;
                }
                let buf = &mut buffers[chunk];
                buf.extend_from_slice(row);
                if buf.len() >= per_chunk {
                    append_block(
                        &chunk_path(d.chunk_dir, chunk, part),
                        buf,
                        d.stride,
                        &mut scratch,
                    )?;
                    buf.clear();
                }
            }
            bar.inc((raw.len() / len) as u64);
            Ok(())
        })?;
    }
    for (i, buf) in buffers.iter_mut().enumerate() {
        if !buf.is_empty() {
            append_block(
                &chunk_path(d.chunk_dir, i, part),
                buf,
                d.stride,
                &mut scratch,
            )?;
        }
    }
    Ok(classes)
}
