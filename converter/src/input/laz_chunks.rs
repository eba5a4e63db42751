//! A LAZ file's point data, decoded chunk by chunk, chunks in parallel. The `las` reader's
//! decoder trusts every chunk but the last (which `laz_check` tries whole before a run): a
//! point-wise chunk (formats 0 to 5) damaged inside decodes to points that look like any
//! others, millions of units off, and the file would convert without a word. A sound chunk's
//! decoder ends exactly at the end of the chunk's bytes; a damaged one runs short of them or
//! over. So each chunk is decoded from its own bytes, and must use up those bytes and no more.
//!
//! A layered chunk (formats 6 to 10) states its count and the size of each field's stream, and
//! its decoder reads every stream whole with the first point: the count and the sizes are
//! checked against the chunk, but damage inside one stream is caught only where its decoder
//! runs out of bytes (the `laz` decoder does not say how much of each stream it used).

use super::las_header::read_at;
use super::laz_check::guarded;
use laz::LazVlr;
use laz::record::{
    LayeredPointRecordDecompressor, RecordDecompressor, SequentialPointRecordDecompressor,
};
use rayon::prelude::*;
use std::fs::File;
use std::io::Cursor;

/// Points a chunk may hold and still be decoded whole, beside others in parallel. A larger
/// one (a chunk size far beyond the usual 50,000, or a count a damaged table states) is
/// decoded a batch at a time: memory follows the batch, not the count.
const WHOLE_CHUNK_POINTS: u64 = 1 << 20;

/// One compressed chunk: where its bytes lie in the file, and the points it holds.
#[derive(Debug, Clone, Copy)]
pub struct Chunk {
    pub at: u64,
    pub bytes: u64,
    pub points: u64,
}

type Decoder = Box<dyn RecordDecompressor<Cursor<Vec<u8>>> + Send>;

/// A large chunk being decoded a batch at a time.
struct OpenChunk {
    decoder: Decoder,
    chunk: Chunk,
    place: String,
    /// Its points decoded so far.
    done: u64,
}

/// What decoding any chunk of a file takes.
struct ChunkReader {
    file: File,
    vlr: LazVlr,
    layered: bool,
    record_len: usize,
}

/// The chunks of a file `laz_check` has checked, the next one to decode, and the records
/// decoded and not yet handed on.
pub struct LazChunks {
    reader: ChunkReader,
    record_len: usize,
    /// `WHOLE_CHUNK_POINTS`, smaller in tests.
    whole_chunk_points: u64,
    chunks: Vec<Chunk>,
    next: usize,
    /// The index of the next chunk's first point.
    first_point: u64,
    open: Option<OpenChunk>,
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
            reader: ChunkReader {
                file,
                vlr,
                layered,
                record_len,
            },
            record_len,
            whole_chunk_points: WHOLE_CHUNK_POINTS,
            chunks,
            next: 0,
            first_point: 0,
            open: None,
            decoded: Vec::new(),
            handed: 0,
        }
    }

    /// Hands on up to `max` records (decoding more where none are left): where their bytes
    /// lie in `records`, empty once every chunk has been handed on. The error is the fault,
    /// in words, without the file name.
    pub fn take(&mut self, max: u64) -> Result<std::ops::Range<usize>, String> {
        if self.handed == self.decoded.len() {
            self.decoded.clear();
            self.handed = 0;
            self.decode_next(max.max(1))?;
        }
        let len = (max as usize * self.record_len).min(self.decoded.len() - self.handed);
        self.handed += len;
        Ok(self.handed - len..self.handed)
    }

    /// The records decoded (`take` says which were handed on last).
    pub fn records(&self) -> &[u8] {
        &self.decoded
    }

    /// Decodes the last chunk alone, before a run, so that a header count that leaves it
    /// `expected` points is refused at once: the count must account for every point of it,
    /// not only some. A layered chunk states its count; a point-wise one must be used up, to
    /// its last byte, by exactly `expected` points.
    pub fn check_last(&self, expected: u64) -> Result<(), String> {
        let Some(c) = self.chunks.last() else {
            return Ok(());
        };
        let at = c.at;
        let mismatch = |found: String| {
            Err(format!(
                "the last compressed chunk (at byte {at}) holds {found} points, but the header's \
                 \"number of point records\" leaves it {expected}"
            ))
        };
        let reader = &self.reader;
        let record_len = reader.record_len;
        if reader.layered {
            let Some(b) = (c.bytes >= record_len as u64 + 4)
                .then(|| read_at(&reader.file, at + record_len as u64, 4))
                .transpose()?
            else {
                return Err(format!(
                    "the last compressed chunk (at byte {at}) is too short to hold its first point"
                ));
            };
            let count = u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as u64;
            return if count == expected {
                Ok(())
            } else {
                mismatch(count.to_string())
            };
        }
        let place = format!("the last compressed chunk (at byte {at})");
        let used = guarded(&place, || {
            let mut decoder = reader.open_chunk(c, &place)?;
            // A point at a time: the count is the header's, not yet known to be the chunk's.
            let mut point = vec![0u8; record_len];
            for done in 0..expected {
                decode_points(&mut *decoder, &mut point, record_len, &place, done)?;
            }
            Ok(decoder.get_mut().position())
        })?;
        if used < c.bytes {
            return mismatch(format!("more than {expected}"));
        }
        Ok(())
    }

    /// Decodes the next batch: up to `max` points of a large chunk, or the next chunks whole,
    /// at least one and as many more as fit in `max` points.
    fn decode_next(&mut self, max: u64) -> Result<(), String> {
        if self.open.is_none()
            && let Some(&c) = self.chunks.get(self.next)
            && c.points > self.whole_chunk_points
        {
            let place = place(&c, self.first_point);
            let decoder = self.reader.open_chunk(&c, &place)?;
            self.open = Some(OpenChunk {
                decoder,
                chunk: c,
                place,
                done: 0,
            });
            self.next += 1;
            self.first_point += c.points;
        }
        let record_len = self.record_len;
        if let Some(open) = &mut self.open {
            let n = (open.chunk.points - open.done).min(max);
            self.decoded.resize(n as usize * record_len, 0);
            let (decoded, done) = (&mut self.decoded, open.done);
            guarded(&open.place, || {
                decode_points(&mut *open.decoder, decoded, record_len, &open.place, done)
            })?;
            open.done += n;
            if open.done == open.chunk.points {
                let used = open.decoder.get_mut().position();
                let result = used_up(&open.chunk, used, &open.place);
                self.open = None;
                result?;
            }
            return Ok(());
        }
        let mut end = self.next;
        let mut points = 0;
        while let Some(c) = self.chunks.get(end)
            && c.points <= self.whole_chunk_points
            && (end == self.next || points + c.points <= max)
        {
            points += c.points;
            end += 1;
        }
        let batch = &self.chunks[self.next..end];
        // Each chunk decodes straight into its own part of the batch.
        self.decoded.resize(points as usize * record_len, 0);
        let mut parts = Vec::with_capacity(batch.len());
        let mut rest = &mut self.decoded[..];
        let mut first = self.first_point;
        for c in batch {
            let (part, after) = rest.split_at_mut(c.points as usize * record_len);
            parts.push((c, first, part));
            rest = after;
            first += c.points;
        }
        let reader = &self.reader;
        // In the file's order, so that the fault named is the first chunk's whatever the
        // threads did first.
        let results: Vec<Result<(), String>> = parts
            .into_par_iter()
            .map(|(c, first, part)| {
                let place = place(c, first);
                guarded(&place, || reader.decode_whole(c, &place, part))
            })
            .collect();
        results.into_iter().collect::<Result<(), String>>()?;
        self.next = end;
        self.first_point = first;
        Ok(())
    }
}

/// Chunk `c`, whose first point is the file's `first`, in words.
fn place(c: &Chunk, first: u64) -> String {
    format!(
        "the compressed chunk at byte {} (points {first} to {})",
        c.at,
        (first + c.points).saturating_sub(1)
    )
}

impl ChunkReader {
    /// Chunk `c` decoded into `out`, which holds its points.
    fn decode_whole(&self, c: &Chunk, place: &str, out: &mut [u8]) -> Result<(), String> {
        let mut decoder = self.open_chunk(c, place)?;
        decode_points(&mut *decoder, out, self.record_len, place, 0)?;
        used_up(c, decoder.get_mut().position(), place)
    }

    /// The decoder of chunk `c`, over its bytes; a layered chunk's stated count checked first.
    fn open_chunk(&self, c: &Chunk, place: &str) -> Result<Decoder, String> {
        let bytes = read_at(&self.file, c.at, c.bytes as usize)?;
        let mut decoder: Decoder = if self.layered {
            let at = self.record_len;
            let stated = bytes
                .get(at..at + 4)
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as u64);
            if stated != Some(c.points) {
                return Err(format!(
                    "{place} states {} points, but the chunk table gives it {}",
                    stated.map_or("no number of".to_string(), |n| n.to_string()),
                    c.points
                ));
            }
            Box::new(LayeredPointRecordDecompressor::new(Cursor::new(bytes)))
        } else {
            Box::new(SequentialPointRecordDecompressor::new(Cursor::new(bytes)))
        };
        decoder
            .set_fields_from(self.vlr.items())
            .map_err(|e| format!("laszip VLR: {e}"))?;
        Ok(decoder)
    }
}

/// Decodes `out.len() / record_len` points; `done`: the chunk's points decoded before.
fn decode_points(
    decoder: &mut dyn RecordDecompressor<Cursor<Vec<u8>>>,
    out: &mut [u8],
    record_len: usize,
    place: &str,
    done: u64,
) -> Result<(), String> {
    for (i, point) in out.chunks_exact_mut(record_len).enumerate() {
        decoder.decompress_next(point).map_err(|_| {
            format!(
                "{place} is corrupt or truncated: its decoder fails at point {} of the chunk",
                done + i as u64
            )
        })?;
    }
    Ok(())
}

/// A decoded chunk must have used up its bytes exactly.
fn used_up(c: &Chunk, used: u64, place: &str) -> Result<(), String> {
    if used == c.bytes {
        Ok(())
    } else {
        Err(format!(
            "{place} is corrupt: its {} points decode from {used} of its {} bytes",
            c.points, c.bytes
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::super::las_header::LasHeader;
    use super::super::laz_check::check_laz;
    use std::fs::File;

    /// Every record of `path`, handed on `max` at a time, with chunks of more than `whole`
    /// points decoded a batch at a time.
    fn all_records(path: &std::path::Path, whole: u64, max: u64) -> Vec<u8> {
        let file = File::open(path).expect("open");
        let len = file.metadata().expect("size").len();
        let header = LasHeader::read(&file, len).expect("header");
        let mut chunks = check_laz(&file, &header).expect("checked");
        chunks.whole_chunk_points = whole;
        let mut out = Vec::new();
        loop {
            let range = chunks.take(max).expect("decoded");
            if range.is_empty() {
                return out;
            }
            out.extend_from_slice(&chunks.records()[range]);
        }
    }

    #[test]
    fn a_large_chunk_decoded_a_batch_at_a_time_gives_the_same_records() {
        let dir = tempfile::tempdir().expect("tempdir");
        let laz = dir.path().join("city.laz");
        // Chunks of 50,000 points: the last holds 20,000.
        crate::synth::synth(&laz, 120_000, crate::synth::Scene::City, 3, 0.0, false)
            .expect("synth laz");
        let whole = all_records(&laz, u64::MAX, 1 << 18);
        assert_eq!(whole.len(), 120_000 * 34);
        // Every chunk large: each decoded in batches of 7,000 points, across its end.
        assert!(whole == all_records(&laz, 10_000, 7_000));
        // Whole chunks handed on in smaller pieces than they decode in.
        assert!(whole == all_records(&laz, u64::MAX, 7_000));
    }
}
