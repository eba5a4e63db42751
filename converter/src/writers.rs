//! Writing rows (12 bytes of integer position, then attributes) out as LAS, LAZ or PLY.
//! Files are written under a temporary name and renamed when complete.

use crate::error::{ConvertError, Result};
use crate::input::las_layout::{
    ExtraBytesField, FieldOp, eb_code, las_fields, las_fields_ungrouped, row_to_record,
};
use crate::input::las_normals::{EXPORT_NORMAL_NAMES, is_normal_component};
use las::{PointDataBuilder, Transform, Vector, Vlr, Writer};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use strata_format::{AttrType, Attribute, RowLayout, row_position};

/// A sink for rows of one layout.
pub trait RowWriter {
    fn write_rows(&mut self, rows: &[u8]) -> Result<()>;
    /// Flushes and moves the file into place.
    fn finish(self: Box<Self>) -> Result<()>;
}

fn part_path(path: &Path) -> PathBuf {
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
    layout: RowLayout,
    /// For each LAS-order attribute: (dataset row offset, LAS row offset, len, widen u8->u16).
    gather: Vec<(Option<usize>, usize, usize, bool)>,
    ops: Vec<FieldOp>,
    las_row_len: usize,
    record_len: usize,
    buf: Vec<u8>,
}

impl LasRowWriter {
    fn create(path: &Path, layout: &RowLayout, scale: [f64; 3], offset: [f64; 3]) -> Result<Self> {
        refuse_encoded(path, layout)?;
        if let Some(a) = layout.attributes.iter().find(|a| a.ty == AttrType::F16) {
            return Err(ConvertError::output(
                path,
                format!(
                    "attribute \"{}\" is f16, which LAS cannot hold; widen it to f32 first",
                    a.name
                ),
            ));
        }
        let format_number = las_format_for(layout);
        let (standard, _, _) = las_fields(format_number, &[]);
        // A normal is split into three fields only where no attribute already has one of their
        // names: the file then reads back as it was written.
        let split = !layout
            .attributes
            .iter()
            .any(|a| is_normal_component(&a.name));
        let extra: Vec<ExtraBytesField> = layout
            .attributes
            .iter()
            .filter(|a| !standard.iter().any(|s| s.name == a.name))
            .flat_map(|a| extra_fields(a, split))
            .collect();
        let (las_attrs, ops, record_len) = if split {
            las_fields(format_number, &extra)
        } else {
            las_fields_ungrouped(format_number, &extra)
        };
        let mut gather = Vec::new();
        let mut at = 0;
        for a in &las_attrs {
            let src = layout.index_of(&a.name);
            let widen = src
                .is_some_and(|i| layout.attributes[i].ty == AttrType::U8 && a.ty == AttrType::U16);
            gather.push((src.map(|i| layout.offsets[i]), at, a.size(), widen));
            at += a.size();
        }
        let mut builder = las::Builder::from((1, 4));
        builder.point_format = las::point::Format::new(format_number).map_err(|e| {
            ConvertError::output(
                path,
                format!("cannot use point format {format_number} ({e})"),
            )
        })?;
        builder.point_format.extra_bytes = extra.iter().map(|e| e.len as u16).sum();
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
        if !extra.is_empty() {
            builder.vlrs.push(Vlr {
                user_id: "LASF_Spec".into(),
                record_id: 4,
                description: "Extra Bytes Record".into(),
                data: extra
                    .iter()
                    .flat_map(|e| eb_descriptor(&e.attribute))
                    .collect(),
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
            layout: layout.clone(),
            gather,
            ops,
            las_row_len: at,
            record_len,
            buf: Vec::new(),
        })
    }
}

/// Refuses attributes whose raw values are an encoding (`oct16`): written as they are, a reader
/// of the file could not know what they mean. Export decodes them first (`export::widened`).
fn refuse_encoded(path: &Path, layout: &RowLayout) -> Result<()> {
    match layout.attributes.iter().find(|a| a.encoding.is_some()) {
        Some(a) => Err(ConvertError::output(
            path,
            format!(
                "attribute \"{}\" is stored in the {} encoding, which the file cannot say; decode it first",
                a.name,
                a.encoding.as_deref().unwrap_or_default()
            ),
        )),
        None => Ok(()),
    }
}

/// The extra-bytes fields one attribute is written as. A normal of three floats becomes three
/// scalar fields named `NormalX NormalY NormalZ`: PDAL reads those names as its own normal
/// dimensions (a three-component field would reach it as `normal0 normal1 normal2`, and the
/// later revisions of LAS 1.4 deprecate such fields), laspy users find them by name, and
/// `las_fields` reads them back as one `normal`.
fn extra_fields(a: &Attribute, split_normal: bool) -> Vec<ExtraBytesField> {
    if split_normal
        && a.name == "normal"
        && a.count == 3
        && a.ty.is_float()
        && a.scale.is_none()
        && a.offset.is_none()
    {
        return EXPORT_NORMAL_NAMES
            .iter()
            .map(|n| ExtraBytesField {
                attribute: Attribute::new(n, a.ty, 1),
                len: a.ty.size(),
            })
            .collect();
    }
    vec![ExtraBytesField {
        attribute: a.clone(),
        len: a.size(),
    }]
}

/// One 192-byte Extra Bytes descriptor.
fn eb_descriptor(a: &Attribute) -> Vec<u8> {
    let mut d = vec![0u8; 192];
    let (code, options) = match a.count {
        1 => (eb_code(a.ty), 0u8),
        2 => (eb_code(a.ty) + 10, 0),
        3 => (eb_code(a.ty) + 20, 0),
        _ => (0, a.size() as u8),
    };
    d[2] = code;
    d[3] = options;
    let mut put = |off: usize, vals: &Option<Vec<f64>>, bit: u8| {
        if let Some(v) = vals {
            for (i, x) in v.iter().take(3).enumerate() {
                d[off + i * 8..off + i * 8 + 8].copy_from_slice(&x.to_le_bytes());
            }
            d[3] |= bit;
        }
    };
    put(112, &a.scale, 0x08);
    put(136, &a.offset, 0x10);
    let name = a.name.as_bytes();
    d[4..4 + name.len().min(32)].copy_from_slice(&name[..name.len().min(32)]);
    let desc = a.description.as_bytes();
    d[160..160 + desc.len().min(32)].copy_from_slice(&desc[..desc.len().min(32)]);
    d
}

impl RowWriter for LasRowWriter {
    fn write_rows(&mut self, rows: &[u8]) -> Result<()> {
        let stride = self.layout.stride;
        let n = rows.len() / stride;
        self.buf.clear();
        self.buf.resize(n * self.record_len, 0);
        let mut las_row = vec![0u8; self.las_row_len];
        for (row, rec) in rows
            .chunks_exact(stride)
            .zip(self.buf.chunks_exact_mut(self.record_len))
        {
            rec[..12].copy_from_slice(&row[..12]);
            las_row.fill(0);
            for &(src, dst, len, widen) in &self.gather {
                match (src, widen) {
                    (Some(s), false) => las_row[dst..dst + len].copy_from_slice(&row[s..s + len]),
                    (Some(s), true) => {
                        for c in 0..len / 2 {
                            las_row[dst + 2 * c..dst + 2 * c + 2]
                                .copy_from_slice(&(row[s + c] as u16).to_le_bytes());
                        }
                    }
                    (None, _) => {}
                }
            }
            row_to_record(&self.ops, &las_row, rec);
        }
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
