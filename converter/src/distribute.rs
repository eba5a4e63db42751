//! Phase 3: stream the staging file into one file per chunk, positions now quantized.

use crate::error::{ConvertError, Result};
use crate::plan::{grid_cell, grid_shape};
use crate::quantize::Quantization;
use crate::scan::{StagingReader, staging_position};
use indicatif::ProgressBar;
use std::fs::OpenOptions;
use std::io::Write;
use std::path::{Path, PathBuf};
use strata_format::Cube;

pub fn chunk_path(dir: &Path, index: usize) -> PathBuf {
    dir.join(format!("c{index}.bin"))
}

/// Appends buffered rows to a chunk file. Files are opened per flush, so any number of chunks
/// works within the process's file-descriptor limit.
fn flush(dir: &Path, index: usize, buf: &mut Vec<u8>) -> Result<()> {
    if buf.is_empty() {
        return Ok(());
    }
    let path = chunk_path(dir, index);
    let mut f = OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .map_err(|e| ConvertError::io(&path, "cannot open chunk file", e))?;
    f.write_all(buf)
        .map_err(|e| ConvertError::io(&path, "cannot write chunk file", e))?;
    buf.clear();
    Ok(())
}

#[allow(clippy::too_many_arguments)]
pub fn distribute(
    staging: &Path,
    staging_stride: usize,
    row_stride: usize,
    q: &Quantization,
    cube: &Cube,
    lut: &[u32],
    chunk_count: usize,
    chunk_dir: &Path,
    buffer_budget: u64,
    bar: &ProgressBar,
) -> Result<()> {
    let (level, shift) = grid_shape(cube);
    let per_chunk = (buffer_budget / chunk_count.max(1) as u64).clamp(16 << 10, 4 << 20) as usize;
    let mut buffers: Vec<Vec<u8>> = vec![Vec::new(); chunk_count];
    let mut reader = StagingReader::open(staging, staging_stride)?;
    let attr_len = row_stride - 12;
    loop {
        let n = reader.next_batch(1 << 16)?;
        if n == 0 {
            break;
        }
        for rec in reader.buf.chunks_exact(staging_stride) {
            let p = q.quantize(&staging_position(rec));
            let chunk = lut[grid_cell(p, cube, level, shift)] as usize;
            let buf = &mut buffers[chunk];
            buf.extend_from_slice(&p[0].to_le_bytes());
            buf.extend_from_slice(&p[1].to_le_bytes());
            buf.extend_from_slice(&p[2].to_le_bytes());
            buf.extend_from_slice(&rec[24..24 + attr_len]);
            if buf.len() >= per_chunk {
                flush(chunk_dir, chunk, buf)?;
            }
        }
        bar.inc(n as u64);
    }
    for (i, buf) in buffers.iter_mut().enumerate() {
        flush(chunk_dir, i, buf)?;
    }
    Ok(())
}
