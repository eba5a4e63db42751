use super::las_header::LasHeader;
use super::las_layout::{FieldOp, las_fields, parse_extra_bytes, record_to_row, rename_clashes};
use super::laz_check::{check_laz, guarded};
use super::laz_chunks::LazChunks;
use super::{PointSource, Precision, SourceInfo};
use crate::error::{ConvertError, Result};
use las::{PointData, PointDataBuilder, Reader};
use std::fs::File;
use std::io::BufReader;
use std::path::Path;
use strata_format::TimeBase;

/// LAS 1.0-1.4, point formats 0-10, plain or LAZ-compressed (decompressed in parallel).
pub struct LasSource {
    info: SourceInfo,
    reader: Reader,
    data: PointData,
    /// A LAZ file's chunks, decoded by us: the reader's decoder would not check them.
    laz: Option<LazChunks>,
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

impl LasSource {
    pub fn open(path: &Path) -> Result<LasSource> {
        let file = File::open(path).map_err(|e| ConvertError::io(path, "cannot open input", e))?;
        let file_len = file
            .metadata()
            .map_err(|e| ConvertError::io(path, "cannot read file size", e))?
            .len();
        let bad = |what: String| ConvertError::input(path, what);
        let raw = LasHeader::read(&file, file_len).map_err(bad)?;
        let laz = if raw.compressed {
            Some(check_laz(&file, &raw).map_err(bad)?)
        } else {
            raw.check_uncompressed_records().map_err(bad)?;
            None
        };
        let (records, record_notes) = raw.records(&file).map_err(bad)?;
        let (compressed, format_number) = (raw.compressed, raw.format);
        // Everything the reader allocates or seeks by has been checked above; what still panics
        // inside it (for a LAZ it builds the `laz` decoder too, which sizes a buffer by the
        // largest chunk, though `laz_chunks` decodes the points) is this file's fault, not ours.
        let reader = guarded("the point data", || {
            Reader::new(BufReader::with_capacity(1 << 20, file)).map_err(|e| {
                if compressed {
                    format!("LAZ point data is corrupt or truncated ({})", plain(&e))
                } else {
                    format!("invalid LAS header ({})", plain(&e))
                }
            })
        })
        .map_err(bad)?;
        let header = reader.header().clone();
        let format = *header.point_format();
        let record_len = format.len() as usize;
        let points = raw.points;
        if header.number_of_points() != points || record_len as u64 != raw.record_len {
            return Err(bad(format!(
                "the header's point count or record length cannot be read consistently ({points} points of {} bytes)",
                raw.record_len
            )));
        }
        let (scale, offset) = (raw.scale, raw.offset);
        // Writers may place the record among the extended VLRs after the points (LAS 1.4).
        let eb_vlr = records
            .iter()
            .find(|v| v.user_id == "LASF_Spec" && v.record_id == 4)
            .map(|v| v.data.as_slice());
        let mut extra = parse_extra_bytes(eb_vlr, format.extra_bytes as usize)
            .map_err(|e| ConvertError::input(path, e))?;
        let mut warnings: Vec<String> = rename_clashes(format_number, &mut extra)
            .into_iter()
            .chain(record_notes)
            .map(|w| format!("{}: {w}", path.display()))
            .collect();
        let (mut attributes, ops, std_len) = las_fields(format_number, &extra);
        warnings.extend(
            super::keep_scanner_name_free(&mut attributes)
                .map(|w| format!("{}: {w}", path.display())),
        );
        // GPS times count from one of two origins, said once for the file.
        let time_base = if header.gps_time_type().is_standard() {
            TimeBase::GpsAdjustedStandard
        } else {
            TimeBase::GpsWeek
        };
        for a in attributes.iter_mut().filter(|a| a.name == "gps_time") {
            a.time_base = Some(time_base);
        }
        // The waveforms themselves (descriptor VLRs, the data record or file) are not read.
        let waveforms = records.iter().any(|v| {
            v.user_id == "LASF_Spec" && ((100..355).contains(&v.record_id) || v.record_id == 65535)
        });
        if matches!(format_number, 4 | 5 | 9 | 10) && waveforms {
            warnings.push(format!(
                "{}: its waveform data is not kept (the points keep their wave packet fields, \
                 which then refer to waveforms the output does not hold)",
                path.display()
            ));
        }
        if std_len != record_len {
            return Err(ConvertError::input(
                path,
                format!(
                    "point records are {record_len} bytes but format {format_number} with its extra bytes needs {std_len}"
                ),
            ));
        }
        let (crs, crs_notes) = crate::las_crs::crs_of(records.iter(), header.has_wkt_crs());
        warnings.extend(crs_notes.iter().map(|n| format!("{}: {n}", path.display())));
        let data = PointDataBuilder::new().for_header(&header).build();
        let header_bounds = (raw.min, raw.max);
        Ok(LasSource {
            info: SourceInfo {
                path: path.to_path_buf(),
                points,
                attributes,
                precision: Precision::Scaled { scale, offset },
                warnings,
                scanners: Vec::new(),
                crs,
                time_from_unknown_start: false,
            },
            reader,
            data,
            laz,
            ops,
            record_len,
            scale,
            offset,
            remaining: points,
            read_so_far: 0,
            compressed: format.is_compressed,
            data_offset: raw.offset_to_points,
            header_bounds,
        })
    }
}

impl LasSource {
    /// Decodes up to `max` point records and returns their raw bytes (`record_len` each);
    /// empty at the end.
    pub fn read_records(&mut self, max: usize) -> Result<&[u8]> {
        let range = self.fill(max)?;
        Ok(&self.held()[range])
    }

    /// The records decoded so far and not handed on, among others (`fill` says which).
    fn held(&self) -> &[u8] {
        match &self.laz {
            Some(chunks) => chunks.records(),
            None => self.data.raw_bytes(),
        }
    }

    /// Decodes up to `max` point records; where their bytes lie in `held`.
    fn fill(&mut self, max: usize) -> Result<std::ops::Range<usize>> {
        let n = (max as u64).min(self.remaining);
        if n == 0 {
            return Ok(0..0);
        }
        if let Some(chunks) = &mut self.laz {
            let range = chunks
                .take(n)
                .map_err(|what| ConvertError::input(&self.info.path, what))?;
            if range.is_empty() {
                return Err(ConvertError::input(
                    &self.info.path,
                    format!(
                        "header says {} points but the data ends after {}",
                        self.info.points, self.read_so_far
                    ),
                ));
            }
            let got = (range.len() / self.record_len) as u64;
            self.remaining -= got;
            self.read_so_far += got;
            return Ok(range);
        }
        // The batch is read as a whole: the fault lies somewhere in it.
        let batch = format!(
            "points {} to {} (counting from 0)",
            self.read_so_far,
            self.read_so_far + n - 1
        );
        let (reader, data) = (&mut self.reader, &mut self.data);
        let got = guarded(&format!("LAS point data of {batch}"), || {
            reader.fill_points(n, data).map_err(|e| {
                format!(
                    "LAS point data is corrupt or truncated within {batch} ({})",
                    plain(&e)
                )
            })
        })
        .map_err(|what| ConvertError::input(&self.info.path, what))?;
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
        Ok(0..got as usize * self.record_len)
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

/// A dependency's error as plain words: its first line, without a repeated cause.
fn plain(e: &las::Error) -> String {
    let text = e.to_string();
    let first = text.lines().next().unwrap_or_default();
    // io errors wrapped twice read "X: X"; say it once.
    match first.split_once(": ") {
        Some((a, b)) if a == b => a.to_string(),
        _ => first.to_string(),
    }
}

impl PointSource for LasSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn read(&mut self, max: usize, xyz: &mut Vec<[f64; 3]>, rows: &mut Vec<u8>) -> Result<usize> {
        let range = self.fill(max)?;
        let raw = &self.held()[range];
        let row_len = self.info.row_len();
        let got = raw.len() / self.record_len;
        let base = rows.len();
        rows.resize(base + got * row_len, 0);
        xyz.reserve(got);
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
