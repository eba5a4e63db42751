//! The binary sections of an E57 file's scans (ASTM E2807 section 9.8, compressed vectors),
//! walked before the `e57` crate decodes them. The crate reads a data packet's byte streams by
//! the sizes it states and never compares them with the packet's length, nor the packets with
//! the section's length, nor the values with the record count: a stream size off by a few
//! bytes shifted every later packet and decoded garbage, a record count one too high decoded a
//! point from the padding bits, one too low dropped the points past it, and a section that
//! states no room for its packets was read all the same, each converted without a word. A
//! scan whose fields all take no bits (each minimum equal to its maximum) made the crate grow
//! a queue until memory ran out.
//! Only the packet headers are read here: a few bytes a packet of up to 64 KiB.

use super::e57_header::PAGE;
use e57::{PointCloud, RecordDataType};
use std::io::{Read, Seek, SeekFrom};

/// The bytes of a page before its checksum: what logical offsets count.
const PAYLOAD: u64 = PAGE as u64 - 4;

fn logical(physical: u64) -> u64 {
    physical / PAGE as u64 * PAYLOAD + physical % PAGE as u64
}

fn physical(logical: u64) -> u64 {
    logical / PAYLOAD * PAGE as u64 + logical % PAYLOAD
}

/// Bits a value of `data` takes in its byte stream (the crate's packing).
fn bits(data: &RecordDataType) -> u64 {
    let integer = |min: i64, max: i64| {
        let range = i128::from(max) - i128::from(min);
        if range > 0 {
            u64::from(range.ilog2()) + 1
        } else {
            0
        }
    };
    match *data {
        RecordDataType::Single { .. } => 32,
        RecordDataType::Double { .. } => 64,
        RecordDataType::ScaledInteger { min, max, .. } | RecordDataType::Integer { min, max } => {
            integer(min, max)
        }
    }
}

/// Reads `buf.len()` bytes at logical offset `at`, across page checksums.
fn read_logical<F: Read + Seek>(file: &mut F, at: u64, buf: &mut [u8]) -> std::io::Result<()> {
    let mut done = 0;
    while done < buf.len() {
        let l = at + done as u64;
        let room = (PAYLOAD - l % PAYLOAD) as usize;
        let take = room.min(buf.len() - done);
        file.seek(SeekFrom::Start(physical(l)))?;
        file.read_exact(&mut buf[done..done + take])?;
        done += take;
    }
    Ok(())
}

/// Checks the binary section of every scan in `clouds`, read from `file` of `len` bytes. The
/// fault, as the end of a sentence that names the file, where one is found.
pub fn check_sections<F: Read + Seek>(
    file: &mut F,
    len: u64,
    clouds: &[PointCloud],
) -> Result<(), String> {
    let n = clouds.len();
    for (i, pc) in clouds.iter().enumerate() {
        if let Some(j) = clouds[..i]
            .iter()
            .position(|o| o.file_offset == pc.file_offset)
        {
            return Err(format!(
                "scans {j} and {i} of {n} name the same binary section (at byte {}): one \
                 scan's points would be read twice",
                pc.file_offset
            ));
        }
        if pc.prototype.iter().all(|r| bits(&r.data_type) == 0) {
            return Err(format!(
                "scan {i} of {n}: every field of its points takes no bits (each minimum equals \
                 its maximum), so its binary section cannot say how many points it holds"
            ));
        }
        check_section(file, len, pc).map_err(|e| format!("scan {i} of {n}: {e}"))?;
    }
    Ok(())
}

fn check_section<F: Read + Seek>(file: &mut F, len: u64, pc: &PointCloud) -> Result<(), String> {
    let io = |at: u64| move |e: std::io::Error| format!("cannot read byte {at} ({e})");
    let start = pc.file_offset;
    let mut header = [0u8; 32];
    read_logical(file, logical(start), &mut header).map_err(io(start))?;
    let u64_at = |at: usize| {
        let mut b = [0u8; 8];
        b.copy_from_slice(&header[at..at + 8]);
        u64::from_le_bytes(b)
    };
    let (section_len, data_at) = (u64_at(8), u64_at(16));
    // A scan of no points is read without a packet; libE57Format leaves its data offset 0.
    if pc.records == 0 {
        return Ok(());
    }
    let end = logical(start).saturating_add(section_len);
    if section_len < 32 || end > logical(len) {
        return Err(format!(
            "its binary section at byte {start} states a length of {section_len} bytes, which \
             {}",
            if section_len < 32 {
                "leaves no room for its own header"
            } else {
                "runs past the end of the file"
            }
        ));
    }
    // A section whose data starts where it ends holds no packet (the crate writes an empty
    // scan so); its fields then hold no values, refused below.
    let first = logical(data_at);
    if data_at % PAGE as u64 >= PAYLOAD || first < logical(start) + 32 || first > end {
        return Err(format!(
            "its binary section at byte {start} ({section_len} bytes) puts its first data \
             packet at byte {data_at}, outside the section"
        ));
    }
    let streams = pc.prototype.len();
    let mut stream_bytes = vec![0u64; streams];
    let mut at = first;
    // The first index or ignored packet: the crate steps over one by its whole length after
    // reading its header, landing inside the packet after, so none may come before a data
    // packet (writers put the index after the data).
    let mut skipped: Option<(u8, u64)> = None;
    while at < end {
        let here = physical(at);
        let packet = read_packet(file, at, end, streams, start, section_len)?;
        match (&packet.sizes, skipped) {
            (None, _) => skipped = skipped.or(Some((packet.kind, here))),
            (Some(_), Some((kind, there))) => {
                return Err(format!(
                    "its binary section holds {} packet at byte {there} before the data packet \
                     at byte {here}, which the e57 reader cannot step over (it reads on inside \
                     that packet): such a file must be rewritten without it first",
                    if kind == 0 { "an index" } else { "an ignored" }
                ));
            }
            (Some(sizes), None) => stream_bytes
                .iter_mut()
                .zip(sizes)
                .for_each(|(t, s)| *t += s),
        }
        at += packet.len;
        // The crate reads no packet past the one that completes the last point: a run of
        // packets after it (a file of 4-byte ignored packets) is not walked either, but the
        // data packets right after it are, to find points the scan does not count.
        if packet.sizes.is_some() && short_field(pc, &stream_bytes).is_none() {
            while let Ok(Packet {
                len,
                sizes: Some(sizes),
                ..
            }) = read_packet(file, at, end, streams, start, section_len)
            {
                stream_bytes
                    .iter_mut()
                    .zip(sizes)
                    .for_each(|(t, s)| *t += s);
                at += len;
            }
            return uncounted_field(pc, &stream_bytes).map_or(Ok(()), Err);
        }
    }
    match short_field(pc, &stream_bytes) {
        Some((r, held)) => Err(format!(
            "its {:?} field holds values for {held} of the {} points it states",
            r.name, pc.records
        )),
        None => Ok(()),
    }
}

/// A packet's header: its type (1 data, 0 index, 2 ignored), its length and, for a data
/// packet, the sizes of its byte streams.
struct Packet {
    kind: u8,
    len: u64,
    sizes: Option<Vec<u64>>,
}

/// The packet at logical offset `at` of the section at `start` that ends at `end`, of a scan
/// with `streams` fields; its fault, where its header does not fit its section or its streams.
fn read_packet<F: Read + Seek>(
    file: &mut F,
    at: u64,
    end: u64,
    streams: usize,
    start: u64,
    section_len: u64,
) -> Result<Packet, String> {
    let here = physical(at);
    let io = |e: std::io::Error| format!("cannot read byte {here} ({e})");
    if end - at < 4 {
        return Err(format!(
            "its binary section at byte {start} ends inside a packet header at byte {here}"
        ));
    }
    let mut word = [0u8; 4];
    read_logical(file, at, &mut word).map_err(io)?;
    let len = u64::from(u16::from_le_bytes([word[2], word[3]])) + 1;
    if at + len > end {
        return Err(format!(
            "its packet at byte {here} is {len} bytes long, past the end of its binary section \
             at byte {start} ({section_len} bytes)"
        ));
    }
    if word[0] != 1 {
        return Ok(Packet {
            kind: word[0],
            len,
            sizes: None,
        });
    }
    if len < 6 + 2 * streams as u64 {
        return Err(format!(
            "its data packet at byte {here} is {len} bytes long, too short for the sizes of its \
             {streams} byte streams"
        ));
    }
    let mut raw = vec![0u8; 2 + 2 * streams];
    read_logical(file, at + 4, &mut raw).map_err(io)?;
    let count = u16::from_le_bytes([raw[0], raw[1]]) as usize;
    if count != streams {
        return Err(format!(
            "its data packet at byte {here} holds {count} byte streams, but its points have \
             {streams} fields"
        ));
    }
    let sizes: Vec<u64> = raw[2..]
        .chunks_exact(2)
        .map(|b| u64::from(u16::from_le_bytes([b[0], b[1]])))
        .collect();
    let used = 6 + 2 * streams as u64 + sizes.iter().sum::<u64>();
    if used.next_multiple_of(4) != len {
        return Err(format!(
            "its data packet at byte {here} states a length of {len} bytes, but the byte streams \
             it lists take {used}"
        ));
    }
    Ok(Packet {
        kind: 1,
        len,
        sizes: Some(sizes),
    })
}

/// The fault of the first field whose stream holds values for more points than the scan
/// states, beyond the padding a writer leaves (libE57Format flushes a bit-packed integer stream
/// by its last register, of 8, 16, 32 or 64 bits as the field's width needs; the e57 crate by
/// its last byte; floats take none), or whose values take no bits but whose stream holds bytes
/// all the same.
fn uncounted_field(pc: &PointCloud, stream_bytes: &[u64]) -> Option<String> {
    pc.prototype
        .iter()
        .zip(stream_bytes)
        .find_map(|(r, &total)| {
            let bits = bits(&r.data_type);
            if bits == 0 {
                return (total > 0).then(|| {
                    format!(
                        "its {:?} field takes no bits (its minimum equals its maximum), yet its \
                         stream holds {total} bytes: the values in them would be ignored",
                        r.name
                    )
                });
            }
            let padding = match r.data_type {
                RecordDataType::Single { .. } | RecordDataType::Double { .. } => 0,
                _ => bits.next_power_of_two().max(8) - 1,
            };
            let extra = total
                .saturating_mul(8)
                .saturating_sub(pc.records.saturating_mul(bits));
            (extra > padding.max(bits - 1)).then(|| {
                format!(
                    "its {:?} field's stream holds the bits of {} values, but it states {} \
                     points: the points past that count would be dropped",
                    r.name,
                    total.saturating_mul(8) / bits,
                    pc.records
                )
            })
        })
}

/// The first field whose stream, of `stream_bytes` so far, holds values for fewer points than
/// the scan states, and for how many.
fn short_field<'a>(pc: &'a PointCloud, stream_bytes: &[u64]) -> Option<(&'a e57::Record, u64)> {
    pc.prototype
        .iter()
        .zip(stream_bytes)
        .find_map(|(r, total)| {
            let held = total.saturating_mul(8).checked_div(bits(&r.data_type))?;
            (held < pc.records).then_some((r, held))
        })
}
