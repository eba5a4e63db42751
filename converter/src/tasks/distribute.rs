//! A task's distribution: every input is gone through (as the whole conversion's distribution
//! reads it, one part per thread, so a chunk's rows come in the same order), and only the rows
//! of the task's chunks are kept, with those of other chunks that the task's halos reach. A LAS
//! input read in place is not read whole: the plan's file of its records' grid cells says
//! which records the task wants, and only those are touched, through a memory map. Staging
//! rows (decoded LAZ, PLY, E57) are compressed in blocks and read whole.

use crate::chunk_step::GridBox;
use crate::distribute::{ClassCounts, chunk_path};
use crate::error::{ConvertError, Result, io_err};
use crate::plan::{grid_cell, grid_shape};
use crate::rowfile::{Scratch, append_block};
use crate::rows::RowInput;
use indicatif::ProgressBar;
use memmap2::MmapOptions;
use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
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
    /// For each input, the plan's file of its records' grid cells, where it has one.
    pub cells: &'a [Option<PathBuf>],
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
    // One bit per grid cell: whether the task keeps anything of it (256 KiB, so that the
    // test of a row the task does not want stays in cache).
    let mut wanted = vec![0u64; d.lut.len().div_ceil(64)];
    for (cell, &chunk) in d.lut.iter().enumerate() {
        if d.roles
            .get(chunk as usize)
            .is_some_and(|r| !matches!(r, Role::Skip))
        {
            wanted[cell >> 6] |= 1 << (cell & 63);
        }
    }
    let wanted = &wanted;
    crate::distribute::in_parts(d.parts, "distributing a task's points", |part| {
        Worker::new(d, part).run(wanted, bar)
    })
}

/// Records of a LAS input mapped at once: bounded, so that the pages a task touches are let
/// go as it moves on.
const WINDOW_BYTES: usize = 64 << 20;

/// One part of every input, into the part's chunk files.
struct Worker<'a> {
    d: &'a TaskDistribution<'a>,
    part: usize,
    classes: ClassCounts,
    buffers: Vec<Vec<u8>>,
    per_chunk: usize,
    scratch: Scratch,
    converted: Vec<u8>,
    level: u32,
    shift: u32,
}

impl<'a> Worker<'a> {
    fn new(d: &'a TaskDistribution<'a>, part: usize) -> Self {
        let kept = d.roles.iter().filter(|r| !matches!(r, Role::Skip)).count();
        let (level, shift) = grid_shape(d.cube);
        Worker {
            d,
            part,
            classes: [0; 256],
            buffers: vec![Vec::new(); d.roles.len()],
            per_chunk: (d.buffer_budget / (kept.max(1) * d.parts.max(1)) as u64)
                .clamp(16 << 10, 4 << 20) as usize,
            scratch: Scratch::default(),
            converted: Vec::with_capacity(d.stride),
            level,
            shift,
        }
    }

    fn run(mut self, wanted: &[u64], bar: &ProgressBar) -> Result<ClassCounts> {
        let d = self.d;
        for (j, input) in d.inputs.iter().enumerate() {
            let range = input.part(self.part, d.parts);
            match (d.cells.get(j), &input.convert) {
                (Some(Some(cells)), Some(_)) => self.mapped(input, cells, range, wanted, bar)?,
                _ => input.for_each_raw(range, |raw, first| {
                    for (i, rec) in raw.chunks_exact(input.record_len).enumerate() {
                        let p = match &input.convert {
                            Some(c) => c.position(rec, first + i as u64)?,
                            None => row_position(rec),
                        };
                        let cell = grid_cell(p, d.cube, self.level, self.shift);
                        if wanted[cell >> 6] >> (cell & 63) & 1 != 0 {
                            self.keep(input, rec, first + i as u64, cell)?;
                        }
                    }
                    bar.inc((raw.len() / input.record_len) as u64);
                    Ok(())
                })?,
            }
        }
        for (i, buf) in self.buffers.iter_mut().enumerate() {
            if !buf.is_empty() {
                let path = chunk_path(d.chunk_dir, i, self.part);
                append_block(&path, buf, d.stride, &mut self.scratch)?;
            }
        }
        Ok(self.classes)
    }

    /// The records of `range` of a LAS input read in place whose cells (from `cells`) the
    /// task wants, looked at through a memory map.
    fn mapped(
        &mut self,
        input: &RowInput,
        cells: &Path,
        range: std::ops::Range<u64>,
        wanted: &[u64],
        bar: &ProgressBar,
    ) -> Result<()> {
        let len = input.record_len;
        let file = File::open(&input.path).map_err(io_err(&input.path, "cannot open"))?;
        let cell_file = File::open(cells).map_err(io_err(cells, "cannot open"))?;
        let window = (WINDOW_BYTES / len.max(1)).max(1) as u64;
        let mut cell_bytes = Vec::new();
        let mut at = range.start;
        while at < range.end {
            let n = (range.end - at).min(window);
            cell_bytes.resize(n as usize * 4, 0);
            cell_file
                .read_exact_at(&mut cell_bytes, at * 4)
                .map_err(io_err(cells, "cannot read the grid cells of its records"))?;
            // Safety: the input is only read, by this conversion and others; the plan's
            // fingerprint (size and time) checked it is the file the plan was made of.
            let map = unsafe {
                MmapOptions::new()
                    .offset(input.start + at * len as u64)
                    .len(n as usize * len)
                    .map(&file)
            }
            .map_err(io_err(&input.path, "cannot map"))?;
            for (i, c) in cell_bytes.chunks_exact(4).enumerate() {
                let cell = u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as usize;
                let Some(bits) = wanted.get(cell >> 6) else {
                    return Err(ConvertError::input(
                        cells,
                        format!(
                            "record {} has no grid cell {cell}; make the plan again",
                            at + i as u64
                        ),
                    ));
                };
                if bits >> (cell & 63) & 1 != 0 {
                    self.keep(input, &map[i * len..(i + 1) * len], at + i as u64, cell)?;
                }
            }
            bar.inc(n);
            at += n;
        }
        Ok(())
    }

    /// Keeps record `index` of `input` if the task wants it: a row of its own chunk, or of
    /// another's band within one of its halos.
    fn keep(&mut self, input: &RowInput, rec: &[u8], index: u64, cell: usize) -> Result<()> {
        let d = self.d;
        let chunk = d.lut[cell] as usize;
        let own = match d.roles.get(chunk) {
            None | Some(Role::Skip) => return Ok(()),
            Some(Role::Own) => true,
            Some(Role::Band { inner, reaches }) => {
                let p = match &input.convert {
                    Some(c) => c.position(rec, index)?,
                    None => row_position(rec),
                };
                if inner.contains(p) || !reaches.iter().any(|r| r.contains(p)) {
                    return Ok(());
                }
                false
            }
        };
        let row: &[u8] = match &input.convert {
            Some(c) => {
                c.convert(rec, input.record_len, index, &mut self.converted, d.stride)?;
                &self.converted
            }
            None => rec,
        };
        if own && let Some(&c) = d.class_at.and_then(|at| row.get(at)) {
            self.classes[c as usize] += 1;
        }
        let buf = &mut self.buffers[chunk];
        buf.extend_from_slice(row);
        if buf.len() >= self.per_chunk {
            let path = chunk_path(d.chunk_dir, chunk, self.part);
            append_block(&path, buf, d.stride, &mut self.scratch)?;
            buf.clear();
        }
        Ok(())
    }
}
