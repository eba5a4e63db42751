use super::las_layout::{FieldOp, las_fields, parse_extra_bytes, record_to_row};
use super::{PointSource, Precision, SourceInfo};
use crate::error::{ConvertError, Result};
use las::{PointData, PointDataBuilder, Reader};
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::Path;

/// LAS 1.0-1.4, point formats 0-10, plain or LAZ-compressed (decompressed in parallel).
pub struct LasSource {
    info: SourceInfo,
    reader: Reader,
    data: PointData,
    ops: Vec<FieldOp>,
    record_len: usize,
    scale: [f64; 3],
    offset: [f64; 3],
    remaining: u64,
    read_so_far: u64,
    compressed: bool,
    data_offset: u64,
    header_bounds: ([f64; 3], [f64; 3]),
}

const LAS_HEADER_MIN: u64 = 227;

impl LasSource {
    pub fn open(path: &Path) -> Result<LasSource> {
        let mut file =
            File::open(path).map_err(|e| ConvertError::io(path, "cannot open input", e))?;
        let file_len = file
            .metadata()
            .map_err(|e| ConvertError::io(path, "cannot read file size", e))?
            .len();
        let mut head = vec![0u8; file_len.min(375) as usize];
        if file_len < LAS_HEADER_MIN || file.read_exact(&mut head).is_err() {
            return Err(ConvertError::input(
                path,
                format!("file is {file_len} bytes, too short to hold a LAS header (227 bytes)"),
            ));
        }
        if &head[0..4] != b"LASF" {
            return Err(ConvertError::input(
                path,
                "not a LAS or LAZ file (the first four bytes are not \"LASF\")",
            ));
        }
        let (major, minor) = (head[24], head[25]);
        if major != 1 || minor > 4 {
            return Err(ConvertError::input(
                path,
                format!("LAS version {major}.{minor} is not supported (1.0 to 1.4 are)"),
            ));
        }
        let format_byte = head[104];
        // Bits 6-7 mark LAZ compression; the rest is the point format number.
        let format_number = format_byte & 0x3f;
        if format_number > 10 {
            return Err(ConvertError::input(
                path,
                format!("point format {format_number} is not supported (0 to 10 are)"),
            ));
        }
        let offset_to_points = u32::from_le_bytes([head[96], head[97], head[98], head[99]]) as u64;
        let file = File::open(path).map_err(|e| ConvertError::io(path, "cannot open input", e))?;
        // Opening a LAZ file also reads its chunk table at the end of the file.
        let compressed = format_byte & 0x80 != 0;
        let reader = Reader::new(BufReader::with_capacity(1 << 20, file)).map_err(|e| {
            let what = if compressed {
                format!("LAZ point data is corrupt or truncated ({e})")
            } else {
                format!("invalid LAS header ({e})")
            };
            ConvertError::input(path, what)
        })?;
        let header = reader.header().clone();
        let format = *header.point_format();
        let record_len = format.len() as usize;
        let points = header.number_of_points();
        let t = header.transforms();
        let scale = [t.x.scale, t.y.scale, t.z.scale];
        let offset = [t.x.offset, t.y.offset, t.z.offset];
        if scale.iter().chain(&offset).any(|v| !v.is_finite()) || scale.contains(&0.0) {
            return Err(ConvertError::input(
                path,
                format!("header has an unusable scale {scale:?} or offset {offset:?}"),
            ));
        }
        if !format.is_compressed {
            let data_end = offset_to_points + points * record_len as u64;
            let evlr_start =
                data_after_points(&head, minor).filter(|s| *s >= data_end.min(file_len));
            let records_end = evlr_start.unwrap_or(file_len).min(file_len);
            let present = records_end.saturating_sub(offset_to_points) / record_len as u64;
            if data_end > file_len {
                return Err(ConvertError::input(
                    path,
                    format!(
                        "header says {points} points but the file holds only {present} complete records (truncated)"
                    ),
                ));
            }
            if evlr_start.is_none() && present > points {
                return Err(ConvertError::input(
                    path,
                    format!("header says {points} points but the file holds {present} records"),
                ));
            }
        }
        let eb_vlr = header
            .vlrs()
            .iter()
            .find(|v| v.user_id == "LASF_Spec" && v.record_id == 4)
            .map(|v| v.data.as_slice());
        let extra = parse_extra_bytes(eb_vlr, format.extra_bytes as usize)
            .map_err(|e| ConvertError::input(path, e))?;
        let (attributes, ops, std_len) = las_fields(format_number, &extra);
        if std_len != record_len {
            return Err(ConvertError::input(
                path,
                format!(
                    "point records are {record_len} bytes but format {format_number} with its extra bytes needs {std_len}"
                ),
            ));
        }
        let data = PointDataBuilder::new().for_header(&header).build();
        let b = header.bounds();
        let header_bounds = ([b.min.x, b.min.y, b.min.z], [b.max.x, b.max.y, b.max.z]);
        Ok(LasSource {
            info: SourceInfo {
                path: path.to_path_buf(),
                points,
                attributes,
                precision: Precision::Scaled { scale, offset },
            },
            reader,
            data,
            ops,
            record_len,
            scale,
            offset,
            remaining: points,
            read_so_far: 0,
            compressed: format.is_compressed,
            data_offset: offset_to_points,
            header_bounds,
        })
    }
}

impl LasSource {
    /// Decodes up to `max` point records and returns their raw bytes (`record_len` each);
    /// empty at the end.
    pub fn read_records(&mut self, max: usize) -> Result<&[u8]> {
        let n = (max as u64).min(self.remaining);
        if n == 0 {
            return Ok(&[]);
        }
        let got = self.reader.fill_points(n, &mut self.data).map_err(|e| {
            let kind = if self.compressed { "LAZ" } else { "LAS" };
            ConvertError::input(
                &self.info.path,
                format!(
                    "{kind} point data is corrupt or truncated after point {} ({e})",
                    self.read_so_far
                ),
            )
        })?;
        if got == 0 {
            return Err(ConvertError::input(
                &self.info.path,
                format!(
                    "header says {} points but the data ends after {}",
                    self.info.points, self.read_so_far
                ),
            ));
        }
        self.remaining -= got;
        self.read_so_far += got;
        Ok(&self.data.raw_bytes()[..got as usize * self.record_len])
    }

    /// The field ops that turn a record into this source's attribute row.
    pub fn ops(&self) -> &[FieldOp] {
        &self.ops
    }

    pub fn record_len(&self) -> usize {
        self.record_len
    }

    /// Where uncompressed point records start in the file; `None` for LAZ.
    pub fn records_at(&self) -> Option<u64> {
        (!self.compressed).then_some(self.data_offset)
    }

    /// The bounds the header declares (real units), not checked against the points.
    pub fn header_bounds(&self) -> ([f64; 3], [f64; 3]) {
        self.header_bounds
    }

    /// Scale and offset of the records' integer positions.
    pub fn transform(&self) -> ([f64; 3], [f64; 3]) {
        (self.scale, self.offset)
    }
}

/// Where data that follows the point records starts: internal waveform packets (LAS 1.3+,
/// header byte 227) or extended VLRs (LAS 1.4, header byte 235). None if nothing follows.
fn data_after_points(head: &[u8], minor: u8) -> Option<u64> {
    let u64_at = |o: usize| {
        head.get(o..o + 8)
            .map(|b| u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]))
    };
    let waveform = if minor >= 3 { u64_at(227) } else { None };
    let evlr = if minor >= 4 { u64_at(235) } else { None };
    [waveform, evlr]
        .into_iter()
        .flatten()
        .filter(|s| *s > 0)
        .min()
}

impl PointSource for LasSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn read(&mut self, max: usize, xyz: &mut Vec<[f64; 3]>, rows: &mut Vec<u8>) -> Result<usize> {
        let got = self.read_records(max)?.len() / self.record_len;
        let row_len = self.info.row_len();
        let base = rows.len();
        rows.resize(base + got * row_len, 0);
        xyz.reserve(got);
        let raw = self.data.raw_bytes();
        for (rec, row) in raw
            .chunks_exact(self.record_len)
            .zip(rows[base..].chunks_exact_mut(row_len))
        {
            let i =
                |o: usize| i32::from_le_bytes([rec[o], rec[o + 1], rec[o + 2], rec[o + 3]]) as f64;
            xyz.push([
                self.offset[0] + self.scale[0] * i(0),
                self.offset[1] + self.scale[1] * i(4),
                self.offset[2] + self.scale[2] * i(8),
            ]);
            record_to_row(&self.ops, rec, row);
        }
        Ok(got)
    }
}
