//! Writing rows (12 bytes of integer position, then attributes) out as LAS, LAZ or PLY (the
//! PLY writer in `ply_writer.rs`). Files are written under a temporary name and renamed when
//! complete.

use crate::error::{ConvertError, Result};
use crate::las_records::{BIT_FIELDS, LasRecords};
use crate::part_file::create_part;
pub(crate) use crate::part_file::part_path;
use crate::ply_writer::PlyRowWriter;
use las::{PointDataBuilder, Transform, Vector, Vlr, Writer};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use strata_format::{Attribute, Crs, RowLayout, TimeBase, row_position};

/// A sink for rows of one layout.
pub trait RowWriter {
    fn write_rows(&mut self, rows: &[u8]) -> Result<()>;
    /// Flushes and moves the file into place.
    fn finish(self: Box<Self>) -> Result<()>;
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

/// Refuses an output file that exists (without `overwrite`) or that names a folder: found
/// before any point is written, not when the finished file is moved into place.
pub fn check_file_output(path: &Path, overwrite: bool) -> Result<()> {
    if path.exists() && !overwrite {
        return Err(ConvertError::output(
            path,
            "output already exists (pass --overwrite to replace it)",
        ));
    }
    if path.is_dir() {
        return Err(ConvertError::output(
            path,
            "is a folder; the output is a file",
        ));
    }
    // `exp/x.las/` (or `exp/x.las/.`) names a folder: no file can be moved there.
    let bytes = path.as_os_str().as_encoded_bytes();
    if bytes.ends_with(b"/") || bytes.ends_with(b"/.") {
        return Err(ConvertError::output(
            path,
            "ends with / or /., which names a folder; the output is a file",
        ));
    }
    Ok(())
}

/// What a LAS or LAZ output states, and what its points hold that their layout does not say.
#[derive(Debug, Clone, Copy, Default)]
pub struct LasChoices<'a> {
    /// The coordinate reference system the file states.
    pub crs: Option<&'a Crs>,
    /// A point holds a value of a bit field past what point formats 0 to 5 hold (a class
    /// above 31, a return number above 7): rows merged from a legacy LAS and a PLY have the
    /// legacy fields, and the PLY's values. Formats 6 to 10 are taken.
    pub extended: bool,
}

/// Opens a writer chosen by the extension of `path`. `points` is the exact number of rows
/// that will be written (PLY needs it up front); a LAS or LAZ file takes `las` too.
pub fn open_writer(
    path: &Path,
    layout: &RowLayout,
    scale: [f64; 3],
    offset: [f64; 3],
    points: u64,
    overwrite: bool,
    las: LasChoices<'_>,
) -> Result<Box<dyn RowWriter>> {
    // A COPC file is a LAZ file with an octree inside: only `export` of a dataset makes one.
    if crate::export::is_copc(path) {
        return Err(ConvertError::output(
            path,
            "this writes plain LAS or LAZ, not COPC (a COPC file is made from a converted \
             dataset by `strata export DATASET -o NAME.copc.laz`)",
        ));
    }
    // A COPC file is LAZ, and a ".copc.las" would be taken for one: refused, not written as
    // plain LAS under that name.
    if path
        .file_name()
        .and_then(|n| n.to_str())
        .is_some_and(|n| n.to_ascii_lowercase().ends_with(".copc.las"))
    {
        return Err(ConvertError::output(
            path,
            "a COPC file is compressed: name it NAME.copc.laz for COPC (from `strata export`), \
             or NAME.las for plain LAS",
        ));
    }
    check_file_output(path, overwrite)?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "las" | "laz" => Ok(Box::new(LasRowWriter::create(
            path, layout, scale, offset, las,
        )?)),
        "ply" => Ok(Box::new(PlyRowWriter::create(
            path, layout, scale, offset, points,
        )?)),
        _ => Err(ConvertError::output(
            path,
            "unknown output type (expected a .las, .laz or .ply file; `strata export` also \
             writes .copc.laz, and a Potree 2.0 folder with --format potree2)",
        )),
    }
}

/// The LAS point format that holds a layout's attributes best; `extended`: a point holds a
/// value only formats 6 to 10 hold (`LasChoices::extended`).
pub(crate) fn las_format_for(layout: &RowLayout, extended: bool) -> u8 {
    let has = |n: &str| layout.index_of(n).is_some();
    let rgb = layout
        .index_of("rgb")
        .is_some_and(|i| layout.attributes[i].count == 3 && layout.attributes[i].ty.size() <= 2);
    let wave = has("wave_packet_offset");
    // Formats 0 to 5 hold classes up to 31 and return numbers up to 7. Rows read from those
    // formats (the ones with a scan angle rank) fit them; a class or return number from
    // anywhere else (a PLY's uchar) may not, and goes to formats 6 to 10.
    let legacy_fits = !extended
        && (has("scan_angle_rank")
            || !BIT_FIELDS
                .iter()
                .any(|&(n, legacy, extended)| legacy < extended && has(n)));
    // Only formats 8 and 10 have a near-infrared field.
    if has("scan_angle") || has("scanner_channel") || has("nir") || !legacy_fits {
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
    /// `None` once closed (see `Drop`).
    writer: Option<Writer<Latched>>,
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
        las: LasChoices<'_>,
    ) -> Result<Self> {
        let format_number = las_format_for(layout, las.extended);
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
        builder.date = crate::creation_date::today_date();
        builder.system_identifier = "strata".into();
        if gps_time_adjusted(&layout.attributes) {
            builder.gps_time_type = las::GpsTimeType::Standard;
        }
        // The CRS where the dataset has one, one way (LAS 1.4 R15, 2.5: formats 0 to 5 state
        // it as GeoTIFF keys or WKT, not both; 6 to 10 as WKT). Where the dataset has both
        // (they name one system), the legacy formats take the keys, which their readers know,
        // and the others the WKT; keys alone go out as the inputs gave them, there being no
        // conversion here. The global encoding's WKT bit says which a reader takes.
        let stated = las
            .crs
            .map(|c| match (format_number < 6, &c.wkt, &c.geotiff) {
                (true, _, Some(keys)) => Crs {
                    wkt: None,
                    geotiff: Some(keys.clone()),
                },
                (false, Some(wkt), _) => Crs {
                    wkt: Some(wkt.clone()),
                    geotiff: None,
                },
                _ => c.clone(),
            });
        builder.has_wkt_crs = stated.as_ref().is_some_and(|c| c.wkt.is_some());
        for (user_id, record_id, description, data) in stated
            .as_ref()
            .map(crate::las_crs::crs_records)
            .unwrap_or_default()
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
        let (part, file) = create_part(path)?;
        let sink = Latched {
            inner: BufWriter::with_capacity(1 << 20, file),
            failed: false,
        };
        let writer = Writer::new(sink, header)
            .map_err(|e| ConvertError::output(&part, format!("cannot create ({e})")))?;
        Ok(LasRowWriter {
            path: path.to_path_buf(),
            part,
            writer: Some(writer),
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
        let Some(writer) = self.writer.as_mut() else {
            return Err(ConvertError::output(
                &self.part,
                "written after it was closed",
            ));
        };
        let data = PointDataBuilder::new()
            .for_header(writer.header())
            .build_from_bytes(std::mem::take(&mut self.buf))
            .map_err(|e| ConvertError::output(&self.part, format!("cannot encode points ({e})")))?;
        writer
            .write_points(&data)
            .map_err(|e| ConvertError::output(&self.part, format!("cannot write points ({e})")))?;
        Ok(())
    }

    fn finish(mut self: Box<Self>) -> Result<()> {
        close(self.writer.take()).map_err(|e| {
            ConvertError::output(&self.path, format!("cannot finish the LAS header ({e})"))
        })?;
        self.write_exact_bounds()?;
        std::fs::rename(&self.part, &self.path)
            .map_err(|e| ConvertError::io(&self.path, "cannot move into place", e))
    }
}

/// Closes `writer`. The `las` Writer closes itself again when dropped and panics when that
/// fails too (its header's bounds, floored to the grid, fall one step past 32 bits for a point
/// at the end of the range): one whose close failed is not dropped.
fn close(writer: Option<Writer<Latched>>) -> las::Result<()> {
    let Some(mut writer) = writer else {
        return Ok(());
    };
    let closed = writer.close();
    if closed.is_err() {
        std::mem::forget(writer);
    }
    closed
}

impl Drop for LasRowWriter {
    /// A writer given up on (an error while writing) closes without a panic.
    fn drop(&mut self) {
        let _ = close(self.writer.take());
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
