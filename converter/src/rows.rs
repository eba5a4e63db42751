//! Dataset rows (12 bytes of quantized position, then the dataset's attributes) straight from
//! LAS point records, and the files the count and distribute phases read rows from.

use crate::error::{ConvertError, Result};
use crate::input::PointSource;
use crate::input::las::LasSource;
use crate::input::las_layout::{FieldOp, record_to_row};
use crate::quantize::Quantization;
use crate::scan_angle::ScanAngleFill;
use std::fs::File;
use std::ops::Range;
use std::os::unix::fs::FileExt;
use std::path::PathBuf;
use strata_format::{Cube, RowLayout};

/// Turns one LAS input's point records into dataset rows, checking that every position falls
/// inside the cube chosen from the headers.
#[derive(Debug, Clone)]
pub struct RecordToRow {
    path: PathBuf,
    ops: Vec<FieldOp>,
    /// dataset integer = record integer + shift, when the input sits on the dataset's grid.
    shift: Option<[i64; 3]>,
    /// Otherwise dataset integer = round(base + ratio * record integer).
    ratio: [f64; 3],
    base: [f64; 3],
    lo: [i64; 3],
    hi: [i64; 3],
    /// The scan angle's other form, where the dataset holds both and the input one.
    scan_angle: Option<ScanAngleFill>,
}

impl RecordToRow {
    pub fn new(src: &LasSource, layout: &RowLayout, q: &Quantization, cube: &Cube) -> Self {
        let attributes = &src.info().attributes;
        // Where each source attribute starts in the source's row and in the dataset's.
        let mut at = 0;
        let starts: Vec<(usize, usize)> = attributes
            .iter()
            .map(|a| {
                let dataset = layout
                    .attributes
                    .iter()
                    .position(|u| u.name == a.name)
                    .map_or(0, |i| layout.offsets[i] - RowLayout::POSITION_BYTES);
                let here = at;
                at += a.size();
                (here, dataset)
            })
            .collect();
        // An op writes into one source attribute (a grouped normal has one op per component):
        // move it by as much as that attribute moves.
        let moved = |row: usize| {
            starts
                .iter()
                .rev()
                .find(|(source, _)| *source <= row)
                .map_or(row, |(source, dataset)| dataset + (row - source))
        };
        let ops = src
            .ops()
            .iter()
            .map(|op| match *op {
                FieldOp::Copy { record, row, len } => FieldOp::Copy {
                    record,
                    row: moved(row),
                    len,
                },
                FieldOp::Bits {
                    record,
                    shift,
                    mask,
                    row,
                } => FieldOp::Bits {
                    record,
                    shift,
                    mask,
                    row: moved(row),
                },
            })
            .collect();
        let (scale, offset) = src.transform();
        let ratio = [0, 1, 2].map(|a| scale[a] / q.scale[a]);
        let base = [0, 1, 2].map(|a| (offset[a] - q.offset[a]) / q.scale[a]);
        let whole = |v: f64| (v - v.round()).abs() < 1e-9;
        let shift = (0..3)
            .all(|a| ratio[a] == 1.0 && whole(base[a]))
            .then(|| base.map(|b| b.round() as i64));
        let edge = 1i64 << cube.bits;
        RecordToRow {
            path: src.info().path.clone(),
            ops,
            shift,
            ratio,
            base,
            lo: cube.min,
            hi: cube.min.map(|m| m + edge - 1),
            scan_angle: ScanAngleFill::for_input(
                attributes,
                &layout.attributes,
                RowLayout::POSITION_BYTES,
            ),
        }
    }

    /// The dataset position of record number `index`, `rec` its bytes.
    #[inline]
    pub fn position(&self, rec: &[u8], index: u64) -> Result<[i32; 3]> {
        let mut p = [0i32; 3];
        for (a, out) in p.iter_mut().enumerate() {
            let o = 4 * a;
            let raw = i32::from_le_bytes([rec[o], rec[o + 1], rec[o + 2], rec[o + 3]]) as i64;
            let v = match self.shift {
                Some(s) => raw + s[a],
                None => (self.base[a] + self.ratio[a] * raw as f64).round() as i64,
            };
            if v < self.lo[a] || v > self.hi[a] {
                return Err(ConvertError::OutsideHeaderBounds {
                    path: self.path.clone(),
                    record: index,
                });
            }
            *out = v as i32;
        }
        Ok(p)
    }

    /// Converts whole records of `record_len` bytes into rows of `stride` bytes (attributes
    /// this input lacks stay zero). `first` numbers the first record.
    pub fn convert(
        &self,
        records: &[u8],
        record_len: usize,
        first: u64,
        rows: &mut Vec<u8>,
        stride: usize,
    ) -> Result<()> {
        let n = records.len() / record_len;
        rows.clear();
        rows.resize(n * stride, 0);
        for (i, (rec, row)) in records
            .chunks_exact(record_len)
            .zip(rows.chunks_exact_mut(stride))
            .enumerate()
        {
            let p = self.position(rec, first + i as u64)?;
            for a in 0..3 {
                row[4 * a..4 * a + 4].copy_from_slice(&p[a].to_le_bytes());
            }
            record_to_row(&self.ops, rec, &mut row[RowLayout::POSITION_BYTES..]);
            if let Some(fill) = &self.scan_angle {
                fill.apply(row);
            }
        }
        Ok(())
    }
}

/// A file of fixed-length records the count and distribute phases read: an uncompressed LAS
/// input read in place (`convert` set), or a staging file that already holds rows, compressed
/// in blocks (`rowfile`).
#[derive(Debug, Clone)]
pub struct RowInput {
    pub path: PathBuf,
    pub start: u64,
    pub record_len: usize,
    pub records: u64,
    pub convert: Option<RecordToRow>,
    /// Written by `rowfile::RowWriter` (a staging file), not plain records: where its blocks
    /// start.
    pub blocks: Option<Vec<u64>>,
}

/// Records per read, at most.
const BATCH: u64 = 1 << 16;

/// Bytes a batch of records may take: wide records (thousands of attributes) come fewer at a
/// time rather than in a batch of many gigabytes.
const BATCH_BYTES: usize = 16 << 20;

/// How many records of `record_len` bytes to handle at once: at most `most`, at least one.
pub fn batch_records(record_len: usize, most: usize) -> usize {
    (BATCH_BYTES / record_len.max(1)).clamp(1, most)
}

impl RowInput {
    /// Records `0..records` split into `parts` ranges, in order.
    pub fn part(&self, part: usize, parts: usize) -> Range<u64> {
        let at = |k: usize| self.records * k as u64 / parts as u64;
        at(part)..at(part + 1)
    }

    /// Calls `each(records, first)` on the raw records of `range`, in batches.
    pub fn for_each_raw(
        &self,
        range: Range<u64>,
        each: impl FnMut(&[u8], u64) -> Result<()>,
    ) -> Result<()> {
        self.read_raw(range, false, BATCH as usize, each)
    }

    /// As `for_each_raw`, at most `most` records at a time; with `release`, a staging file
    /// frees what has been read (the last reading, by the distribute phase).
    fn read_raw(
        &self,
        range: Range<u64>,
        release: bool,
        most: usize,
        mut each: impl FnMut(&[u8], u64) -> Result<()>,
    ) -> Result<()> {
        if let Some(blocks) = &self.blocks {
            let len = self.record_len;
            return crate::rowfile::for_each_in(&self.path, blocks, len, range, release, each);
        }
        let file =
            File::open(&self.path).map_err(|e| ConvertError::io(&self.path, "cannot open", e))?;
        let mut raw = Vec::new();
        let mut at = range.start;
        while at < range.end {
            let n = (range.end - at).min(batch_records(self.record_len, most) as u64);
            raw.resize(n as usize * self.record_len, 0);
            file.read_exact_at(&mut raw, self.start + at * self.record_len as u64)
                .map_err(|e| {
                    ConvertError::io(
                        &self.path,
                        format!("cannot read records {at}..{}", at + n),
                        e,
                    )
                })?;
            each(&raw, at)?;
            at += n;
        }
        Ok(())
    }

    /// Calls `each(rows)` on the rows of `range`, in batches. With `release`, for the last
    /// time: the blocks of a staging file are freed as they are read (so distributing moves
    /// the rows from the staging file into the chunk files rather than copying them). From a
    /// file of plain records, a batch's records and rows together take at most `batch_bytes`
    /// (one record at least); a staging file comes a block (1 MiB at most) at a time.
    pub fn for_each_rows(
        &self,
        range: Range<u64>,
        stride: usize,
        release: bool,
        batch_bytes: usize,
        mut each: impl FnMut(&[u8]) -> Result<()>,
    ) -> Result<()> {
        let mut rows = Vec::new();
        let most = (batch_bytes / (self.record_len + stride).max(1)).clamp(1, BATCH as usize);
        self.read_raw(range, release, most, |raw, first| match &self.convert {
            Some(c) => {
                c.convert(raw, self.record_len, first, &mut rows, stride)?;
                each(&rows)
            }
            None => each(raw),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_batch_budget_reads_the_same_rows_fewer_at_a_time() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rows.bin");
        let (len, records) = (20usize, 1000u64);
        let bytes: Vec<u8> = (0..len * records as usize)
            .map(|i| (i % 251) as u8)
            .collect();
        // A header of 7 bytes before the records.
        let mut file = vec![0xAA; 7];
        file.extend_from_slice(&bytes);
        std::fs::write(&path, &file).unwrap();
        let input = RowInput {
            path,
            start: 7,
            record_len: len,
            records,
            convert: None,
            blocks: None,
        };
        for (budget, most) in [(usize::MAX, BATCH as usize), (40 * 33, 33), (1, 1)] {
            let (mut read, mut largest) = (Vec::new(), 0);
            input
                .for_each_rows(10..records, len, false, budget, |rows| {
                    largest = largest.max(rows.len() / len);
                    read.extend_from_slice(rows);
                    Ok(())
                })
                .unwrap();
            assert_eq!(read, bytes[10 * len..], "budget {budget}");
            assert_eq!(largest, most.min(990), "budget {budget}");
        }
    }
}
