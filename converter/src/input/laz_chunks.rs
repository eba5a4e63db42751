//! A LAZ file's point data, decoded chunk by chunk, chunks in parallel. The `las` reader's
//! decoder trusts every chunk but the last (which `laz_check` tries whole before a run): a
//! chunk damaged inside decodes to points that look like any others, millions of units off,
//! and the file would convert without a word. A sound chunk's decoder ends exactly at the end
//! of the chunk's bytes; a damaged one runs short of them or over. So each chunk is decoded
//! from its own bytes, and must use up those bytes and no more.

use super::las_header::read_at;
use super::laz_check::guarded;
use laz::LazVlr;
use laz::record::{
    LayeredPointRecordDecompressor, RecordDecompressor, SequentialPointRecordDecompressor,
};
use rayon::prelude::*;
use std::fs::File;
use std::io::Cursor;

/// One compressed chunk: where its bytes lie in the file, and the points it holds.
#[derive(Debug, Clone, Copy)]
pub struct Chunk {
    pub at: u64,
    pub bytes: u64,
    pub points: u64,
}

/// The chunks of a file `laz_check` has checked, the next one to decode, and the records
/// decoded and not yet handed on.
pub struct LazChunks {
    file: File,
    vlr: LazVlr,
    /// Formats 6 to 10: each chunk holds its first point, its count, then one stream per field.
    layered: bool,
    record_len: usize,
    chunks: Vec<Chunk>,
    next: usize,
    /// The index of the next chunk's first point.
    first_point: u64,
    /// Records decoded, those before byte `handed` handed on.
    decoded: Vec<u8>,
    handed: usize,
}

impl LazChunks {
    pub fn new(
        file: File,
        vlr: LazVlr,
        layered: bool,
        record_len: usize,
        chunks: Vec<Chunk>,
    ) -> LazChunks {
        LazChunks {
            file,
            vlr,
            layered,
            record_len,
            chunks,
            next: 0,
            first_point: 0,
            decoded: Vec::new(),
            handed: 0,
        }
    }

    /// Hands on up to `max` records (decoding more chunks where none are left): where their
    /// bytes lie in `records`, empty once every chunk has been handed on. The error is the
    /// fault, in words, without the file name.
    pub fn take(&mut self, max: u64) -> Result<std::ops::Range<usize>, String> {
        if self.handed == self.decoded.len() {
            self.decoded.clear();
            self.handed = 0;
            self.decode_next(max)?;
        }
        let len = (max as usize * self.record_len).min(self.decoded.len() - self.handed);
        self.handed += len;
        Ok(self.handed - len..self.handed)
    }

    /// The records decoded (`take` says which were handed on last).
    pub fn records(&self) -> &[u8] {
        &self.decoded
    }

    /// Decodes the next chunks, at least one and as many more as fit in `max` points.
    fn decode_next(&mut self, max: u64) -> Result<(), String> {
        let mut end = self.next;
        let mut points = 0;
        while end < self.chunks.len()
            && (end == self.next || points + self.chunks[end].points <= max)
        {
            points += self.chunks[end].points;
            end += 1;
        }
        let mut firsts = Vec::with_capacity(end - self.next);
        let mut first = self.first_point;
        for c in &self.chunks[self.next..end] {
            firsts.push(first);
            first += c.points;
        }
        let (file, vlr) = (&self.file, &self.vlr);
        let (layered, record_len) = (self.layered, self.record_len);
        let batch = &self.chunks[self.next..end];
        let decoded = guarded("the LAZ point data", || {
            batch
                .par_iter()
                .zip(firsts.par_iter())
                .map(|(c, &first)| decode_chunk(file, vlr, layered, record_len, c, first))
                .collect::<Result<Vec<Vec<u8>>, String>>()
        })?;
        for records in &decoded {
            self.decoded.extend_from_slice(records);
        }
        self.next = end;
        self.first_point = first;
        Ok(())
    }
}

/// The records of chunk `c`, whose first point is the file's `first`.
fn decode_chunk(
    file: &File,
    vlr: &LazVlr,
    layered: bool,
    record_len: usize,
    c: &Chunk,
    first: u64,
) -> Result<Vec<u8>, String> {
    let place = format!(
        "the compressed chunk at byte {} (points {first} to {})",
        c.at,
        (first + c.points).saturating_sub(1)
    );
    let bytes = read_at(file, c.at, c.bytes as usize)?;
    let mut records = vec![0u8; c.points as usize * record_len];
    let used = if layered {
        // The count stated after the first point must be the chunk's.
        let stated = bytes
            .get(record_len..record_len + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as u64);
        if stated != Some(c.points) {
            return Err(format!(
                "{place} states {} points, but the chunk table gives it {}",
                stated.map_or("no number of".to_string(), |n| n.to_string()),
                c.points
            ));
        }
        let mut dec = LayeredPointRecordDecompressor::new(Cursor::new(bytes));
        decode_all(&mut dec, vlr, &mut records, record_len, &place)?;
        dec.get_mut().position()
    } else {
        let mut dec = SequentialPointRecordDecompressor::new(Cursor::new(bytes));
        decode_all(&mut dec, vlr, &mut records, record_len, &place)?;
        dec.get_mut().position()
    };
    if used != c.bytes {
        return Err(format!(
            "{place} is corrupt: its {} points decode from {used} of its {} bytes",
            c.points, c.bytes
        ));
    }
    Ok(records)
}

fn decode_all<R: std::io::Read>(
    dec: &mut impl RecordDecompressor<R>,
    vlr: &LazVlr,
    records: &mut [u8],
    record_len: usize,
    place: &str,
) -> Result<(), String> {
    dec.set_fields_from(vlr.items())
        .map_err(|e| format!("laszip VLR: {e}"))?;
    for (i, point) in records.chunks_exact_mut(record_len).enumerate() {
        dec.decompress_next(point).map_err(|_| {
            format!("{place} is corrupt or truncated: its bytes end within point {i} of the chunk")
        })?;
    }
    Ok(())
}
