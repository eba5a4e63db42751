//! Checks a LAZ file's laszip VLR and chunk table against its header and its length before the
//! `laz` decoder sees them. The decoder trusts both: an item size that disagrees with the record
//! length trips an assert in its parallel path, zero items divide by zero, and a chunk count or
//! offset taken at its word asks for tens of gigabytes. Whatever still panics inside it is caught
//! by [`guarded`] and becomes this file's error.

use super::las_header::{LasHeader, read_at};
use super::laz_chunks::{Chunk, LazChunks};
use laz::laszip::{ChunkTable, ChunkTableEntry};
use std::fs::File;
use std::io::Cursor;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Once;
use std::sync::atomic::{AtomicUsize, Ordering};

/// A chunk size beyond the points a file holds is refused where that many records would take
/// more than this: the 50,000 LASzip writers use take under 4 MiB at the usual record lengths.
const MAX_CHUNK_BYTES: u64 = 256 << 20;

/// Guarded calls in progress: while there are any, a panic is not reported on stderr (it
/// becomes the file's error instead).
static GUARDED: AtomicUsize = AtomicUsize::new(0);
static QUIET_HOOK: Once = Once::new();

/// Runs `f` (a call into a decoding dependency) so that a panic inside it, on this thread or on
/// the rayon workers it waits for, becomes an error saying `what` is corrupt.
pub fn guarded<T>(what: &str, f: impl FnOnce() -> Result<T, String>) -> Result<T, String> {
    QUIET_HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if GUARDED.load(Ordering::SeqCst) == 0 {
                previous(info);
            }
        }));
    });
    GUARDED.fetch_add(1, Ordering::SeqCst);
    let result = catch_unwind(AssertUnwindSafe(f));
    GUARDED.fetch_sub(1, Ordering::SeqCst);
    result.unwrap_or_else(|_| {
        Err(format!(
            "{what} is corrupt (its decoder could not make sense of it)"
        ))
    })
}

const LASZIP_USER: &str = "laszip encoded";
const LASZIP_RECORD: u16 = 22204;

/// The laszip VLR's facts that must agree with the header.
struct LaszipVlr {
    data: Vec<u8>,
    layered: bool,
    /// `None` for variable-size chunks.
    chunk_size: Option<u64>,
}

/// The expected size of each laszip item type; `None` for the extra-bytes types (any size).
fn item_size(item_type: u16) -> Option<Option<u64>> {
    Some(match item_type {
        0 | 14 => None,
        6 => Some(20),
        7 => Some(8),
        8 | 11 => Some(6),
        9 | 13 => Some(29),
        10 => Some(30),
        12 => Some(8),
        _ => return None,
    })
}

fn read_laszip_vlr(file: &File, h: &LasHeader) -> Result<LaszipVlr, String> {
    let Some(vlr) = h.find(LASZIP_USER, LASZIP_RECORD) else {
        return Err(
            "header field \"point data format\" marks the points as LAZ-compressed, but the file has no laszip VLR describing the compression".into(),
        );
    };
    let data = read_at(file, vlr.data_at, vlr.data_len as usize)?;
    let bad = |what: String| Err(format!("laszip VLR: {what}"));
    if data.len() < 34 {
        return bad(format!(
            "it is {} bytes, too short for its 34-byte description",
            data.len()
        ));
    }
    let u16_at = |o: usize| u16::from_le_bytes([data[o], data[o + 1]]);
    let compressor = u16_at(0);
    if !(2..=3).contains(&compressor) {
        return bad(format!(
            "compressor {compressor} is not chunked compression (2 or 3), the only kind supported"
        ));
    }
    let chunk_size = u32::from_le_bytes([data[12], data[13], data[14], data[15]]);
    let items = u16_at(32) as usize;
    if items == 0 {
        return bad("it lists no compressed items".into());
    }
    if data.len() < 34 + 6 * items {
        return bad(format!(
            "it lists {items} items but has room for only {}",
            (data.len() - 34) / 6
        ));
    }
    let mut total = 0u64;
    for i in 0..items {
        let (ty, size) = (u16_at(34 + 6 * i), u16_at(36 + 6 * i) as u64);
        match item_size(ty) {
            None => return bad(format!("item {} has unknown type {ty}", i + 1)),
            Some(Some(want)) if want != size => {
                return bad(format!(
                    "item {} (type {ty}) says {size} bytes where that type has {want}",
                    i + 1
                ));
            }
            Some(None) if size == 0 => return bad(format!("item {} is 0 bytes long", i + 1)),
            _ => {}
        }
        total += size;
    }
    if total != h.record_len {
        return bad(format!(
            "its items add up to {total} bytes per point, but header field \"point record length\" says {}",
            h.record_len
        ));
    }
    let first = u16_at(34);
    let (want, kind) = if h.format >= 6 {
        (10, "6 to 10")
    } else {
        (6, "0 to 5")
    };
    if first != want {
        return bad(format!(
            "its first item has type {first}, but point format {} (one of {kind}) needs type {want}",
            h.format
        ));
    }
    Ok(LaszipVlr {
        layered: compressor == 3,
        chunk_size: match chunk_size {
            0 | u32::MAX => None,
            n => Some(n as u64),
        },
        data,
    })
}

/// Checks the laszip VLR and the chunk table; on success the `laz` decoder can be given the
/// file, and the chunks are returned for decoding. The error is the fault, in words, without
/// the file name.
pub fn check_laz(file: &File, h: &LasHeader) -> Result<LazChunks, String> {
    let vlr = read_laszip_vlr(file, h)?;
    let laz_vlr = guarded("the laszip VLR", || {
        laz::LazVlr::from_buffer(&vlr.data).map_err(|e| format!("laszip VLR: {e}"))
    })?;
    let start = h.offset_to_points;
    if start + 8 > h.points_end() {
        return Err(format!(
            "the compressed point data at byte {start} is too short to hold its chunk table offset"
        ));
    }
    let mut table_at = u64::from_le_bytes(read8(file, start)?);
    // Where the offset used was read, for the message.
    let mut stored_at = start;
    // A writer that could not go back to fill the offset in leaves it at the end of the file.
    if table_at <= start || table_at > i64::MAX as u64 {
        stored_at = h.file_len - 8;
        table_at = u64::from_le_bytes(read8(file, stored_at)?);
    }
    let table_end = h
        .after_points
        .filter(|s| *s > table_at && *s <= h.file_len)
        .unwrap_or(h.file_len);
    if table_at < start + 8 || table_at.saturating_add(8) > table_end {
        return Err(format!(
            "the chunk table offset ({table_at}) stored at byte {stored_at} lies outside the compressed point data (bytes {} to {table_end}): the file is corrupt or truncated",
            start + 8
        ));
    }
    let head = read_at(file, table_at, 8)?;
    let chunks = u32::from_le_bytes([head[4], head[5], head[6], head[7]]) as u64;
    let data_len = table_at - start - 8;
    let points = h.points;
    // Every chunk holds at least one point in at least one byte; a table of variable-size
    // chunks may end with one empty chunk more (see below).
    let trailing = u64::from(vlr.chunk_size.is_none());
    if chunks > data_len + trailing || chunks > points + trailing {
        return Err(format!(
            "the chunk table at byte {table_at} lists {chunks} chunks, but the file holds {points} points in {data_len} bytes of compressed data"
        ));
    }
    if let Some(size) = vlr.chunk_size {
        let expected = points.div_ceil(size);
        if chunks != expected {
            return Err(format!(
                "the chunk table at byte {table_at} lists {chunks} chunks, but {points} points (header field \"number of point records\") in chunks of {size} (laszip VLR) make {expected}"
            ));
        }
    }
    let record_len = h.record_len as usize;
    if chunks == 0 {
        return Ok(LazChunks::new(
            own_handle(file)?,
            laz_vlr,
            vlr.layered,
            record_len,
            Vec::new(),
        ));
    }
    if let Some(size) = vlr.chunk_size {
        // The decoder sizes the last chunk's buffer by the chunk size, not by the points left
        // in it: a damaged size far beyond a one-chunk file's points would have it reserve
        // gigabytes (an abort, not an error) for a few points. Writers use 50,000 whatever the
        // file holds, so only a size beyond both the points and what a chunk may take is
        // refused.
        let bytes = size.saturating_mul(h.record_len);
        if size > points && bytes > MAX_CHUNK_BYTES {
            return Err(format!(
                "the laszip VLR gives chunks of {size} points, more than the {points} points the file holds (header field \"number of point records\"), and the decoder would reserve {} MiB for one: the chunk size is damaged, or far beyond what a file of this size needs",
                bytes >> 20
            ));
        }
    }
    let bytes = read_at(file, table_at, (table_end - table_at) as usize)?;
    let table = guarded("the chunk table", || {
        ChunkTable::read(&mut Cursor::new(bytes), vlr.chunk_size.is_none())
            .map_err(|_| match vlr.chunk_size {
                Some(_) => format!("the chunk table at byte {table_at} is corrupt or truncated"),
                // 0 and 4294967295 both declare variable-size chunks, whose table is laid
                // out otherwise: a damaged size reads a good table as garbage.
                None => format!(
                    "the chunk table at byte {table_at} does not read as the table of variable-size chunks the laszip VLR's chunk size declares: one of them is corrupt, or the table is truncated"
                ),
            })
    })?;
    let mut entries: Vec<ChunkTableEntry> = table.as_ref().to_vec();
    let stored: u64 = entries.iter().map(|e| e.byte_count).sum();
    // Chunks of variable size may end with empty ones (laz-rs writes one when its last batch
    // of chunks is closed by `done`): they hold no point to read, though the point-wise
    // compressor of formats 0 to 5 gives one a few bytes.
    if vlr.chunk_size.is_none() {
        while entries.len() > 1 && entries.last().is_some_and(|e| e.point_count == 0) {
            entries.pop();
        }
    }
    if stored != data_len {
        return Err(format!(
            "the chunk table at byte {table_at} gives chunk sizes adding up to {stored} bytes, but the compressed data is {data_len} bytes"
        ));
    }
    if let Some(i) = entries.iter().position(|e| e.byte_count == 0) {
        return Err(format!(
            "the chunk table at byte {table_at} gives chunk {i} no bytes (only empty chunks at the end may have none)"
        ));
    }
    let last_points = match vlr.chunk_size {
        Some(size) => points - size * (chunks - 1),
        None => {
            if let Some(i) = entries.iter().position(|e| e.point_count == 0) {
                return Err(format!(
                    "the chunk table at byte {table_at} gives chunk {i} no points (only chunks at the end may be empty)"
                ));
            }
            let listed: u64 = entries.iter().map(|e| e.point_count).sum();
            if listed != points {
                return Err(format!(
                    "the chunk table at byte {table_at} lists {listed} points, but header field \"number of point records\" says {points}"
                ));
            }
            entries[entries.len() - 1].point_count
        }
    };
    let mut at = start + 8;
    let mut left = points;
    let list = entries
        .iter()
        .map(|e| {
            let points = vlr.chunk_size.map_or(e.point_count, |size| size.min(left));
            let chunk = Chunk {
                at,
                bytes: e.byte_count,
                points,
            };
            at += e.byte_count;
            left = left.saturating_sub(points);
            chunk
        })
        .collect();
    let chunks = LazChunks::new(own_handle(file)?, laz_vlr, vlr.layered, record_len, list);
    chunks.check_last(last_points)?;
    Ok(chunks)
}

/// A handle of its own on the file, for the chunks' decoding.
fn own_handle(file: &File) -> Result<File, String> {
    file.try_clone()
        .map_err(|e| format!("cannot open the file a second time ({})", e.kind()))
}

fn read8(file: &File, at: u64) -> Result<[u8; 8], String> {
    let b = read_at(file, at, 8)?;
    Ok([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]])
}
