//! `strata export`: every point of a dataset back out as LAS, LAZ or PLY.

use crate::error::{ConvertError, Result};
use crate::writers::{RowWriter, open_writer, write_then_finish};
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
    if is_copc(output) {
        return crate::copc::export_copc(dataset, output, overwrite);
    }
    let ds = LocalDataset::open(dataset)?;
    let meta = ds.metadata();
    let layout = ds.layout().clone();
    let wide = widened(&layout);
    let writer = open_writer(
        output,
        &wide.layout,
        meta.scale,
        meta.offset,
        meta.points,
        overwrite,
        meta.crs.as_ref(),
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
            if wide.is_identity() {
                writer.write_rows(&rows)?;
            } else {
                wide.convert(&rows, &mut out);
                writer.write_rows(&out)?;
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

/// What the output cannot state of the dataset's coordinate reference system, to be said: one
/// given as GeoTIFF keys only, where the output states a CRS as WKT alone (COPC, Potree 2.0,
/// LAS point formats 6 to 10). Strata does not translate GeoTIFF keys into WKT.
pub fn crs_loss(dataset: &Path, output: &Path, potree2: bool) -> Result<Option<String>> {
    let ds = LocalDataset::open(dataset)?;
    let meta = ds.metadata();
    if !meta
        .crs
        .as_ref()
        .is_some_and(|c| c.wkt.is_none() && c.geotiff.is_some())
    {
        return Ok(None);
    }
    let ext = output
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let lost = if potree2 {
        Some("Potree 2.0 states one as WKT, so the output states none".to_string())
    } else if is_copc(output) {
        Some("COPC states one as WKT, so the output states none".to_string())
    } else if matches!(ext.as_deref(), Some("las" | "laz")) {
        let format = crate::writers::las_format_for(&widened(ds.layout()).layout);
        (format >= 6).then(|| {
            format!(
                "point format {format} states one as WKT; the output carries the GeoTIFF keys, \
                 which readers that follow the format ignore"
            )
        })
    } else {
        None
    };
    Ok(lost.map(|lost| {
        format!(
            "{}: the dataset's coordinate reference system is given as GeoTIFF keys only, and \
             {lost} (strata does not translate GeoTIFF keys into WKT)",
            output.display()
        )
    }))
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
    let wide = widened(layout);
    let n = (rows.len() / layout.stride.max(1)) as u64;
    let writer = open_writer(output, &wide.layout, scale, offset, n, overwrite, crs)?;
    write_then_finish(writer, output, |writer| {
        if wide.is_identity() {
            writer.write_rows(rows)?;
        } else {
            let mut out = Vec::new();
            wide.convert(rows, &mut out);
            writer.write_rows(&out)?;
        }
        Ok(n)
    })
}

/// A dataset's rows as the export formats can hold them: an `oct16` normal decoded to three
/// f32 (`(0, 0)`, no normal, as `0 0 0`), f16 widened to f32 (neither LAS nor PLY has half
/// floats); everything else as stored.
pub struct Widened {
    /// The layout of the exported rows.
    pub layout: RowLayout,
    from: RowLayout,
    steps: Vec<Step>,
}

/// How one attribute's bytes become the exported row's.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Step {
    Copy,
    Oct16,
    F16,
}

/// The export layout of `layout` and how its rows are converted.
pub fn widened(layout: &RowLayout) -> Widened {
    let mut steps = Vec::with_capacity(layout.attributes.len());
    let attributes = layout
        .attributes
        .iter()
        .map(|a| {
            if a.is_oct16() {
                steps.push(Step::Oct16);
                Attribute {
                    description: "unit normal".into(),
                    ..Attribute::new(&a.name, AttrType::F32, 3)
                }
            } else if a.ty == AttrType::F16 {
                steps.push(Step::F16);
                Attribute {
                    ty: AttrType::F32,
                    ..a.clone()
                }
            } else {
                steps.push(Step::Copy);
                a.clone()
            }
        })
        .collect();
    Widened {
        layout: RowLayout::new(attributes),
        from: layout.clone(),
        steps,
    }
}

impl Widened {
    /// Whether rows are exported as they are stored.
    pub fn is_identity(&self) -> bool {
        self.steps.iter().all(|s| *s == Step::Copy)
    }

    /// Converts whole rows of the dataset's layout into `out` (replacing its contents).
    pub fn convert(&self, rows: &[u8], out: &mut Vec<u8>) {
        let n = rows.len() / self.from.stride;
        out.clear();
        out.resize(n * self.layout.stride, 0);
        let pos = RowLayout::POSITION_BYTES;
        for (row, dst) in rows
            .chunks_exact(self.from.stride)
            .zip(out.chunks_exact_mut(self.layout.stride))
        {
            dst[..pos].copy_from_slice(&row[..pos]);
            for (i, step) in self.steps.iter().enumerate() {
                let a = &self.from.attributes[i];
                let src = &row[self.from.offsets[i]..self.from.offsets[i] + a.size()];
                let to = self.layout.offsets[i];
                let dst = &mut dst[to..to + self.layout.attributes[i].size()];
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
                    Step::F16 => {
                        for (c, h) in src.chunks_exact(2).enumerate() {
                            let v = AttrType::F16.read_f64(h) as f32;
                            dst[c * 4..c * 4 + 4].copy_from_slice(&v.to_le_bytes());
                        }
                    }
                }
            }
        }
    }
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
        let wide = widened(&layout);
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
        wide.convert(&rows, &mut out);
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
