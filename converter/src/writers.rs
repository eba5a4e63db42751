//! Writing rows (12 bytes of integer position, then attributes) out as LAS, LAZ or PLY.
//! Files are written under a temporary name and renamed when complete.

use crate::error::{ConvertError, Result};
use crate::las_records::{BIT_FIELDS, LasRecords, refuse_encoded};
use las::{PointDataBuilder, Transform, Vector, Vlr, Writer};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use strata_format::{AttrType, Attribute, Crs, RowLayout, TimeBase, row_position};

/// A sink for rows of one layout.
pub trait RowWriter {
    fn write_rows(&mut self, rows: &[u8]) -> Result<()>;
    /// Flushes and moves the file into place.
    fn finish(self: Box<Self>) -> Result<()>;
}

/// Where an output is written before it is renamed into place: `NAME.part` beside it.
pub(crate) fn part_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".part");
    path.with_file_name(name)
}

/// The LAS writer's file, which after its first failure (a full disk) takes every further
/// write and seek without doing it: the `las` crate closes a writer again when it is dropped
/// and panics if that fails, and a writer whose close failed is dropped on the error path.
/// The first failure is the one reported; the file is removed.
struct Latched {
    inner: BufWriter<File>,
    failed: bool,
}

impl Latched {
    /// Passes `r` on, remembering a failure (an interruption is retried, not a failure).
    fn latch<T>(&mut self, r: std::io::Result<T>) -> std::io::Result<T> {
        self.failed = r
            .as_ref()
            .is_err_and(|e| e.kind() != std::io::ErrorKind::Interrupted);
        r
    }
}

impl Write for Latched {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if self.failed {
            return Ok(buf.len());
        }
        let r = self.inner.write(buf);
        self.latch(r)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        if self.failed {
            return Ok(());
        }
        let r = self.inner.flush();
        self.latch(r)
    }
}

impl std::io::Seek for Latched {
    fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
        if self.failed {
            return Ok(0);
        }
        let r = self.inner.seek(pos);
        self.latch(r)
    }
}

/// Opens a writer chosen by the extension of `path`. `points` is the exact number of rows
/// that will be written (PLY needs it up front); the file states `crs` where its format can
/// (LAS and LAZ).
pub fn open_writer(
    path: &Path,
    layout: &RowLayout,
    scale: [f64; 3],
    offset: [f64; 3],
    points: u64,
    overwrite: bool,
    crs: Option<&Crs>,
) -> Result<Box<dyn RowWriter>> {
    // A COPC file is a LAZ file with an octree inside: only `export` of a dataset makes one.
    if crate::export::is_copc(path) {
        return Err(ConvertError::output(
            path,
            "this writes plain LAS or LAZ, not COPC (a COPC file is made from a converted \
             dataset by `strata export DATASET -o NAME.copc.laz`)",
        ));
    }
    if path.exists() && !overwrite {
        return Err(ConvertError::output(
            path,
            "output already exists (pass --overwrite to replace it)",
        ));
    }
    // Found before any point is written, not when the finished file is moved into place.
    if path.is_dir() {
        return Err(ConvertError::output(
            path,
            "is a folder; the output is a file",
        ));
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "las" | "laz" => Ok(Box::new(LasRowWriter::create(
            path, layout, scale, offset, crs,
        )?)),
        "ply" => Ok(Box::new(PlyRowWriter::create(
            path, layout, scale, offset, points,
        )?)),
        _ => Err(ConvertError::output(
            path,
            "unknown output type (expected a .las, .laz or .ply file)",
        )),
    }
}

/// The LAS point format that holds a layout's attributes best.
pub(crate) fn las_format_for(layout: &RowLayout) -> u8 {
    let has = |n: &str| layout.index_of(n).is_some();
    let rgb = layout
        .index_of("rgb")
        .is_some_and(|i| layout.attributes[i].count == 3 && layout.attributes[i].ty.size() <= 2);
    let wave = has("wave_packet_offset");
    // Formats 0 to 5 hold classes up to 31 and return numbers up to 7. Rows read from those
    // formats (the ones with a scan angle rank) fit them; a class or return number from
    // anywhere else (a PLY's uchar) may not, and goes to formats 6 to 10.
    let legacy_fits = has("scan_angle_rank")
        || !BIT_FIELDS
            .iter()
            .any(|&(n, legacy, extended)| legacy < extended && has(n));
    if has("scan_angle") || has("scanner_channel") || !legacy_fits {
        match (wave, has("nir"), rgb) {
            (true, true, _) => 10,
            (true, false, _) => 9,
            (false, true, _) => 8,
            (false, false, true) => 7,
            _ => 6,
        }
    } else {
        match (wave, rgb, has("gps_time")) {
            (true, true, _) => 5,
            (true, false, _) => 4,
            (false, true, true) => 3,
            (false, true, false) => 2,
            (false, false, true) => 1,
            _ => 0,
        }
    }
}

struct LasRowWriter {
    path: PathBuf,
    part: PathBuf,
    writer: Writer<Latched>,
    records: LasRecords,
    buf: Vec<u8>,
    stride: usize,
    /// The integer bounds of the positions written, for the header (see `finish`).
    min: [i32; 3],
    max: [i32; 3],
    scale: [f64; 3],
    offset: [f64; 3],
    /// Point formats 6 to 10, which keep no legacy compatibility: the legacy counts are 0.
    extended: bool,
}

/// Whether `attributes`' `gps_time` is adjusted standard GPS time (LAS global encoding bit 0).
pub(crate) fn gps_time_adjusted(attributes: &[Attribute]) -> bool {
    attributes
        .iter()
        .any(|a| a.name == "gps_time" && a.time_base == Some(TimeBase::GpsAdjustedStandard))
}

impl LasRowWriter {
    fn create(
        path: &Path,
        layout: &RowLayout,
        scale: [f64; 3],
        offset: [f64; 3],
        crs: Option<&Crs>,
    ) -> Result<Self> {
        let format_number = las_format_for(layout);
        let mut records = LasRecords::new(path, layout, format_number)?;
        if format_number >= 6 {
            records = records.single_returns_where_missing();
        }

        let mut builder = las::Builder::from((1, 4));
        builder.point_format = las::point::Format::new(format_number).map_err(|e| {
            ConvertError::output(
                path,
                format!("cannot use point format {format_number} ({e})"),
            )
        })?;
        builder.point_format.extra_bytes = records.extra_bytes() as u16;
        builder.transforms = Vector {
            x: Transform {
                scale: scale[0],
                offset: offset[0],
            },
            y: Transform {
                scale: scale[1],
                offset: offset[1],
            },
            z: Transform {
                scale: scale[2],
                offset: offset[2],
            },
        };
        builder.generating_software = format!("strata {}", env!("CARGO_PKG_VERSION"));
        if gps_time_adjusted(&layout.attributes) {
            builder.gps_time_type = las::GpsTimeType::Standard;
        }
        // The CRS where the dataset has one (the point formats 6 to 10 call for WKT; GeoTIFF
        // keys go out as the inputs gave them, there being no conversion here). The global
        // encoding's WKT bit says which a reader takes: the WKT where there is one.
        builder.has_wkt_crs = crs.is_some_and(|c| c.wkt.is_some());
        for (user_id, record_id, description, data) in
            crs.map(crate::las_crs::crs_records).unwrap_or_default()
        {
            builder.vlrs.push(Vlr {
                user_id: user_id.into(),
                record_id,
                description: description.into(),
                data,
            });
        }
        if let Some(data) = records.extra_bytes_vlr() {
            builder.vlrs.push(Vlr {
                user_id: "LASF_Spec".into(),
                record_id: 4,
                description: "Extra Bytes Record".into(),
                data,
            });
        }
        // Compression follows the final name; the file is written under a ".part" name.
        builder.point_format.is_compressed = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("laz"));
        let header = builder
            .into_header()
            .map_err(|e| ConvertError::output(path, format!("cannot build LAS header ({e})")))?;
        let part = part_path(path);
        let file = File::create(&part).map_err(|e| ConvertError::io(&part, "cannot create", e))?;
        let sink = Latched {
            inner: BufWriter::with_capacity(1 << 20, file),
            failed: false,
        };
        let writer = Writer::new(sink, header)
            .map_err(|e| ConvertError::output(&part, format!("cannot create ({e})")))?;
        Ok(LasRowWriter {
            path: path.to_path_buf(),
            part,
            writer,
            records,
            buf: Vec::new(),
            stride: layout.stride,
            min: [i32::MAX; 3],
            max: [i32::MIN; 3],
            scale,
            offset,
            extended: format_number >= 6,
        })
    }
}

impl RowWriter for LasRowWriter {
    fn write_rows(&mut self, rows: &[u8]) -> Result<()> {
        self.records.check_fits(&self.path, rows)?;
        for row in rows.chunks_exact(self.stride) {
            for (a, v) in row_position(row).into_iter().enumerate() {
                self.min[a] = self.min[a].min(v);
                self.max[a] = self.max[a].max(v);
            }
        }
        self.records.fill(rows, &mut self.buf);
        let data = PointDataBuilder::new()
            .for_header(self.writer.header())
            .build_from_bytes(std::mem::take(&mut self.buf))
            .map_err(|e| ConvertError::output(&self.part, format!("cannot encode points ({e})")))?;
        self.writer
            .write_points(&data)
            .map_err(|e| ConvertError::output(&self.part, format!("cannot write points ({e})")))?;
        Ok(())
    }

    fn finish(mut self: Box<Self>) -> Result<()> {
        self.writer
            .close()
            .map_err(|e| ConvertError::output(&self.part, format!("cannot finish ({e})")))?;
        self.write_exact_bounds()?;
        std::fs::rename(&self.part, &self.path)
            .map_err(|e| ConvertError::io(&self.path, "cannot move into place", e))
    }
}

impl LasRowWriter {
    /// Writes the header's bounds from the integer bounds of the points. The `las` crate
    /// widens its own to the grid with a floor and a ceiling of values that carry rounding
    /// (98.99999999999994 steps becomes 98), a step beyond the points.
    fn write_exact_bounds(&self) -> Result<()> {
        use std::io::{Seek, SeekFrom};
        // No points: zero bounds (the `las` crate leaves infinities, which readers refuse).
        let empty = self.min[0] > self.max[0];
        let real = |a: usize, v: i32| {
            if empty {
                0.0
            } else {
                self.offset[a] + self.scale[a] * f64::from(v)
            }
        };
        // Max X, min X, max Y, min Y, max Z, min Z from byte 179 of every LAS header version.
        let mut bytes = Vec::with_capacity(48);
        for a in 0..3 {
            bytes.extend_from_slice(&real(a, self.max[a]).to_le_bytes());
            bytes.extend_from_slice(&real(a, self.min[a]).to_le_bytes());
        }
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .open(&self.part)
            .map_err(|e| ConvertError::io(&self.part, "cannot reopen", e))?;
        file.seek(SeekFrom::Start(179))
            .and_then(|_| file.write_all(&bytes))
            .map_err(|e| ConvertError::io(&self.part, "cannot write the header's bounds in", e))?;
        // LAS 1.4: the legacy point count and counts by return (bytes 107 to 130) are 0 where
        // the point format is 6 or higher, as COPC's writer, PDAL and laspy leave them; the
        // `las` crate fills them in.
        if self.extended {
            file.seek(SeekFrom::Start(107))
                .and_then(|_| file.write_all(&[0u8; 24]))
                .map_err(|e| {
                    ConvertError::io(&self.part, "cannot write the header's counts in", e)
                })?;
        }
        Ok(())
    }
}

struct PlyRowWriter {
    path: PathBuf,
    part: PathBuf,
    out: BufWriter<File>,
    layout: RowLayout,
    scale: [f64; 3],
    offset: [f64; 3],
    /// How each attribute's values are written.
    written_as: Vec<PlyValue>,
}

/// How an attribute's stored values become a PLY property's.
#[derive(Debug, Clone, Copy, PartialEq)]
enum PlyValue {
    /// The stored bytes.
    Stored,
    /// f16 as float (PLY has no half floats).
    Float,
    /// 64-bit integers as double (PLY has no 64-bit integers).
    Double,
    /// A LAS extra attribute with a scale or offset, as the double it stands for: PLY has no
    /// place for the scale, and a reader would take the raw integer for the value.
    Scaled,
}

impl PlyValue {
    fn of(a: &strata_format::Attribute) -> PlyValue {
        match a.ty {
            _ if a.scale.is_some() || a.offset.is_some() => PlyValue::Scaled,
            AttrType::F16 => PlyValue::Float,
            AttrType::U64 | AttrType::I64 => PlyValue::Double,
            _ => PlyValue::Stored,
        }
    }
}

fn ply_type(t: AttrType) -> &'static str {
    match t {
        AttrType::I8 => "char",
        AttrType::U8 => "uchar",
        AttrType::I16 => "short",
        AttrType::U16 => "ushort",
        AttrType::I32 => "int",
        AttrType::U32 => "uint",
        AttrType::F32 | AttrType::F16 => "float",
        AttrType::F64 | AttrType::U64 | AttrType::I64 => "double",
    }
}

impl PlyRowWriter {
    fn create(
        path: &Path,
        layout: &RowLayout,
        scale: [f64; 3],
        offset: [f64; 3],
        points: u64,
    ) -> Result<Self> {
        refuse_encoded(path, layout)?;
        let part = part_path(path);
        let file = File::create(&part).map_err(|e| ConvertError::io(&part, "cannot create", e))?;
        let mut out = BufWriter::with_capacity(1 << 20, file);
        let mut h = format!(
            "ply\nformat binary_little_endian 1.0\ncomment written by strata {}\nelement vertex {points}\nproperty double x\nproperty double y\nproperty double z\n",
            env!("CARGO_PKG_VERSION")
        );
        for (a, names) in layout.attributes.iter().zip(ply_property_names(layout)) {
            let ty = match PlyValue::of(a) {
                PlyValue::Scaled => "double",
                _ => ply_type(a.ty),
            };
            for n in names {
                h.push_str(&format!("property {ty} {n}\n"));
            }
        }
        h.push_str("end_header\n");
        out.write_all(h.as_bytes())
            .map_err(|e| ConvertError::io(&part, "cannot write", e))?;
        Ok(PlyRowWriter {
            path: path.to_path_buf(),
            part,
            out,
            written_as: layout.attributes.iter().map(PlyValue::of).collect(),
            layout: layout.clone(),
            scale,
            offset,
        })
    }
}

/// Each attribute's PLY property names: a colour as `red green blue`, a normal as `nx ny nz`,
/// other vectors as `NAME_0`, `NAME_1`, …. A name already taken (a scalar `red` beside a
/// colour, a LAS extra attribute named `green`) gets a number, as a PLY reader refuses a
/// property declared twice; white space, which would end the name in the header, becomes `_`.
fn ply_property_names(layout: &RowLayout) -> Vec<Vec<String>> {
    let mut taken: std::collections::HashSet<String> =
        ["x", "y", "z"].iter().map(|n| n.to_string()).collect();
    let mut unique = |n: String| {
        let n: String = n
            .chars()
            .map(|c| if c.is_whitespace() { '_' } else { c })
            .collect();
        let n = if n.is_empty() {
            "attribute".to_string()
        } else {
            n
        };
        let mut name = n.clone();
        let mut i = 1;
        while taken.contains(&name) {
            name = format!("{n}_{i}");
            i += 1;
        }
        taken.insert(name.clone());
        name
    };
    let group = |a: &strata_format::Attribute| -> Option<[&str; 3]> {
        match (a.name.as_str(), a.count) {
            ("rgb", 3) => Some(["red", "green", "blue"]),
            ("normal", 3) => Some(["nx", "ny", "nz"]),
            _ => None,
        }
    };
    // A colour and a normal keep the names readers group them by.
    let grouped: Vec<Option<Vec<String>>> = layout
        .attributes
        .iter()
        .map(|a| group(a).map(|g| g.iter().map(|n| unique(n.to_string())).collect()))
        .collect();
    layout
        .attributes
        .iter()
        .zip(grouped)
        .map(|(a, grouped)| {
            grouped.unwrap_or_else(|| match a.count {
                1 => vec![unique(a.name.clone())],
                c => (0..c).map(|i| unique(format!("{}_{i}", a.name))).collect(),
            })
        })
        .collect()
}

impl RowWriter for PlyRowWriter {
    fn write_rows(&mut self, rows: &[u8]) -> Result<()> {
        let mut rec = Vec::with_capacity(self.layout.stride + 24);
        for row in rows.chunks_exact(self.layout.stride) {
            rec.clear();
            let p = row_position(row);
            for ((o, s), v) in self.offset.iter().zip(&self.scale).zip(p) {
                rec.extend_from_slice(&(o + s * v as f64).to_le_bytes());
            }
            for (i, a) in self.layout.attributes.iter().enumerate() {
                let v = &row[self.layout.offsets[i]..self.layout.offsets[i] + a.size()];
                let values = v.chunks_exact(a.ty.size());
                match self.written_as[i] {
                    PlyValue::Stored => rec.extend_from_slice(v),
                    PlyValue::Float => {
                        for c in values {
                            rec.extend_from_slice(&(a.ty.read_f64(c) as f32).to_le_bytes());
                        }
                    }
                    PlyValue::Double => {
                        for c in values {
                            let d = a.ty.read_f64(c);
                            // Compared in i128, which holds both types and the double's
                            // rounding past them (u64::MAX becomes 2^64) without saturating.
                            let exact = a.ty.read_wide_integer(c);
                            if let Some(v) = exact.filter(|&v| d as i128 != v) {
                                return Err(ConvertError::output(
                                    &self.path,
                                    format!(
                                        "attribute \"{}\" holds {}, which no PLY property \
                                         holds exactly (PLY has no 64-bit integers, and a \
                                         double keeps 53 bits); export to .las or .laz, whose \
                                         extra bytes keep it",
                                        a.name, v
                                    ),
                                ));
                            }
                            rec.extend_from_slice(&d.to_le_bytes());
                        }
                    }
                    PlyValue::Scaled => {
                        // LAS 1.4: value = raw · scale + offset, each per component.
                        for (c, raw) in values.enumerate() {
                            let (scale, offset) = a.scaling(c);
                            let value = a.ty.read_f64(raw) * scale + offset;
                            rec.extend_from_slice(&value.to_le_bytes());
                        }
                    }
                }
            }
            self.out
                .write_all(&rec)
                .map_err(|e| ConvertError::io(&self.part, "cannot write", e))?;
        }
        Ok(())
    }

    fn finish(mut self: Box<Self>) -> Result<()> {
        self.out
            .flush()
            .map_err(|e| ConvertError::io(&self.part, "cannot write", e))?;
        std::fs::rename(&self.part, &self.path)
            .map_err(|e| ConvertError::io(&self.path, "cannot move into place", e))
    }
}

/// Writes with `write`, then finishes: the writer works under a temporary name, removed on
/// any failure, so that nothing that looks like a finished file (an export, a scene) stays.
pub(crate) fn write_then_finish(
    mut writer: Box<dyn RowWriter>,
    output: &Path,
    write: impl FnOnce(&mut dyn RowWriter) -> Result<u64>,
) -> Result<u64> {
    let result = match write(writer.as_mut()) {
        Ok(written) => writer.finish().map(|()| written),
        Err(e) => {
            drop(writer);
            Err(e)
        }
    };
    if result.is_err() {
        let _ = std::fs::remove_file(part_path(output));
    }
    result
}
