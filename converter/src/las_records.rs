//! A dataset's rows as the records of a LAS point format: which LAS field each attribute
//! fills, the attributes that become extra bytes, and the conversions between point format
//! families (a legacy `scan_angle_rank` in degrees becomes the `scan_angle` of formats 6 to 10
//! in steps of 0.006°). Shared by the LAS/LAZ writer and the COPC export.

use crate::error::{ConvertError, Result, shown};
use crate::input::las_layout::{
    ExtraBytesField, FieldOp, UNDESCRIBED, eb_code, las_fields, las_fields_ungrouped, row_to_record,
};
use crate::input::las_normals::{EXPORT_NORMAL_NAMES, is_normal_component};
use std::path::Path;
use strata_format::{AttrType, Attribute, RowLayout};

/// How one LAS field is filled from a dataset row.
#[derive(Debug, Clone, Copy)]
enum Source {
    /// Copied (the row's offset).
    Copy(usize),
    /// A u8 widened to u16, per component.
    Widen(usize),
    /// A legacy scan angle rank (i8 degrees) as a scan angle (i16, 0.006°).
    RankToAngle { at: usize, ty: AttrType },
    /// Another type than the field's (an f32 intensity from a PLY): each component converted
    /// (a value beyond the field's range, or a fraction in an integer field, is refused by
    /// `check_fits`, so nothing is rounded).
    Cast {
        at: usize,
        from: AttrType,
        to: AttrType,
        count: usize,
    },
    /// Not in the dataset: zero.
    Zero,
    /// Not in the dataset: one (a single return).
    One,
}

/// A row value that must lie within `min..=max` to fit its LAS field.
#[derive(Debug, Clone)]
struct Limit {
    /// Where the value is in the row, and its type there.
    at: usize,
    ty: AttrType,
    name: String,
    min: f64,
    max: f64,
    /// Why the bound: the point format's bit field, or the field's type.
    bits: bool,
    /// Whether the value must be a whole number: a float going into an integer field, where a
    /// fraction would otherwise be rounded away without a word.
    whole: bool,
}

/// The fields LAS holds in fewer than 8 bits: name, and the largest value formats 0 to 5 and
/// formats 6 to 10 hold (255: a whole byte, or not a field of the family).
pub const BIT_FIELDS: [(&str, u8, u8); 7] = [
    ("classification", 31, 255),
    ("return_number", 7, 15),
    ("number_of_returns", 7, 15),
    ("classification_flags", 7, 15),
    ("scan_direction_flag", 1, 1),
    ("edge_of_flight_line", 1, 1),
    ("scanner_channel", 255, 3),
];

/// The bit fields formats 6 to 10 hold more of than formats 0 to 5, with the largest value
/// formats 0 to 5 hold.
pub fn legacy_limited() -> impl Iterator<Item = (&'static str, u8)> {
    BIT_FIELDS
        .iter()
        .filter(|&&(_, legacy, extended)| legacy < extended)
        .map(|&(name, legacy, _)| (name, legacy))
}

pub struct LasRecords {
    stride: usize,
    format_number: u8,
    /// The values the format's fields hold, so that one it cannot hold is refused rather than
    /// cut or clamped.
    limits: Vec<Limit>,
    /// Per LAS-order attribute: where it comes from, its offset and size in the LAS row.
    gather: Vec<(Source, usize, usize)>,
    ops: Vec<FieldOp>,
    las_row_len: usize,
    pub record_len: usize,
    extra: Vec<ExtraBytesField>,
    /// The name of each LAS-order attribute, beside `gather`.
    names: Vec<String>,
}

impl LasRecords {
    /// The records of point format `format_number` for rows of `layout`; `path` names the
    /// output in errors.
    pub fn new(path: &Path, layout: &RowLayout, format_number: u8) -> Result<LasRecords> {
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
        let (standard, _, _) = las_fields(format_number, &[]);
        let has = |n: &str| standard.iter().any(|s| s.name == n);
        // The legacy rank fills the extended angle where the format has only that.
        let rank_as_angle = has("scan_angle")
            && layout.index_of("scan_angle").is_none()
            && layout.index_of("scan_angle_rank").is_some();
        // A normal is split into three fields only where no attribute already has one of their
        // names: the file then reads back as it was written.
        let split = !layout
            .attributes
            .iter()
            .any(|a| is_normal_component(&a.name));
        let extra: Vec<ExtraBytesField> = layout
            .attributes
            .iter()
            .filter(|a| {
                let converted = rank_as_angle && a.name == "scan_angle_rank";
                !has(&a.name) && !converted
            })
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
            let source = match src {
                Some(i)
                    if layout.attributes[i].ty == AttrType::U8
                        && a.ty == AttrType::U16
                        && layout.attributes[i].count == a.count =>
                {
                    Source::Widen(layout.offsets[i])
                }
                Some(i)
                    if layout.attributes[i].ty != a.ty || layout.attributes[i].count != a.count =>
                {
                    Source::Cast {
                        at: layout.offsets[i],
                        from: layout.attributes[i].ty,
                        to: a.ty,
                        count: (a.count as usize).min(layout.attributes[i].count as usize),
                    }
                }
                Some(i) => Source::Copy(layout.offsets[i]),
                None if rank_as_angle && a.name == "scan_angle" => layout
                    .index_of("scan_angle_rank")
                    .map_or(Source::Zero, |i| Source::RankToAngle {
                        at: layout.offsets[i],
                        ty: layout.attributes[i].ty,
                    }),
                None => Source::Zero,
            };
            gather.push((source, at, a.size()));
            at += a.size();
        }
        if record_len > u16::MAX as usize {
            return Err(ConvertError::output(
                path,
                format!(
                    "a point's record would take {record_len} bytes, more than LAS's 65,535: too many extra attributes"
                ),
            ));
        }
        let names: Vec<String> = las_attrs.iter().map(|a| a.name.clone()).collect();
        let mut limits: Vec<Limit> = BIT_FIELDS
            .iter()
            .filter_map(|&(name, legacy, extended)| {
                let max = if format_number < 6 { legacy } else { extended };
                let i = layout.index_of(name)?;
                let a = &layout.attributes[i];
                (max < u8::MAX && a.count == 1).then(|| Limit {
                    at: layout.offsets[i],
                    ty: a.ty,
                    name: name.to_string(),
                    min: 0.0,
                    max: f64::from(max),
                    bits: true,
                    whole: a.ty.is_float(),
                })
            })
            .collect();
        // Formats 6 to 10 hold a scan angle from -180° to 180° in steps of 0.006°: a value
        // beyond is no angle a reader can take (an extra-bytes field of that name in another
        // unit, say), and is refused rather than written.
        if format_number >= 6
            && let Some(i) = layout.index_of("scan_angle")
            && layout.attributes[i].count == 1
        {
            limits.push(Limit {
                at: layout.offsets[i],
                ty: layout.attributes[i].ty,
                name: "scan_angle".into(),
                min: -30000.0,
                max: 30000.0,
                bits: false,
                whole: layout.attributes[i].ty.is_float(),
            });
        }
        for (&(source, _, _), name) in gather.iter().zip(&names) {
            // A rank beyond ±180° has no scan angle (nor does a NaN one): refused, not cut.
            if let Source::RankToAngle { at, ty } = source {
                limits.push(Limit {
                    at,
                    ty,
                    name: "scan_angle_rank".into(),
                    min: -180.0,
                    max: 180.0,
                    bits: false,
                    whole: false,
                });
            }
            if let Source::Cast {
                at,
                from,
                to,
                count,
            } = source
                && let Some((min, max)) = integer_range(to)
            {
                limits.extend((0..count).map(|c| Limit {
                    at: at + c * from.size(),
                    ty: from,
                    name: name.clone(),
                    min,
                    max,
                    bits: false,
                    whole: from.is_float(),
                }));
            }
        }
        Ok(LasRecords {
            stride: layout.stride,
            format_number,
            limits,
            gather,
            ops,
            las_row_len: at,
            record_len,
            extra,
            names,
        })
    }

    /// Points without return numbers are written as single returns (1 of 1), which formats 6
    /// and up require (a return number of 0 is invalid there), as PDAL writes them.
    pub fn single_returns_where_missing(mut self) -> LasRecords {
        for (g, name) in self.gather.iter_mut().zip(&self.names) {
            if matches!(g.0, Source::Zero)
                && (name == "return_number" || name == "number_of_returns")
            {
                g.0 = Source::One;
            }
        }
        self
    }

    /// Bytes of extra fields at the end of each record.
    pub fn extra_bytes(&self) -> usize {
        self.extra.iter().map(|e| e.len).sum()
    }

    /// The Extra Bytes VLR's payload (LASF_Spec 4), where there are extra fields.
    pub fn extra_bytes_vlr(&self) -> Option<Vec<u8>> {
        (!self.extra.is_empty()).then(|| {
            self.extra
                .iter()
                .flat_map(|e| eb_descriptor(&e.attribute))
                .collect()
        })
    }

    /// Refuses `rows` where a field holds a value the point format cannot (a PLY's class 200
    /// in format 3, return 20 in format 6, a float intensity of 0.25); `path` names the output.
    /// The error counts rows from the first of `rows` (`ConvertError::placed` says where).
    pub fn check_fits(&self, path: &Path, rows: &[u8]) -> Result<()> {
        for (r, row) in rows.chunks_exact(self.stride).enumerate() {
            for l in &self.limits {
                let v = l.ty.read_f64(&row[l.at..]);
                // NaN fails every comparison, infinities the range.
                let whole = !l.whole || v.fract() == 0.0;
                if whole && v >= l.min && v <= l.max {
                    continue;
                }
                let holds = if l.bits {
                    format!("LAS point format {} holds", self.format_number)
                } else {
                    "LAS's field holds".to_string()
                };
                let why = if v.is_finite() && v >= l.min && v <= l.max {
                    format!(
                        "not a whole number, and {holds} whole numbers only ({} to {}); \
                         export to .ply to keep it",
                        l.min, l.max
                    )
                } else {
                    format!(
                        "outside what {holds} ({} to {}); export to .ply to keep it",
                        l.min, l.max
                    )
                };
                return Err(ConvertError::unfit(path, &l.name, shown(l.ty, v), r, why));
            }
        }
        Ok(())
    }

    /// The records of `rows`, into `out` (replacing its contents).
    pub fn fill(&self, rows: &[u8], out: &mut Vec<u8>) {
        let n = rows.len() / self.stride;
        out.clear();
        out.resize(n * self.record_len, 0);
        let mut las_row = vec![0u8; self.las_row_len];
        for (row, rec) in rows
            .chunks_exact(self.stride)
            .zip(out.chunks_exact_mut(self.record_len))
        {
            rec[..12].copy_from_slice(&row[..12]);
            las_row.fill(0);
            for &(source, dst, len) in &self.gather {
                let to = &mut las_row[dst..dst + len];
                match source {
                    Source::Copy(s) => to.copy_from_slice(&row[s..s + len]),
                    Source::Widen(s) => {
                        for c in 0..len / 2 {
                            to[2 * c..2 * c + 2]
                                .copy_from_slice(&(row[s + c] as u16).to_le_bytes());
                        }
                    }
                    Source::RankToAngle { at, ty } => {
                        // Read as the type it has (a PLY's may be a float): within
                        // ±180° (`limits`), so the steps fit.
                        let degrees = ty.read_f64(&row[at..]);
                        let steps = (degrees / 0.006).round() as i16;
                        to.copy_from_slice(&steps.to_le_bytes());
                    }
                    Source::Cast {
                        at,
                        from,
                        to: ty,
                        count,
                    } => {
                        for c in 0..count {
                            let v = from.read_f64(&row[at + c * from.size()..]);
                            store(ty, v, &mut to[c * ty.size()..(c + 1) * ty.size()]);
                        }
                    }
                    Source::One => to[0] = 1,
                    Source::Zero => {}
                }
            }
            row_to_record(&self.ops, &las_row, rec);
        }
    }
}

/// Refuses attributes whose raw values are an encoding (`oct16`): written as they are, a reader
/// of the file could not know what they mean. Export decodes them first (`export::widened`).
pub fn refuse_encoded(path: &Path, layout: &RowLayout) -> Result<()> {
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
        // Bytes no descriptor covered are written back as such (LAS 1.4 R15: type 0, their
        // count in `options`), not as a field of bytes.
        _ if a.name == UNDESCRIBED && a.ty == AttrType::U8 => (0, a.size() as u8),
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
    if let (Some(values), true) = (&a.no_data, code != 0) {
        for (i, v) in values.iter().take(3).enumerate() {
            d[40 + i * 8..48 + i * 8].copy_from_slice(&v.to_le_bytes());
        }
        d[3] |= 0x01;
    }
    let name = text_prefix(&a.name, NAME_BYTES).as_bytes();
    d[4..4 + name.len()].copy_from_slice(name);
    let desc = text_prefix(&a.description, NAME_BYTES).as_bytes();
    d[160..160 + desc.len()].copy_from_slice(desc);
    d
}

/// The smallest and largest value of an integer type.
fn integer_range(ty: AttrType) -> Option<(f64, f64)> {
    Some(match ty {
        AttrType::U8 => (0.0, u8::MAX as f64),
        AttrType::I8 => (i8::MIN as f64, i8::MAX as f64),
        AttrType::U16 => (0.0, u16::MAX as f64),
        AttrType::I16 => (i16::MIN as f64, i16::MAX as f64),
        AttrType::U32 => (0.0, u32::MAX as f64),
        AttrType::I32 => (i32::MIN as f64, i32::MAX as f64),
        AttrType::U64 => (0.0, u64::MAX as f64),
        AttrType::I64 => (i64::MIN as f64, i64::MAX as f64),
        AttrType::F16 | AttrType::F32 | AttrType::F64 => return None,
    })
}

/// `v` in the bytes of `ty`: integers rounded and held within their range (NaN as 0).
fn store(ty: AttrType, v: f64, out: &mut [u8]) {
    let v = if v.is_nan() { 0.0 } else { v };
    // `as` from a value within the type's range is exact.
    let v = integer_range(ty).map_or(v, |(lo, hi)| v.round().clamp(lo, hi));
    match ty {
        AttrType::U8 => out.copy_from_slice(&[v as u8]),
        AttrType::I8 => out.copy_from_slice(&(v as i8).to_le_bytes()),
        AttrType::U16 => out.copy_from_slice(&(v as u16).to_le_bytes()),
        AttrType::I16 => out.copy_from_slice(&(v as i16).to_le_bytes()),
        AttrType::U32 => out.copy_from_slice(&(v as u32).to_le_bytes()),
        AttrType::I32 => out.copy_from_slice(&(v as i32).to_le_bytes()),
        AttrType::U64 => out.copy_from_slice(&(v as u64).to_le_bytes()),
        AttrType::I64 => out.copy_from_slice(&(v as i64).to_le_bytes()),
        // No LAS field is a half float; the plan refuses them before this.
        AttrType::F32 | AttrType::F16 => {
            let n = out.len().min(4);
            out[..n].copy_from_slice(&(v as f32).to_le_bytes()[..n]);
        }
        AttrType::F64 => out.copy_from_slice(&v.to_le_bytes()),
    }
}

/// The longest start of `text` of at most `max` bytes that ends between characters: a field
/// cut inside a UTF-8 sequence is text no reader can decode (laspy refuses the whole file).
/// The bytes an extra-bytes record keeps of a field's name (and of its description).
pub(crate) const NAME_BYTES: usize = 32;

/// The longest start of `text` of at most `max` bytes that ends between characters.
pub(crate) fn text_prefix(text: &str, max: usize) -> &str {
    let mut end = text.len().min(max);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    &text[..end]
}

#[cfg(test)]
#[path = "las_records_tests.rs"]
mod tests;
