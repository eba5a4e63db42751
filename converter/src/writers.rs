//! Writing rows (12 bytes of integer position, then attributes) out as LAS, LAZ or PLY.
//! Files are written under a temporary name and renamed when complete.

use crate::error::{ConvertError, Result};
use crate::las_records::{LasRecords, refuse_encoded};
use las::{PointDataBuilder, Transform, Vector, Vlr, Writer};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use strata_format::{AttrType, RowLayout, row_position};

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

/// Opens a writer chosen by the extension of `path`. `points` is the exact number of rows
/// that will be written (PLY needs it up front).
pub fn open_writer(
    path: &Path,
    layout: &RowLayout,
    scale: [f64; 3],
    offset: [f64; 3],
    points: u64,
    overwrite: bool,
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
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "las" | "laz" => Ok(Box::new(LasRowWriter::create(path, layout, scale, offset)?)),
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
fn las_format_for(layout: &RowLayout) -> u8 {
    let has = |n: &str| layout.index_of(n).is_some();
    let rgb = layout
        .index_of("rgb")
        .is_some_and(|i| layout.attributes[i].count == 3 && layout.attributes[i].ty.size() <= 2);
    let wave = has("wave_packet_offset");
    if has("scan_angle") || has("scanner_channel") {
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
    writer: Writer<BufWriter<File>>,
    records: LasRecords,
    buf: Vec<u8>,
}

impl LasRowWriter {
    fn create(path: &Path, layout: &RowLayout, scale: [f64; 3], offset: [f64; 3]) -> Result<Self> {
        let format_number = las_format_for(layout);
        let records = LasRecords::new(path, layout, format_number)?;
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
        let writer = Writer::new(BufWriter::with_capacity(1 << 20, file), header)
            .map_err(|e| ConvertError::output(&part, format!("cannot create ({e})")))?;
        Ok(LasRowWriter {
            path: path.to_path_buf(),
            part,
            writer,
            records,
            buf: Vec::new(),
        })
    }
}

impl RowWriter for LasRowWriter {
    fn write_rows(&mut self, rows: &[u8]) -> Result<()> {
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
        std::fs::rename(&self.part, &self.path)
            .map_err(|e| ConvertError::io(&self.path, "cannot move into place", e))
    }
}

struct PlyRowWriter {
    path: PathBuf,
    part: PathBuf,
    out: BufWriter<File>,
    layout: RowLayout,
    scale: [f64; 3],
    offset: [f64; 3],
    /// 64-bit integer attributes are written as double (PLY has no 64-bit integers) and f16 as
    /// float (nor half floats).
    wide: Vec<bool>,
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
        for a in &layout.attributes {
            let names: Vec<String> = match (a.name.as_str(), a.count) {
                ("rgb", 3) => vec!["red".into(), "green".into(), "blue".into()],
                ("normal", 3) => vec!["nx".into(), "ny".into(), "nz".into()],
                (n, 1) => vec![n.to_string()],
                (n, c) => (0..c).map(|i| format!("{n}_{i}")).collect(),
            };
            for n in names {
                h.push_str(&format!("property {} {n}\n", ply_type(a.ty)));
            }
        }
        h.push_str("end_header\n");
        out.write_all(h.as_bytes())
            .map_err(|e| ConvertError::io(&part, "cannot write", e))?;
        Ok(PlyRowWriter {
            path: path.to_path_buf(),
            part,
            out,
            wide: layout
                .attributes
                .iter()
                .map(|a| matches!(a.ty, AttrType::U64 | AttrType::I64 | AttrType::F16))
                .collect(),
            layout: layout.clone(),
            scale,
            offset,
        })
    }
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
                if self.wide[i] && a.ty == AttrType::F16 {
                    for c in v.chunks_exact(2) {
                        rec.extend_from_slice(&(a.ty.read_f64(c) as f32).to_le_bytes());
                    }
                } else if self.wide[i] {
                    for c in v.chunks_exact(8) {
                        rec.extend_from_slice(&a.ty.read_f64(c).to_le_bytes());
                    }
                } else {
                    rec.extend_from_slice(v);
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
