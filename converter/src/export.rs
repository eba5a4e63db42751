//! `strata export`: every point of a dataset back out as LAS, LAZ or PLY (COPC in `copc.rs`,
//! Potree 2.0 in `potree2.rs`), and the widening of stored rows every export shares.

use crate::error::{ConvertError, Result};
pub use crate::export_notes::export_notes;
use crate::las_export_names::las_export_renames;
use crate::las_records::legacy_limited;
use crate::writers::{LasChoices, RowWriter, open_writer, write_then_finish};
use std::path::Path;
use strata_format::{
    AttrType, Attribute, Crs, DatasetFile, LocalDataset, Metadata, NodeKey, RowLayout,
    oct16_decode, row_position,
};

/// Whether `output` names a COPC file (`.copc.laz`).
pub fn is_copc(output: &Path) -> bool {
    output
        .file_name()
        .and_then(|n| n.to_str())
        .is_some_and(|n| n.to_ascii_lowercase().ends_with(".copc.laz"))
}

/// Writes all points of `dataset` to `output` (LAS, LAZ, PLY, or COPC for `.copc.laz`);
/// returns the number written.
pub fn export(dataset: &Path, output: &Path, overwrite: bool) -> Result<u64> {
    crate::replace::refuse_source(dataset, output)?;
    if is_copc(output) {
        return crate::copc::export_copc(dataset, output, overwrite);
    }
    let ds = LocalDataset::open(dataset)?;
    let extended = high_classes(ds.metadata());
    let legacy = Target::of_file(output) == Target::Las
        && crate::writers::las_format_for(&widened(ds.layout(), Target::Las).layout, extended) < 6;
    match write_dataset(&ds, dataset, output, overwrite, extended) {
        // The metadata counts the classes but not the return numbers: one past what the
        // legacy format chosen holds is met only as it is written, and the file is written
        // again in a format of 6 to 10, which holds it (a value past those fails there too).
        Err(ConvertError::Unfit(u))
            if legacy && legacy_limited().any(|(name, _)| name == u.field) =>
        {
            write_dataset(&ds, dataset, output, overwrite, true)
        }
        written => written,
    }
}

/// `export`'s LAS, LAZ or PLY output, in formats 6 to 10 where `extended` (`LasChoices`).
fn write_dataset(
    ds: &LocalDataset,
    dataset: &Path,
    output: &Path,
    overwrite: bool,
    extended: bool,
) -> Result<u64> {
    let meta = ds.metadata();
    let layout = ds.layout().clone();
    let wide = widened(&layout, Target::of_file(output));
    let writer = open_writer(
        output,
        &wide.layout,
        meta.scale,
        meta.offset,
        meta.points,
        overwrite,
        LasChoices {
            crs: meta.crs.as_ref(),
            extended,
        },
    )?;
    let write_all = |writer: &mut dyn RowWriter| -> Result<u64> {
        let mut written = 0u64;
        let mut out = Vec::new();
        for node in ds.all_nodes()? {
            if node.point_count == 0 {
                continue;
            }
            let cols = ds.read_node(&node)?;
            let rows = cols.to_rows(&layout);
            check_finite(dataset, meta, &node.key, &rows, layout.stride)?;
            let placed = |e: ConvertError| e.placed(dataset, &node.key, |r| r);
            if wide.is_identity() {
                writer.write_rows(&rows).map_err(placed)?;
            } else {
                wide.convert(&rows, &mut out, output).map_err(placed)?;
                writer.write_rows(&out).map_err(placed)?;
            }
            written += node.point_count as u64;
        }
        // The header (PLY's above all) was written for the metadata's count.
        if written != meta.points {
            return Err(ConvertError::input(
                dataset.join(DatasetFile::Metadata.name()),
                format!(
                    "says the dataset holds {} points, but its nodes hold {written}",
                    meta.points
                ),
            ));
        }
        Ok(written)
    };
    write_then_finish(writer, output, write_all)
}

/// Refuses a node whose coordinates the metadata's scale and offset make non-finite: a scale
/// that passes every check of its own may still overflow the coordinates it multiplies (1e308),
/// and written out they would all read infinite.
pub(crate) fn check_finite(
    dataset: &Path,
    meta: &Metadata,
    node: &NodeKey,
    rows: &[u8],
    stride: usize,
) -> Result<()> {
    for row in rows.chunks_exact(stride) {
        let p = row_position(row);
        if let Some(a) =
            (0..3).find(|&a| !(meta.offset[a] + meta.scale[a] * f64::from(p[a])).is_finite())
        {
            return Err(ConvertError::input(
                dataset.join(DatasetFile::Metadata.name()),
                format!(
                    "its scale {:e} and offset {:e} on axis {} give node {} a point \
                     whose coordinate is not a finite number",
                    meta.scale[a],
                    meta.offset[a],
                    ["x", "y", "z"][a],
                    node
                ),
            ));
        }
    }
    Ok(())
}

/// Whether the dataset's points have a classification code above LAS formats 0 to 5's 31, as
/// its metadata counts them (a code that is no number counts as one).
pub(crate) fn high_classes(meta: &Metadata) -> bool {
    meta.classes
        .keys()
        .any(|code| !code.parse::<u64>().is_ok_and(|c| c <= 31))
}

/// Whether a row of `layout` in `rows` holds a value of a bit field past what LAS formats 0
/// to 5 hold (a classification above 31, a return number above 7).
fn rows_need_extended(layout: &RowLayout, rows: &[u8]) -> bool {
    let fields: Vec<(usize, AttrType, f64)> = legacy_limited()
        .filter_map(|(name, legacy)| {
            let i = layout.index_of(name)?;
            Some((
                layout.offsets[i],
                layout.attributes[i].ty,
                f64::from(legacy),
            ))
        })
        .collect();
    rows.chunks_exact(layout.stride.max(1)).any(|row| {
        fields
            .iter()
            .any(|&(at, ty, most)| ty.read_f64(&row[at..]) > most)
    })
}

/// Writes `rows` of a dataset's `layout` (a selection of its points, such as a profile) to
/// `output` as LAS, LAZ or PLY, every attribute kept as `export` keeps it.
pub fn export_rows(
    output: &Path,
    layout: &RowLayout,
    scale: [f64; 3],
    offset: [f64; 3],
    rows: &[u8],
    overwrite: bool,
    crs: Option<&Crs>,
) -> Result<u64> {
    let wide = widened(layout, Target::of_file(output));
    let n = (rows.len() / layout.stride.max(1)) as u64;
    let las = LasChoices {
        crs,
        extended: rows_need_extended(layout, rows),
    };
    let writer = open_writer(output, &wide.layout, scale, offset, n, overwrite, las)?;
    write_then_finish(writer, output, |writer| {
        if wide.is_identity() {
            writer.write_rows(rows)?;
        } else {
            let mut out = Vec::new();
            wide.convert(rows, &mut out, output)?;
            writer.write_rows(&out)?;
        }
        Ok(n)
    })
}

/// The kind of output rows are widened for (`widened`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// PLY keeps each type (an 8-bit colour stays 8-bit).
    Ply,
    /// LAS, LAZ and COPC: colour in the 16-bit RGB fields.
    Las,
    /// Potree 2.0: colour as 3 x uint16 (Potree's decoder reads no other), normals as three
    /// floats, 64-bit integers as doubles.
    Potree2,
}

impl Target {
    /// The target a file output is (`.ply`, else LAS).
    pub fn of_file(output: &Path) -> Target {
        match output.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("ply") => Target::Ply,
            _ => Target::Las,
        }
    }
}

/// A dataset's rows as an export format can hold them: an `oct16` normal decoded to three
/// f32 (`(0, 0)`, no normal, as `0 0 0`), f16 widened to f32 (no export format has half
/// floats); for LAS and Potree 2.0 a colour and a near infrared in 16 bits (LAS 1.4 R15: RGB
/// "should always be normalized to 16 bit values"; Potree reads 3 x uint16): 8-bit colour
/// times 257 (255 is 65535, and `/ 257` gives it back), a float colour taken as 0 to 1; for
/// PLY and Potree 2.0, which have no 64-bit integers, those as doubles, refused where a double
/// does not hold them; for Potree 2.0 a normal of doubles as three f32; everything else as
/// stored.
pub struct Widened {
    /// The layout of the exported rows.
    pub layout: RowLayout,
    from: RowLayout,
    steps: Vec<Step>,
    target: Target,
}

/// How one attribute's bytes become the exported row's.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Step {
    Copy,
    Oct16,
    F16,
    /// 8-bit colour to 16 bits, times 257.
    Colour8,
    /// A float colour in 0 to 1 to 16 bits, times 65535 and rounded; refused outside 0 to 1.
    UnitColour,
    /// f64 to f32 (a Potree normal).
    Narrow,
    /// A 64-bit integer as a double (PLY, Potree 2.0), refused where the double would round it.
    ExactDouble,
}

/// The export layout of `layout` for `target`, and how its rows are converted.
pub fn widened(layout: &RowLayout, target: Target) -> Widened {
    let mut steps = Vec::with_capacity(layout.attributes.len());
    let mut attributes: Vec<Attribute> = layout
        .attributes
        .iter()
        .map(|a| {
            let colour = a.name == "rgb" && a.count == 3 && target != Target::Ply;
            // LAS 1.4 keeps the near infrared with the colour, in 16 bits alike (a float one
            // is a value, cast as other fields are).
            let nir8 = a.name == "nir" && a.count == 1 && target != Target::Ply;
            let (step, ty) = if a.is_oct16() {
                steps.push(Step::Oct16);
                return Attribute {
                    description: "unit normal".into(),
                    ..Attribute::new(&a.name, AttrType::F32, 3)
                };
            } else if (colour || nir8) && a.ty == AttrType::U8 {
                (Step::Colour8, AttrType::U16)
            } else if colour && a.ty.is_float() {
                (Step::UnitColour, AttrType::U16)
            } else if a.ty == AttrType::F16 {
                (Step::F16, AttrType::F32)
            } else if target == Target::Potree2
                && a.name == "normal"
                && a.count == 3
                && a.ty == AttrType::F64
            {
                (Step::Narrow, AttrType::F32)
            } else if target != Target::Las
                && matches!(a.ty, AttrType::U64 | AttrType::I64)
                && a.scale.is_none()
                && a.offset.is_none()
            {
                // (A scaled one is a real number, which PLY export writes as its double.)
                (Step::ExactDouble, AttrType::F64)
            } else {
                (Step::Copy, a.ty)
            };
            steps.push(step);
            // A no-value marker is a raw value of the stored type: of another, it means none.
            let no_data = a.no_data.clone().filter(|_| ty == a.ty);
            Attribute {
                ty,
                no_data,
                ..a.clone()
            }
        })
        .collect();
    if target == Target::Las {
        for (i, name, _) in las_export_renames(&attributes) {
            attributes[i].name = name;
        }
    }
    Widened {
        layout: RowLayout::new(attributes),
        from: layout.clone(),
        steps,
        target,
    }
}

impl Widened {
    /// Whether rows are exported as they are stored.
    pub fn is_identity(&self) -> bool {
        self.steps.iter().all(|s| *s == Step::Copy)
    }

    /// Converts whole rows of the dataset's layout into `out` (replacing its contents); a
    /// value the output cannot hold is refused (`ConvertError::Unfit`, `output` named, rows
    /// counted from the first of `rows`).
    pub fn convert(&self, rows: &[u8], out: &mut Vec<u8>, output: &Path) -> Result<()> {
        let n = rows.len() / self.from.stride;
        out.clear();
        out.resize(n * self.layout.stride, 0);
        let pos = RowLayout::POSITION_BYTES;
        for (r, (row, dst)) in rows
            .chunks_exact(self.from.stride)
            .zip(out.chunks_exact_mut(self.layout.stride))
            .enumerate()
        {
            dst[..pos].copy_from_slice(&row[..pos]);
            for (i, step) in self.steps.iter().enumerate() {
                let a = &self.from.attributes[i];
                let src = &row[self.from.offsets[i]..self.from.offsets[i] + a.size()];
                let to = self.layout.offsets[i];
                let dst = &mut dst[to..to + self.layout.attributes[i].size()];
                let w = self.layout.attributes[i].ty.size();
                let values = src.chunks_exact(a.ty.size()).zip(dst.chunks_exact_mut(w));
                match step {
                    Step::Copy => dst.copy_from_slice(src),
                    Step::Oct16 => {
                        let raw = [
                            u16::from_le_bytes([src[0], src[1]]),
                            u16::from_le_bytes([src[2], src[3]]),
                        ];
                        let n = oct16_decode(raw).unwrap_or([0.0; 3]);
                        for (c, v) in n.into_iter().enumerate() {
                            dst[c * 4..c * 4 + 4].copy_from_slice(&(v as f32).to_le_bytes());
                        }
                    }
                    Step::F16 | Step::Narrow => {
                        for (v, d) in values {
                            d.copy_from_slice(&(a.ty.read_f64(v) as f32).to_le_bytes());
                        }
                    }
                    Step::Colour8 => {
                        for (v, d) in values {
                            d.copy_from_slice(&(u16::from(v[0]) * 257).to_le_bytes());
                        }
                    }
                    Step::UnitColour => {
                        for (v, d) in values {
                            let v = a.ty.read_f64(v);
                            // NaN fails the comparison too.
                            if !(0.0..=1.0).contains(&v) {
                                return Err(ConvertError::unfit(
                                    output,
                                    &a.name,
                                    crate::error::shown(a.ty, v),
                                    r,
                                    "outside 0 to 1, which a float colour must lie in to go \
                                     out as a 16-bit colour (0 to 65535); export to .ply to \
                                     keep it",
                                ));
                            }
                            d.copy_from_slice(&((v * 65535.0).round() as u16).to_le_bytes());
                        }
                    }
                    Step::ExactDouble => {
                        for (v, d) in values {
                            let x = exact_double(a.ty, v).map_err(|v| {
                                ConvertError::unfit(
                                    output,
                                    &a.name,
                                    v.to_string(),
                                    r,
                                    no_double_holds(match self.target {
                                        Target::Ply => "PLY property",
                                        _ => "Potree 2.0 attribute",
                                    }),
                                )
                            })?;
                            d.copy_from_slice(&x.to_le_bytes());
                        }
                    }
                }
            }
        }
        Ok(())
    }
}

/// One component of an attribute of type `ty` as a double, for formats without 64-bit
/// integers (PLY, Potree 2.0): `Err` with the exact value where a double does not hold it (a
/// u64 past 2^53), which is refused rather than rounded.
pub(crate) fn exact_double(ty: AttrType, c: &[u8]) -> std::result::Result<f64, i128> {
    let d = ty.read_f64(c);
    // Compared in i128, which holds both types and the double's rounding past them (u64::MAX
    // becomes 2^64) without saturating.
    match ty.read_wide_integer(c) {
        Some(v) if d as i128 != v => Err(v),
        _ => Ok(d),
    }
}

/// Why a value `exact_double` refused cannot go out as a `what` of the format.
pub(crate) fn no_double_holds(what: &str) -> String {
    format!(
        "which no {what} holds exactly (the format has no 64-bit integers, and a double keeps \
         53 bits); export to .las or .laz, whose extra bytes keep it"
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use strata_format::oct16_encode;

    #[test]
    fn oct16_normals_and_half_floats_are_widened_to_f32() {
        let layout = RowLayout::new(vec![
            Attribute::new("intensity", AttrType::U16, 1),
            Attribute::oct16_normal(),
            Attribute::new("radius", AttrType::F16, 1),
        ]);
        let wide = widened(&layout, Target::Ply);
        assert!(!wide.is_identity());
        let shapes: Vec<(&str, AttrType, u8, bool)> = wide
            .layout
            .attributes
            .iter()
            .map(|a| (a.name.as_str(), a.ty, a.count, a.encoding.is_some()))
            .collect();
        assert_eq!(
            shapes,
            [
                ("intensity", AttrType::U16, 1, false),
                ("normal", AttrType::F32, 3, false),
                ("radius", AttrType::F32, 1, false),
            ]
        );
        let n = [0.6, -0.8, 0.0];
        let mut rows = Vec::new();
        for raw in [oct16_encode(n), [0, 0]] {
            rows.extend_from_slice(&[1, 0, 0, 0, 2, 0, 0, 0, 3, 0, 0, 0]);
            rows.extend_from_slice(&700u16.to_le_bytes());
            rows.extend_from_slice(&raw[0].to_le_bytes());
            rows.extend_from_slice(&raw[1].to_le_bytes());
            rows.extend_from_slice(&half::f16::from_f64(0.25).to_le_bytes());
        }
        let mut out = Vec::new();
        wide.convert(&rows, &mut out, Path::new("x.ply"))
            .expect("converted");
        assert_eq!(out.len(), 2 * wide.layout.stride);
        let f =
            |row: usize, at: usize| AttrType::F32.read_f64(&out[row * wide.layout.stride + at..]);
        assert_eq!(&out[..12], &rows[..12]);
        assert_eq!(u16::from_le_bytes([out[12], out[13]]), 700);
        for (c, want) in n.iter().enumerate() {
            assert!((f(0, 14 + 4 * c) - want).abs() < 1e-4, "component {c}");
            assert_eq!(f(1, 14 + 4 * c), 0.0, "no normal is 0 0 0");
        }
        assert_eq!(f(0, 26), 0.25);
    }
}
