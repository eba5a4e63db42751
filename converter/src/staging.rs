//! Staging files of dataset rows, for inputs the distribute phase cannot read in place: LAZ
//! (decoded once) and, on the general path, the f64 staging file once the scale is known.

use crate::error::{ConvertError, Result, panic_message};
use crate::input::las::LasSource;
use crate::plan::Counts;
use crate::quantize::Quantization;
use crate::rows::{RecordToRow, RowInput, batch_records};
use crate::scan::{StagingReader, staging_position};
use indicatif::ProgressBar;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;
use strata_format::row_position;

fn create(path: &Path) -> Result<BufWriter<File>> {
    let file =
        File::create(path).map_err(|e| ConvertError::io(path, "cannot create staging file", e))?;
    Ok(BufWriter::with_capacity(8 << 20, file))
}

fn finish(out: BufWriter<File>, path: &Path, stride: usize, records: u64) -> Result<RowInput> {
    out.into_inner()
        .map_err(|e| ConvertError::io(path, "cannot write staging file", e.into_error()))?;
    Ok(RowInput {
        path: path.to_path_buf(),
        start: 0,
        record_len: stride,
        records,
        convert: None,
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
    let out = create(staging)?;
    let record_len = src.record_len();
    let (full_tx, full_rx) = std::sync::mpsc::sync_channel::<(Vec<u8>, u64)>(1);
    let (empty_tx, empty_rx) = std::sync::mpsc::channel::<Vec<u8>>();
    std::thread::scope(|scope| {
        let writer = scope.spawn(move || -> Result<(BufWriter<File>, u64)> {
            let mut out = out;
            let mut rows = Vec::new();
            let mut done = 0u64;
            for (records, first) in full_rx {
                conv.convert(&records, record_len, first, &mut rows, stride)?;
                for row in rows.chunks_exact(stride) {
                    counts.add(row_position(row));
                }
                out.write_all(&rows)
                    .map_err(|e| ConvertError::io(staging, "cannot write staging file", e))?;
                let n = (records.len() / record_len) as u64;
                done += n;
                bar.inc(n);
                let _ = empty_tx.send(records);
            }
            Ok((out, done))
        });
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
        let (out, done) = written?;
        finish(out, staging, stride, done)
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
    let mut out = create(staging)?;
    let mut reader = StagingReader::open(f64_staging, f64_stride)?;
    let attr_len = stride - 12;
    let mut rows = Vec::new();
    let mut done = 0u64;
    loop {
        let n = reader.next_batch(batch_records(f64_stride, 1 << 16))?;
        if n == 0 {
            break;
        }
        rows.clear();
        for rec in reader.buf.chunks_exact(f64_stride) {
            for v in q.quantize(&staging_position(rec)) {
                rows.extend_from_slice(&v.to_le_bytes());
            }
            rows.extend_from_slice(&rec[24..24 + attr_len]);
        }
        out.write_all(&rows)
            .map_err(|e| ConvertError::io(staging, "cannot write staging file", e))?;
        done += n as u64;
        bar.inc(n as u64);
    }
    finish(out, staging, stride, done)
}
