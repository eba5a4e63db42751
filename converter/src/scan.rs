//! Phase 1: decode every input once into a staging file of (f64 position, attribute row)
//! records in the dataset's attribute layout (compressed, `rowfile`), checking coordinates and
//! measuring extents.

use crate::crs_identity::agreed_codes;
use crate::error::{ConvertError, Result};
use crate::input::{NO_SCANNER, SCANNER, SourceInfo, open_source};
use crate::las_crs::epsg;
use crate::quantize::SourceExtent;
use crate::rowfile::RowWriter;
use crate::rows::batch_records;
use crate::scan_angle::ScanAngleFill;
use indicatif::ProgressBar;
use std::path::{Path, PathBuf};
use strata_format::{AttrType, Attribute, Crs, MAX_ATTRIBUTES, TimeBase};

pub const BATCH: usize = 1 << 18;

#[derive(Debug, Clone)]
pub struct ScanResult {
    pub attributes: Vec<Attribute>,
    pub points: u64,
    pub min: [f64; 3],
    pub max: [f64; 3],
    pub extents: Vec<SourceExtent>,
}

/// Bytes of a staging record's position (three f64) before its attributes.
const STAGED_POSITION_BYTES: usize = 24;

/// Bytes of one staging record for `attributes`.
pub fn staging_stride(attributes: &[Attribute]) -> usize {
    STAGED_POSITION_BYTES + attributes.iter().map(|a| a.size()).sum::<usize>()
}

/// What opening every input tells before any point is read.
#[derive(Debug, Clone, Default)]
pub struct InputsSummary {
    /// The union of the inputs' attributes, in first-seen order.
    pub attributes: Vec<Attribute>,
    /// The points the inputs declare.
    pub points: u64,
    /// Every input's scanner positions, input after input: the `scanner` attribute indexes
    /// this list.
    pub scanners: Vec<[f64; 3]>,
    /// The input (index into `inputs`) each scanner belongs to.
    pub scanner_inputs: Vec<usize>,
    /// The first coordinate reference system an input states.
    pub crs: Option<strata_format::Crs>,
}

/// Opens every input: the union of their attributes (a name with two different types is an
/// error naming both files) and their scanners. The inputs' own warnings (renamed attributes)
/// are added to `warnings`.
pub fn union_attributes(inputs: &[PathBuf], warnings: &mut Vec<String>) -> Result<InputsSummary> {
    // Per attribute: as merged, the input it came from first, and whether an input's time so
    // far counts from an unknown start.
    let mut union: Vec<(Attribute, PathBuf, bool)> = Vec::new();
    let mut summary = InputsSummary::default();
    let mut first_coded: Option<(Vec<u32>, PathBuf)> = None;
    let mut seen: Vec<(PathBuf, &PathBuf)> = Vec::new();
    for (i, path) in inputs.iter().enumerate() {
        let src = open_source(path)?;
        // One file named twice (`a.las ./a.las`) is read twice: said, as it is rarely meant.
        if let Ok(real) = std::fs::canonicalize(path) {
            if let Some((_, first)) = seen.iter().find(|(r, _)| *r == real) {
                warnings.push(format!(
                    "{}: the same file as {} given before it; its points are converted twice",
                    path.display(),
                    first.display()
                ));
            }
            seen.push((real, path));
        }
        // Saturating: E57 point counts are the file's word, not yet checked against its data.
        summary.points = summary.points.saturating_add(src.info().points);
        warnings.extend(src.info().warnings.iter().cloned());
        if src.info().attributes.len() > MAX_ATTRIBUTES {
            return Err(ConvertError::input(
                path,
                format!(
                    "its points have {} attributes; a dataset holds at most {MAX_ATTRIBUTES}",
                    src.info().attributes.len()
                ),
            ));
        }
        for a in &src.info().attributes {
            let relative = src.info().time_from_unknown_start && a.name == "gps_time";
            match union.iter_mut().find(|(u, ..)| u.name == a.name) {
                Some((u, first, _)) if u.ty != a.ty || u.count != a.count => {
                    return Err(ConvertError::input(
                        path,
                        format!(
                            "attribute \"{}\" is {}x{} here but {}x{} in {}; inputs must agree on attribute types",
                            a.name,
                            a.count,
                            a.ty.name(),
                            u.count,
                            u.ty.name(),
                            first.display()
                        ),
                    ));
                }
                // An E57 without acquisitionStart stamps its points from an unknown start:
                // beside times of a base they would be read in it.
                Some((u, first, any_relative))
                    if (relative && u.time_base.is_some())
                        || (*any_relative && a.time_base.is_some()) =>
                {
                    return Err(ConvertError::input(
                        path,
                        format!(
                            "its \"{}\" and that of {} cannot make one attribute: one of them \
                             counts from an unknown start (an E57 without acquisitionStart), the \
                             other in {}; convert them apart",
                            a.name,
                            first.display(),
                            a.time_base.or(u.time_base).map_or("", TimeBase::name),
                        ),
                    ));
                }
                Some((u, first, _))
                    if u.time_base.is_some()
                        && a.time_base.is_some()
                        && u.time_base != a.time_base =>
                {
                    let name = |t: Option<TimeBase>| t.map_or("", TimeBase::name);
                    return Err(ConvertError::input(
                        path,
                        format!(
                            "its \"{}\" is {} but {} in {}; one dataset holds one time base, so \
                             convert them apart or bring their times to one base first",
                            a.name,
                            name(a.time_base),
                            name(u.time_base),
                            first.display()
                        ),
                    ));
                }
                Some((u, first, any_relative)) => {
                    // An input that does not say (a PLY) takes the others' time base; once
                    // one counts from an unknown start, no later base may join.
                    u.time_base = u.time_base.or(a.time_base);
                    *any_relative |= relative;
                    // The rows keep the raw integers: one scale must hold for every input.
                    let differs = (0..a.count as usize).find(|&c| u.scaling(c) != a.scaling(c));
                    if let Some(c) = differs {
                        let component = if a.count > 1 {
                            format!(" (component {c})")
                        } else {
                            String::new()
                        };
                        let shown = |a: &Attribute| {
                            let (scale, offset) = a.scaling(c);
                            format!("scale {scale} and offset {offset}")
                        };
                        return Err(ConvertError::input(
                            path,
                            format!(
                                "attribute \"{}\"{component} is stored with {} here but {} in {}; inputs must agree on how an attribute is scaled",
                                a.name,
                                shown(a),
                                shown(u),
                                first.display()
                            ),
                        ));
                    }
                    // One input's no-value marker may be another's real value: where they
                    // differ, none is stated.
                    if u.no_data.is_some() && u.no_data != a.no_data {
                        u.no_data = None;
                        warnings.push(format!(
                            "{}: its \"{}\" has another no-data value than in {} (or none); the \
                             dataset states none",
                            path.display(),
                            a.name,
                            first.display()
                        ));
                    }
                }
                None => union.push((a.clone(), path.clone(), relative)),
            }
        }
        if union.len() > MAX_ATTRIBUTES {
            return Err(ConvertError::input(
                path,
                format!(
                    "its attributes bring the inputs' attributes to {}; a dataset holds at most {MAX_ATTRIBUTES}",
                    union.len()
                ),
            ));
        }
        let scanners = &src.info().scanners;
        if summary.scanners.len() + scanners.len() > NO_SCANNER as usize {
            return Err(ConvertError::input(
                path,
                format!(
                    "its {} scans bring the inputs' scans to more than the {NO_SCANNER} a dataset can number",
                    scanners.len()
                ),
            ));
        }
        summary.scanners.extend_from_slice(scanners);
        summary.scanner_inputs.extend(scanners.iter().map(|_| i));
        // Every input that names EPSG codes names the first such input's: points in two
        // systems make no dataset.
        if let Some(codes) = src.info().crs.as_ref().and_then(agreed_codes) {
            match &first_coded {
                None => first_coded = Some((codes, path.clone())),
                Some((first, at)) if *first != codes => {
                    return Err(ConvertError::input(
                        path,
                        format!(
                            "states the coordinate reference system {}, but {} states {}: \
                             points in two systems make no dataset; bring them into one first \
                             (PDAL's filters.reprojection, for one)",
                            epsg(&codes),
                            at.display(),
                            epsg(first)
                        ),
                    ));
                }
                Some(_) => {}
            }
        }
        match (&summary.crs, &src.info().crs) {
            (None, Some(crs)) => summary.crs = Some(crs.clone()),
            (Some(kept), Some(crs)) if kept != crs => {
                summary.crs = Some(merged_crs(kept, crs, path, warnings));
            }
            _ => {}
        }
    }
    summary.attributes = union.into_iter().map(|(a, ..)| a).collect();
    Ok(summary)
}

/// One system for inputs that state `kept` and then `crs` (two EPSG systems were refused
/// before): the same codes, however written (WKT 1 or 2, GeoTIFF keys), are one system,
/// stated every way the inputs did; where the codes cannot be told, the first is kept, and
/// said.
fn merged_crs(kept: &Crs, crs: &Crs, path: &Path, warnings: &mut Vec<String>) -> Crs {
    match (agreed_codes(kept), agreed_codes(crs)) {
        (Some(a), Some(b)) if a == b => Crs {
            wkt: kept.wkt.clone().or_else(|| crs.wkt.clone()),
            geotiff: kept.geotiff.clone().or_else(|| crs.geotiff.clone()),
        },
        _ => {
            warnings.push(format!(
                "{}: states another coordinate reference system than the inputs before it (one \
                 that names no EPSG code, so that they cannot be compared); the first one \
                 stated is kept",
                path.display()
            ));
            kept.clone()
        }
    }
}

pub fn scan(
    inputs: &[PathBuf],
    attributes: &[Attribute],
    staging: &Path,
    bar: &ProgressBar,
) -> Result<ScanResult> {
    let stride = staging_stride(attributes);
    // Compressed in blocks like every work file of rows (`rowfile`).
    let mut out = RowWriter::create(staging, stride)?;
    let mut result = ScanResult {
        attributes: attributes.to_vec(),
        points: 0,
        min: [f64::INFINITY; 3],
        max: [f64::NEG_INFINITY; 3],
        extents: Vec::new(),
    };
    let batch = batch_records(stride, BATCH);
    let mut xyz = Vec::with_capacity(batch);
    let mut rows = Vec::new();
    let mut records = Vec::with_capacity(batch * stride);
    // Scanner indices are global: each input's scans follow those of the inputs before it.
    let mut scanner_base = 0usize;
    for path in inputs {
        let mut src = open_source(path)?;
        // `union_attributes` checked that the indices fit.
        src.set_scanner_base(scanner_base.min(NO_SCANNER as usize) as u16);
        scanner_base += src.info().scanners.len();
        let defaults = defaults_for(src.info(), attributes);
        let scan_angle =
            ScanAngleFill::for_input(&src.info().attributes, attributes, STAGED_POSITION_BYTES);
        // (source row offset, staging offset, length) for each attribute this input has.
        let mut copies = Vec::new();
        let mut src_off = 0usize;
        for a in &src.info().attributes {
            let mut dst = STAGED_POSITION_BYTES;
            for u in attributes {
                if u.name == a.name {
                    break;
                }
                dst += u.size();
            }
            copies.push((src_off, dst, a.size()));
            src_off += a.size();
        }
        let row_len = src.info().row_len();
        let mut extent = SourceExtent {
            precision: src.info().precision,
            min: [f64::INFINITY; 3],
            max: [f64::NEG_INFINITY; 3],
        };
        let mut index = 0u64;
        loop {
            xyz.clear();
            rows.clear();
            let n = src.read(batch, &mut xyz, &mut rows)?;
            if n == 0 {
                break;
            }
            records.clear();
            records.resize(n * stride, 0);
            for (at, bytes) in &defaults {
                for rec in records.chunks_exact_mut(stride) {
                    rec[*at..*at + bytes.len()].copy_from_slice(bytes);
                }
            }
            for (i, (p, rec)) in xyz.iter().zip(records.chunks_exact_mut(stride)).enumerate() {
                for a in 0..3 {
                    let v = p[a];
                    if !v.is_finite() {
                        return Err(ConvertError::input(
                            path,
                            format!(
                                "point {} has a non-finite {} coordinate ({v})",
                                index + i as u64,
                                ["x", "y", "z"][a]
                            ),
                        ));
                    }
                    extent.min[a] = extent.min[a].min(v);
                    extent.max[a] = extent.max[a].max(v);
                    rec[a * 8..a * 8 + 8].copy_from_slice(&v.to_le_bytes());
                }
                let row = &rows[i * row_len..(i + 1) * row_len];
                for &(s, d, len) in &copies {
                    rec[d..d + len].copy_from_slice(&row[s..s + len]);
                }
                if let Some(fill) = &scan_angle {
                    fill.apply(rec);
                }
            }
            out.write(&records)?;
            index += n as u64;
            bar.inc(n as u64);
        }
        result.points += index;
        for a in 0..3 {
            result.min[a] = result.min[a].min(extent.min[a]);
            result.max[a] = result.max[a].max(extent.max[a]);
        }
        result.extents.push(extent);
    }
    out.finish()?;
    Ok(result)
}

/// The values (staging offset, bytes) that the points of an input without some of the
/// dataset's attributes take for them where 0 would say something false: no scanner, not
/// scanner 0; a single return (1 of 1), not return 0, which LAS formats 6 and up forbid, as
/// an input without returns (a PLY, an E57) converted alone is exported. Every other missing
/// attribute is 0.
fn defaults_for(input: &SourceInfo, attributes: &[Attribute]) -> Vec<(usize, Vec<u8>)> {
    let mut out = Vec::new();
    let mut at = STAGED_POSITION_BYTES;
    for a in attributes {
        let missing = !input.attributes.iter().any(|i| i.name == a.name);
        let single = a.count == 1;
        match a.name.as_str() {
            SCANNER if missing && single && a.ty == AttrType::U16 => {
                out.push((at, NO_SCANNER.to_le_bytes().to_vec()));
            }
            "return_number" | "number_of_returns" if missing && single && a.ty == AttrType::U8 => {
                out.push((at, vec![1]));
            }
            _ => {}
        }
        at += a.size();
    }
    out
}

#[inline]
pub fn staging_position(rec: &[u8]) -> [f64; 3] {
    let f = |o: usize| {
        let mut b = [0u8; 8];
        b.copy_from_slice(&rec[o..o + 8]);
        f64::from_le_bytes(b)
    };
    [f(0), f(8), f(16)]
}
