//! The LAS public header block, its VLRs and EVLRs, read and checked against the file before
//! the `las` crate (or the `laz` decoder behind it) sees them: every size and count is checked
//! against the file's length so that nothing is allocated or sought on the header's word alone.

use std::fs::File;
use std::os::unix::fs::FileExt;
use strata_format::number;

/// The header fields the converter relies on, checked against each other and the file.
#[derive(Debug, Clone)]
pub struct LasHeader {
    pub minor: u8,
    pub header_size: u64,
    pub offset_to_points: u64,
    pub format: u8,
    pub compressed: bool,
    pub record_len: u64,
    pub points: u64,
    pub scale: [f64; 3],
    pub offset: [f64; 3],
    pub min: [f64; 3],
    pub max: [f64; 3],
    /// Where data after the point records starts (waveform packets or EVLRs), if any.
    pub after_points: Option<u64>,
    pub vlrs: Vec<Vlr>,
    pub file_len: u64,
}

/// One (extended) variable length record: its ids and where its payload lies in the file.
#[derive(Debug, Clone)]
pub struct Vlr {
    pub user_id: String,
    pub record_id: u16,
    pub data_at: u64,
    pub data_len: u64,
}

impl Vlr {
    pub fn is(&self, user_id: &str, record_id: u16) -> bool {
        self.user_id == user_id && self.record_id == record_id
    }
}

/// Bytes of a point record of each format without extra bytes.
pub const FORMAT_LEN: [u64; 11] = [20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67];

const AXES: [&str; 3] = ["x", "y", "z"];

fn u16_at(b: &[u8], o: usize) -> u64 {
    u16::from_le_bytes([b[o], b[o + 1]]) as u64
}
fn u32_at(b: &[u8], o: usize) -> u64 {
    u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]) as u64
}
fn u64_at(b: &[u8], o: usize) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[o..o + 8]);
    u64::from_le_bytes(a)
}
fn f64_at(b: &[u8], o: usize) -> f64 {
    f64::from_bits(u64_at(b, o))
}

/// Whether scaled integers from `lo` to `hi` all land on one value beside `offset` (a double
/// holds about 16 digits): every point of the field would get the same coordinate.
pub fn range_lost(offset: f64, scale: f64, lo: f64, hi: f64) -> bool {
    lo != hi && lo * scale + offset == hi * scale + offset
}

/// Reads `len` bytes at `at`, which the caller has checked lie inside the file.
pub fn read_at(file: &File, at: u64, len: usize) -> Result<Vec<u8>, String> {
    let mut b = vec![0u8; len];
    file.read_exact_at(&mut b, at)
        .map_err(|e| format!("cannot read {len} bytes at byte {at} ({})", e.kind()))?;
    Ok(b)
}

/// An ASCII id field (user id), NULs and control characters dropped.
fn id_text(b: &[u8]) -> String {
    let end = b.iter().position(|&c| c == 0).unwrap_or(b.len());
    String::from_utf8_lossy(&b[..end])
        .chars()
        .filter(|c| !c.is_control())
        .collect()
}

impl LasHeader {
    /// Reads and checks the header; the error is the fault, in words, without the file name.
    pub fn read(file: &File, file_len: u64) -> Result<LasHeader, String> {
        if file_len < 227 {
            return Err(format!(
                "the file is {file_len} bytes, too short to hold a LAS header (227 bytes)"
            ));
        }
        let head = read_at(file, 0, file_len.min(375) as usize)?;
        if &head[0..4] != b"LASF" {
            return Err("not a LAS or LAZ file (the first four bytes are not \"LASF\")".into());
        }
        let (major, minor) = (head[24], head[25]);
        if major != 1 || minor > 4 {
            return Err(format!(
                "header field \"version\": LAS version {major}.{minor} is not supported (1.0 to 1.4 are)"
            ));
        }
        let header_size = u16_at(&head, 94);
        let least = match minor {
            0..=2 => 227,
            3 => 235,
            _ => 375,
        };
        if header_size < least || header_size > file_len {
            return Err(format!(
                "header field \"header size\" is {header_size} bytes, but a LAS 1.{minor} header needs {least} and the file holds {file_len}"
            ));
        }
        let offset_to_points = u32_at(&head, 96);
        if offset_to_points < header_size || offset_to_points > file_len {
            return Err(format!(
                "header field \"offset to point data\" ({offset_to_points}) lies outside the file's {file_len} bytes after its {header_size}-byte header"
            ));
        }
        let format_byte = head[104];
        let format = format_byte & 0x3f;
        if format > 10 {
            // The byte as stored, with the format it names where its top bits (LAZ) are set.
            let named = if format == format_byte {
                String::new()
            } else {
                format!(" (byte {format_byte})")
            };
            return Err(format!(
                "header field \"point data format\": point format {format}{named} is not supported (0 to 10 are)"
            ));
        }
        let record_len = u16_at(&head, 105);
        if record_len < FORMAT_LEN[format as usize] {
            return Err(format!(
                "header field \"point record length\" is {record_len} bytes, shorter than the {} bytes of point format {format}",
                FORMAT_LEN[format as usize]
            ));
        }
        let legacy = u32_at(&head, 107);
        let points = if minor >= 4 {
            let extended = u64_at(&head, 247);
            // A legacy count of 0 is what 1.4 writers leave for formats 6-10 and for more than
            // 2^32 points; any other legacy count must be the same number.
            if extended != legacy && legacy != 0 {
                return Err(format!(
                    "header fields \"legacy number of point records\" ({legacy}) and \"number of point records\" ({extended}) disagree"
                ));
            }
            extended
        } else {
            legacy
        };
        let scale = [0, 1, 2].map(|a| f64_at(&head, 131 + 8 * a));
        let offset = [0, 1, 2].map(|a| f64_at(&head, 155 + 8 * a));
        for a in 0..3 {
            let (s, o) = (scale[a], offset[a]);
            if !s.is_normal() {
                return Err(format!(
                    "header field \"{} scale factor\" is {}, which cannot scale coordinates",
                    AXES[a],
                    number(s)
                ));
            }
            // Every record integer must give a finite coordinate.
            if o.is_finite() && !(s.abs() * 2f64.powi(31)).is_finite() {
                return Err(format!(
                    "header field \"{} scale factor\" is {}, which puts coordinates beyond any number that can be stored",
                    AXES[a],
                    number(s)
                ));
            }
            if !o.is_finite() || !(o.abs() + s.abs() * 2f64.powi(31)).is_finite() {
                return Err(format!(
                    "header field \"{} offset\" is {}, which puts coordinates beyond any number that can be stored",
                    AXES[a],
                    number(o)
                ));
            }
            // A double holds about 16 digits: beside an offset that large, the whole range of
            // the records is lost, and every point gets the same coordinate. (A coarser rule,
            // one step lost, would refuse the scale 1e-9 and offset 5e6 that a small far
            // float cloud's export writes, whose integers are kept exactly.)
            if range_lost(o, s, -(2f64.powi(31)), 2f64.powi(31)) {
                return Err(format!(
                    "header field \"{} offset\" is {}, so large that the steps of the scale factor {} are lost in it: every point would get the same coordinate",
                    AXES[a],
                    number(o),
                    number(s)
                ));
            }
        }
        let max = [0, 1, 2].map(|a| f64_at(&head, 179 + 16 * a));
        let min = [0, 1, 2].map(|a| f64_at(&head, 187 + 16 * a));
        let u64_field = |o: usize| (head.len() >= o + 8).then(|| u64_at(&head, o));
        let waveform = if minor >= 3 { u64_field(227) } else { None };
        let evlr_start = if minor >= 4 { u64_field(235) } else { None };
        let after_points = [waveform, evlr_start]
            .into_iter()
            .flatten()
            .filter(|s| *s > 0)
            .min();
        let mut header = LasHeader {
            minor,
            header_size,
            offset_to_points,
            format,
            compressed: format_byte & 0x80 != 0,
            record_len,
            points,
            scale,
            offset,
            min,
            max,
            after_points,
            vlrs: Vec::new(),
            file_len,
        };
        header.read_vlrs(file, u32_at(&head, 100))?;
        if let (Some(start), true) = (evlr_start.filter(|s| *s > 0), minor >= 4) {
            header.read_evlrs(file, start, u32_at(&head, 243))?;
        }
        Ok(header)
    }

    /// The VLRs between the header and the points; each must end before the points begin.
    fn read_vlrs(&mut self, file: &File, count: u64) -> Result<(), String> {
        let mut at = self.header_size;
        for i in 0..count {
            if at + 54 > self.offset_to_points {
                return Err(format!(
                    "header field \"number of VLRs\" says {count}, but VLR {} would start at byte {at}, past the start of the point data at byte {}",
                    i + 1,
                    self.offset_to_points
                ));
            }
            let h = read_at(file, at, 54)?;
            let len = u16_at(&h, 20);
            if at + 54 + len > self.offset_to_points {
                return Err(format!(
                    "VLR {} (at byte {at}) is {len} bytes long and runs past the start of the point data at byte {}",
                    i + 1,
                    self.offset_to_points
                ));
            }
            self.vlrs.push(Vlr {
                user_id: id_text(&h[2..18]),
                record_id: u16_at(&h, 18) as u16,
                data_at: at + 54,
                data_len: len,
            });
            at += 54 + len;
        }
        Ok(())
    }

    /// The extended VLRs after the points (LAS 1.4); each must lie inside the file.
    fn read_evlrs(&mut self, file: &File, start: u64, count: u64) -> Result<(), String> {
        let mut at = start;
        for i in 0..count {
            if at.checked_add(60).is_none_or(|end| end > self.file_len) {
                return Err(format!(
                    "header field \"number of EVLRs\" says {count}, but EVLR {} would start at byte {at}, past the end of the file ({} bytes)",
                    i + 1,
                    self.file_len
                ));
            }
            let h = read_at(file, at, 60)?;
            let len = u64_at(&h, 20);
            let end = (at + 60).checked_add(len);
            if end.is_none_or(|e| e > self.file_len) {
                return Err(format!(
                    "EVLR {} (at byte {at}) says it is {len} bytes long, past the end of the file ({} bytes)",
                    i + 1,
                    self.file_len
                ));
            }
            self.vlrs.push(Vlr {
                user_id: id_text(&h[2..18]),
                record_id: u16_at(&h, 18) as u16,
                data_at: at + 60,
                data_len: len,
            });
            at += 60 + len;
        }
        Ok(())
    }

    /// Every VLR and EVLR the header lists, with the payloads of those the converter reads
    /// (the extra bytes' descriptions, the coordinate reference system); others by their ids
    /// alone. The las crate keeps only the first EVLR: a file stating its extra bytes or its
    /// CRS in a later one (a COPC file's follow its hierarchy's) lost them. A CRS record
    /// larger than any is left out, said in the notes; an extra-bytes one is an error (the
    /// points cannot be read without it).
    pub fn records(&self, file: &File) -> Result<(Vec<las::Vlr>, Vec<String>), String> {
        const MOST: u64 = 16 << 20;
        let (mut out, mut notes) = (Vec::with_capacity(self.vlrs.len()), Vec::new());
        for v in &self.vlrs {
            let extra_bytes = v.is("LASF_Spec", 4);
            let crs = v.user_id == "LASF_Projection";
            let too_long = format!(
                "record {} of {:?} (at byte {}) is {} bytes long, more than any such record ({MOST} at most)",
                v.record_id, v.user_id, v.data_at, v.data_len
            );
            if (extra_bytes || crs) && v.data_len > MOST {
                if extra_bytes {
                    return Err(too_long);
                }
                notes.push(format!(
                    "{too_long}: its coordinate reference system is not read"
                ));
                continue;
            }
            let data = match extra_bytes || crs {
                true => read_at(file, v.data_at, v.data_len as usize)?,
                false => Vec::new(),
            };
            out.push(las::Vlr {
                user_id: v.user_id.clone(),
                record_id: v.record_id,
                description: String::new(),
                data,
            });
        }
        Ok((out, notes))
    }

    pub fn find(&self, user_id: &str, record_id: u16) -> Option<&Vlr> {
        self.vlrs.iter().find(|v| v.is(user_id, record_id))
    }

    /// Where the point data ends: at the data that follows it, or at the end of the file.
    pub fn points_end(&self) -> u64 {
        self.after_points
            .filter(|s| *s >= self.offset_to_points && *s <= self.file_len)
            .unwrap_or(self.file_len)
    }

    /// Uncompressed records: the file must hold exactly the records the header counts, up to
    /// the data that follows them.
    pub fn check_uncompressed_records(&self) -> Result<(), String> {
        let (points, len) = (self.points, self.record_len);
        let room = self.points_end() - self.offset_to_points;
        let present = room / len;
        let needed = points.saturating_mul(len);
        if needed > room {
            return Err(format!(
                "header says {points} points but the file holds only {present} complete records (truncated)"
            ));
        }
        if self.after_points.is_none() && present > points {
            return Err(format!(
                "header says {points} points but the file holds {present} records"
            ));
        }
        Ok(())
    }
}
