//! Staging files of dataset rows, for inputs the distribute phase cannot read in place: LAZ
//! (decoded once) and, on the general path, the f64 staging file once the scale is known.

use crate::error::{ConvertError, Result, panic_message, spawn_worker};
use crate::input::las::LasSource;
use crate::plan::Counts;
use crate::quantize::Quantization;
use crate::rowfile::{RowWriter, for_each_block};
use crate::rows::{RecordToRow, RowInput, batch_records};
use crate::scan::staging_position;
use indicatif::ProgressBar;
use std::path::Path;
use strata_format::row_position;

fn create(path: &Path, stride: usize) -> Result<RowWriter> {
    RowWriter::create(path, stride)
}

fn finish(out: RowWriter, path: &Path, stride: usize) -> Result<RowInput> {
    let (records, blocks) = out.finish_indexed()?;
    Ok(RowInput {
        path: path.to_path_buf(),
        start: 0,
        record_len: stride,
        records,
        convert: None,
        blocks: Some(blocks),
    })
}

/// Decodes a (compressed) LAS input once into rows, counting them into `counts` on the way.
/// Decompression (which runs on the rayon pool) overlaps with converting, counting and writing
/// the previous batch on a thread of its own.
pub fn decode_to_rows(
    src: &mut LasSource,
    conv: &RecordToRow,
    stride: usize,
    staging: &Path,
    counts: &mut Counts,
    bar: &ProgressBar,
) -> Result<RowInput> {
    let out = create(staging, stride)?;
    let record_len = src.record_len();
    let (full_tx, full_rx) = std::sync::mpsc::sync_channel::<(Vec<u8>, u64)>(1);
    let (empty_tx, empty_rx) = std::sync::mpsc::channel::<Vec<u8>>();
    std::thread::scope(|scope| {
        let writer = spawn_worker(
            scope,
            "writing staging rows",
            0,
            move || -> Result<(RowWriter, u64)> {
                let mut out = out;
                let mut rows = Vec::new();
                let mut done = 0u64;
                for (records, first) in full_rx {
                    conv.convert(&records, record_len, first, &mut rows, stride)?;
                    for row in rows.chunks_exact(stride) {
                        counts.add(row_position(row));
                    }
                    out.write(&rows)?;
                    let n = (records.len() / record_len) as u64;
                    done += n;
                    bar.inc(n);
                    let _ = empty_tx.send(records);
                }
                Ok((out, done))
            },
        )?;
        let mut decoded = 0u64;
        let read = loop {
            let records = match src.read_records(batch_records(record_len, 1 << 18)) {
                Ok(r) => r,
                Err(e) => break Err(e),
            };
            if records.is_empty() {
                break Ok(());
            }
            let mut batch = empty_rx.try_recv().unwrap_or_default();
            batch.clear();
            batch.extend_from_slice(records);
            let n = (records.len() / record_len) as u64;
            // A closed channel means the writer stopped on an error, which it returns.
            if full_tx.send((batch, decoded)).is_err() {
                break Ok(());
            }
            decoded += n;
        };
        drop(full_tx);
        let written = writer.join().unwrap_or_else(|p| {
            Err(ConvertError::internal(
                "writing staging rows",
                panic_message(p.as_ref()),
            ))
        });
        read?;
        let (out, _) = written?;
        finish(out, staging, stride)
    })
}

/// Quantizes an f64 staging file (see `scan`) into rows.
pub fn quantize_staging(
    f64_staging: &Path,
    f64_stride: usize,
    q: &Quantization,
    stride: usize,
    staging: &Path,
    bar: &ProgressBar,
) -> Result<RowInput> {
    let mut out = create(staging, stride)?;
    let attr_len = stride - 12;
    let mut rows = Vec::new();
    let mut done = 0u64;
    for_each_block(f64_staging, f64_stride, |records| {
        rows.clear();
        for rec in records.chunks_exact(f64_stride) {
            for v in q.quantize(&staging_position(rec)) {
                rows.extend_from_slice(&v.to_le_bytes());
            }
            rows.extend_from_slice(&rec[24..24 + attr_len]);
        }
        out.write(&rows)?;
        let n = (records.len() / f64_stride) as u64;
        done += n;
        bar.inc(n);
        Ok(())
    })?;
    debug_assert_eq!(out.rows, done);
    finish(out, staging, stride)
}
