//! Everything before indexing: read the inputs (in place where they allow it), count them on
//! the coarse grid, cut the cube into chunks and distribute the rows into chunk files. The
//! result, a `Plan`, is all that indexing and a resumed run need.

use crate::build::ConvertOptions;
use crate::chunk_step::ChunkStep;
use crate::disk::{DiskUse, check_conversion};
use crate::distribute::{ClassCounts, Distribution, RowBuffers, Share, distribute};
use crate::error::{ConvertError, Result, io_err};
use crate::input::las::LasSource;
use crate::input::{PointSource, Precision};
use crate::plan::{Chunk, Counts, count, cube_for, grid_shape, max_chunk_points, plan_chunks};
use crate::progress::Phases;
use crate::quantize::{Quantization, SourceExtent, choose};
use crate::rows::{RecordToRow, RowInput};
use crate::scan::{scan, staging_stride, union_attributes};
use crate::staging::{decode_to_rows, quantize_staging};
use crate::workdir::WorkDir;
use serde::{Deserialize, Serialize};
use std::fs;
use std::path::{Path, PathBuf};
use strata_format::{AttrType, Attribute, Cube, MAX_ATTRIBUTES, RowLayout};

/// What the work directory must hold for `--resume`: the result of everything before indexing.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Plan {
    pub fingerprint: String,
    pub attributes: Vec<Attribute>,
    pub points: u64,
    pub scale: [f64; 3],
    pub offset: [f64; 3],
    pub coarsened: bool,
    /// What the user must know of how the inputs were read (renamed attributes, bounds that were
    /// measured, a coarsened scale); printed and recorded in the metadata.
    #[serde(default)]
    pub warnings: Vec<String>,
    pub min: [f64; 3],
    pub max: [f64; 3],
    pub cube: Cube,
    pub chunks: Vec<Chunk>,
    /// Points per classification code, where the rows have a one-byte classification.
    #[serde(default)]
    pub classes: Vec<(u8, u64)>,
    /// Point spacing in real units at the 50th, 90th and 99th percentile of points (sparsest
    /// last), estimated from the counting grid as if each cell held a surface across it. It
    /// depends on the inputs alone, not on how they are cut into chunks.
    #[serde(default)]
    pub spacing_quantiles: [f64; 3],
    /// Where each scan's scanner stood (world coordinates), every input's scans in input order;
    /// the rows' u16 `scanner` attribute indexes it (`input::SCANNER`; an index past its end,
    /// `input::NO_SCANNER` among them, names no scanner). Empty for inputs without scanners.
    #[serde(default)]
    pub scanners: Vec<[f64; 3]>,
    /// The input (index into the inputs, and so into metadata's `sources`) of each scanner.
    #[serde(default)]
    pub scanner_inputs: Vec<usize>,
    /// The coordinate reference system the inputs state (the first one stated).
    #[serde(default)]
    pub crs: Option<strata_format::Crs>,
}

impl Plan {
    pub fn quantization(&self) -> Quantization {
        Quantization {
            scale: self.scale,
            offset: self.offset,
            coarsened: self.coarsened,
            // Said once, when the plan was made.
            coarse_grids: None,
            coarse_floats: None,
        }
    }

    /// A quantized position in real units.
    pub fn to_real(&self, p: [i64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| self.offset[a] + self.scale[a] * p[a] as f64)
    }
}

/// Every input as rows the count and distribute phases can read, with the dataset's scale,
/// offset and cube.
struct Staged {
    inputs: Vec<RowInput>,
    q: Quantization,
    cube: Cube,
    counts: Counts,
}

/// Read, count, plan and distribute into the work directory's chunk files.
pub fn prepare(
    opts: &ConvertOptions,
    wd: &WorkDir,
    threads: usize,
    phases: &mut Phases,
    fingerprint: String,
    step: &dyn ChunkStep,
) -> Result<Plan> {
    let Counted {
        mut plan,
        inputs,
        lut,
        class_at,
    } = count_and_plan(
        opts,
        wd,
        threads,
        phases,
        fingerprint,
        step,
        DiskUse::HandOver,
    )?;
    let layout = RowLayout::new(plan.attributes.clone());
    let class_counts = phases.timed("distribute", Some((plan.points, "points")), |bar| {
        distribute(
            &Distribution {
                inputs: &inputs,
                stride: layout.stride,
                cube: &plan.cube,
                lut: &lut,
                chunk_count: plan.chunks.len(),
                chunk_dir: &wd.chunks(),
                buffer_budget: distribute_budget(opts.memory_limit),
                room: distribute_room(opts.memory_limit),
                threads,
                class_at,
                share: Share::WHOLE,
            },
            bar,
            &RowBuffers::new(threads),
        )
    })?;
    remove_staging(&inputs, wd)?;
    plan.classes = class_list(class_at, &class_counts);
    Ok(plan)
}

/// Bytes of row buffers the distribution may hold, all workers together.
pub fn distribute_budget(memory_limit: u64) -> u64 {
    (memory_limit / 6).min(256 << 20)
}

/// What the distribution's row buffers may take at most: the distribution runs alone, in half
/// of what the limit leaves (the batches read and the rest take the other half).
pub fn distribute_room(memory_limit: u64) -> u64 {
    crate::plan::index_room(memory_limit) / 2
}

/// The plan's points per classification code, from the distribution's counts (none where the
/// rows have no one-byte classification).
pub fn class_list(class_at: Option<usize>, counts: &ClassCounts) -> Vec<(u8, u64)> {
    class_at
        .map(|_| {
            (0..=255u8)
                .zip(counts.iter().copied())
                .filter(|(_, n)| *n > 0)
                .collect()
        })
        .unwrap_or_default()
}

/// Everything up to the distribution: the plan (its class counts still empty: the
/// distribution counts them), the inputs as rows and the lookup from grid cell to chunk.
pub struct Counted {
    pub plan: Plan,
    pub inputs: Vec<RowInput>,
    pub lut: Vec<u32>,
    /// Where a row holds its one-byte classification, if it has one.
    pub class_at: Option<usize>,
}

/// Read and count the inputs and cut the cube into chunks: what `--plan-only` stops after.
pub fn count_and_plan(
    opts: &ConvertOptions,
    wd: &WorkDir,
    threads: usize,
    phases: &mut Phases,
    fingerprint: String,
    step: &dyn ChunkStep,
    disk: DiskUse,
) -> Result<Counted> {
    let mut warnings = Vec::new();
    let summary = union_attributes(&opts.inputs, &mut warnings)?;
    let (mut attributes, declared) = (summary.attributes, summary.points);
    let added = step.attributes(&attributes)?;
    attributes.extend(added);
    // The inputs were held to the cap each; what --normals adds must fit under it too, or the
    // dataset written would be one no reader opens.
    if attributes.len() > MAX_ATTRIBUTES {
        return Err(ConvertError::Usage(format!(
            "the inputs' attributes and those --normals adds come to {}; a dataset holds at most {MAX_ATTRIBUTES}",
            attributes.len()
        )));
    }
    let layout = RowLayout::new(attributes.clone());
    check_conversion(wd.work(), wd.root(), declared, layout.stride, disk)?;
    let staged = match stage_from_headers(opts, &layout, wd, threads, phases) {
        Ok(Some(staged)) if !needlessly_large(&staged) => staged,
        Ok(Some(staged)) => {
            // The header's bounds hold the points but are far larger than they are: its cube
            // would give the octree levels without points. Measure instead.
            remove_staging(&staged.inputs, wd)?;
            stage_measured(opts, &attributes, &layout, wd, threads, phases, declared)?
        }
        Ok(None) => stage_measured(opts, &attributes, &layout, wd, threads, phases, declared)?,
        Err(ConvertError::OutsideHeaderBounds { path, record }) => {
            warnings.push(bounds_warning(&path, record));
            wd.remove_decoded(opts.inputs.len())?;
            stage_measured(opts, &attributes, &layout, wd, threads, phases, declared)?
        }
        Err(e) => return Err(e),
    };
    warnings.extend(staged.q.coarse_floats.clone());
    warnings.extend(staged.q.coarse_grids.clone());
    let points: u64 = staged.inputs.iter().map(|i| i.records).sum();
    if points == 0 {
        return Err(ConvertError::input(
            &opts.inputs[0],
            "the inputs hold no points",
        ));
    }
    if points > u32::MAX as u64 * 64 {
        return Err(ConvertError::Usage(format!(
            "{points} points is more than this converter supports"
        )));
    }
    // Several chunks per worker keep the workers busy to the end; the memory limit caps them.
    let balanced = (points / (threads as u64 * 4)).max(1 << 20);
    let max_chunk = max_chunk_points(
        opts.memory_limit,
        threads,
        layout.stride,
        step.bytes_per_point(layout.stride),
    )
    .min(balanced);
    let (chunks, lut) = plan_chunks(&staged.counts.cells, &staged.cube, max_chunk)?;

    let class_at = layout
        .index_of("classification")
        .filter(|&i| layout.attributes[i].ty == AttrType::U8 && layout.attributes[i].count == 1)
        .map(|i| layout.offsets[i]);
    let spacing_quantiles = spacing_quantiles(&staged.counts, &staged.cube, staged.q.scale);
    let q = staged.q;
    let to_real =
        |p: [i32; 3]| -> [f64; 3] { [0, 1, 2].map(|a| q.offset[a] + q.scale[a] * p[a] as f64) };
    let plan = Plan {
        fingerprint,
        attributes,
        points,
        scale: q.scale,
        offset: q.offset,
        coarsened: q.coarsened,
        warnings,
        min: to_real(staged.counts.min),
        max: to_real(staged.counts.max),
        cube: staged.cube,
        chunks,
        classes: Vec::new(),
        spacing_quantiles,
        scanners: summary.scanners,
        scanner_inputs: summary.scanner_inputs,
        crs: summary.crs,
    };
    Ok(Counted {
        plan,
        inputs: staged.inputs,
        lut,
        class_at,
    })
}

/// See `Plan::spacing_quantiles`. Cells too small to hold a patch of surface (most points in
/// cells of fewer than `MIN_CELL_POINTS`) say nothing of the spacing, so the grid is made
/// coarser until they do.
fn spacing_quantiles(counts: &Counts, cube: &Cube, scale: [f64; 3]) -> [f64; 3] {
    const MIN_CELL_POINTS: u64 = 16;
    let (mut level, shift) = grid_shape(cube);
    let mut side = (1u64 << shift.min(63)) as f64 * scale.iter().fold(0.0f64, |m, s| m.max(*s));
    let mut cells = counts.cells.clone();
    loop {
        let quantiles = weighted_quantiles(&cells, side);
        if quantiles[3] >= MIN_CELL_POINTS as f64 || level == 0 {
            return [quantiles[0], quantiles[1], quantiles[2]];
        }
        cells = coarser(&cells, level);
        level -= 1;
        side *= 2.0;
    }
}

/// Spacing at the 50th, 90th and 99th percentile of points, and the points-weighted median of
/// points per cell.
fn weighted_quantiles(cells: &[u64], side: f64) -> [f64; 4] {
    let mut occupied: Vec<(f64, u64)> = cells
        .iter()
        .filter(|&&m| m > 0)
        .map(|&m| (side / (m as f64).sqrt(), m))
        .collect();
    occupied.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: u64 = occupied.iter().map(|c| c.1).sum();
    let at = |share: f64| {
        let want = (total as f64 * share).ceil() as u64;
        let mut seen = 0;
        occupied
            .iter()
            .find(|c| {
                seen += c.1;
                seen >= want
            })
            .copied()
            .unwrap_or((0.0, 0))
    };
    [at(0.5).0, at(0.9).0, at(0.99).0, at(0.5).1 as f64]
}

/// The counting grid one level coarser (cells indexed x, y, z from the most significant).
fn coarser(cells: &[u64], level: u32) -> Vec<u64> {
    let (n, h) = (1usize << level, 1usize << (level - 1));
    let mut out = vec![0u64; h * h * h];
    for x in 0..n {
        for y in 0..n {
            for z in 0..n {
                out[((x / 2) * h + y / 2) * h + z / 2] += cells[(x * n + y) * n + z];
            }
        }
    }
    out
}

/// LAS and LAZ inputs: scale, offset and cube from their headers, so uncompressed records are
/// read in place and LAZ is decoded only once. `None` when an input is not LAS or LAZ, or a
/// header's bounds are unusable; `OutsideHeaderBounds` when a point shows the header wrong.
fn stage_from_headers(
    opts: &ConvertOptions,
    layout: &RowLayout,
    wd: &WorkDir,
    threads: usize,
    phases: &mut Phases,
) -> Result<Option<Staged>> {
    let is_las = |p: &PathBuf| {
        p.extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("las") || e.eq_ignore_ascii_case("laz"))
    };
    if !opts.inputs.iter().all(is_las) {
        return Ok(None);
    }
    let mut sources = Vec::new();
    let mut extents = Vec::new();
    let (mut min, mut max) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for path in &opts.inputs {
        let src = LasSource::open(path)?;
        let (lo, hi) = src.header_bounds();
        if (0..3).any(|a| !lo[a].is_finite() || !hi[a].is_finite() || lo[a] > hi[a]) {
            return Ok(None);
        }
        let (scale, offset) = src.transform();
        // One step of the input's grid on each side absorbs bounds written rounded; no record
        // lies beyond what its 32-bit integers can express, whatever the header says, so
        // bounds beyond that cannot coarsen the scale.
        let (mut lo, mut hi) = (lo, hi);
        for a in 0..3 {
            let ends = [i32::MIN, i32::MAX].map(|i| offset[a] + scale[a] * i as f64);
            let (least, most) = (ends[0].min(ends[1]), ends[0].max(ends[1]));
            let pad = scale[a].abs();
            lo[a] = (lo[a] - pad).clamp(least, most);
            hi[a] = (hi[a] + pad).clamp(least, most);
        }
        for a in 0..3 {
            min[a] = min[a].min(lo[a]);
            max[a] = max[a].max(hi[a]);
        }
        extents.push(SourceExtent {
            precision: Precision::Scaled { scale, offset },
            min: lo,
            max: hi,
        });
        sources.push(src);
    }
    let q = choose(&extents, min, max).map_err(|e| ConvertError::input(&opts.inputs[0], e))?;
    let cube = cube_for(&q, min, max);
    check_storable(&q, &cube, &opts.inputs[0])?;
    let compressed: u64 = sources
        .iter()
        .filter(|s| s.records_at().is_none())
        .map(|s| s.info().points)
        .sum();
    let mut counts = Counts::new(&cube);
    let read = |bar: &indicatif::ProgressBar| -> Result<Vec<RowInput>> {
        let mut inputs = Vec::new();
        for (i, mut src) in sources.into_iter().enumerate() {
            let conv = RecordToRow::new(&src, layout, &q, &cube);
            inputs.push(match src.records_at() {
                Some(start) => RowInput {
                    path: src.info().path.clone(),
                    start,
                    record_len: src.record_len(),
                    records: src.info().points,
                    convert: Some(conv),
                    blocks: None,
                },
                None => {
                    let rows = wd.decoded_rows(i);
                    decode_to_rows(&mut src, &conv, layout.stride, &rows, &mut counts, bar)?
                }
            });
        }
        Ok(inputs)
    };
    // Only decoding takes long enough to be a phase; in-place inputs are just opened.
    let inputs = if compressed > 0 {
        phases.timed("read", Some((compressed, "points")), read)?
    } else {
        read(&indicatif::ProgressBar::hidden())?
    };
    // Decoded inputs were counted as they were decoded; those read in place are counted here.
    let rest: Vec<&RowInput> = inputs.iter().filter(|i| !wd.holds(&i.path)).collect();
    let total = rest.iter().map(|i| i.records).sum();
    phases.timed("count", Some((total, "points")), |bar| {
        count(&rest, &mut counts, threads, opts.memory_limit, bar)
    })?;
    Ok(Some(Staged {
        inputs,
        q,
        cube,
        counts,
    }))
}

/// Any inputs: decode into f64 positions, measure, then quantize into rows.
fn stage_measured(
    opts: &ConvertOptions,
    attributes: &[Attribute],
    layout: &RowLayout,
    wd: &WorkDir,
    threads: usize,
    phases: &mut Phases,
    declared: u64,
) -> Result<Staged> {
    let (input, q, cube) = phases.timed("read", Some((declared, "points")), |bar| {
        let staging = wd.measured_staging();
        let scanned = scan(&opts.inputs, attributes, &staging, bar)?;
        if scanned.points == 0 {
            return Err(ConvertError::input(
                &opts.inputs[0],
                "the inputs hold no points",
            ));
        }
        let q = choose(&scanned.extents, scanned.min, scanned.max)
            .map_err(|e| ConvertError::input(&opts.inputs[0], e))?;
        let cube = cube_for(&q, scanned.min, scanned.max);
        check_storable(&q, &cube, &opts.inputs[0])?;
        let input = quantize_staging(
            &staging,
            staging_stride(attributes),
            &q,
            layout.stride,
            &wd.measured_rows(),
            bar,
        )?;
        fs::remove_file(&staging).map_err(io_err(&staging, "cannot remove staging file"))?;
        Ok((input, q, cube))
    })?;
    let mut counts = Counts::new(&cube);
    phases.timed("count", Some((declared, "points")), |bar| {
        count(&[&input], &mut counts, threads, opts.memory_limit, bar)
    })?;
    Ok(Staged {
        inputs: vec![input],
        q,
        cube,
        counts,
    })
}

/// Whether the header-derived cube is at least four times wider than the counted points need.
fn needlessly_large(staged: &Staged) -> bool {
    let c = &staged.counts;
    if (0..3).any(|a| c.min[a] > c.max[a]) {
        return false;
    }
    let extent = (0..3)
        .map(|a| c.max[a] as i64 - c.min[a] as i64 + 1)
        .max()
        .unwrap_or(1);
    let needed = (64 - (extent.max(2) - 1).leading_zeros()).max(1);
    staged.cube.bits >= needed + 2
}

/// Every real coordinate of the cube, and so every number the metadata derives from it, must be
/// a finite f64.
fn check_storable(q: &Quantization, cube: &Cube, path: &Path) -> Result<()> {
    for a in 0..3 {
        let ends = [cube.min[a], cube.min[a] + (1i64 << cube.bits)]
            .map(|i| q.offset[a] + q.scale[a] * i as f64);
        let spacing = q.scale[a] * (1u64 << cube.bits) as f64;
        if !ends.iter().all(|e| e.is_finite()) || !spacing.is_finite() {
            return Err(ConvertError::input(
                path,
                format!(
                    "the points' {} coordinates reach {:e}, too close to the largest number a coordinate can hold to be stored",
                    ["x", "y", "z"][a],
                    if ends[0].is_finite() {
                        ends[1]
                    } else {
                        ends[0]
                    }
                ),
            ));
        }
    }
    Ok(())
}

fn bounds_warning(path: &Path, record: u64) -> String {
    format!(
        "{}: point {record} lies outside the bounds the header declares; bounds measured from the points instead",
        path.display()
    )
}

/// Removes the staging files among `inputs` (those in the work directory).
fn remove_staging(inputs: &[RowInput], wd: &WorkDir) -> Result<()> {
    for i in inputs.iter().filter(|i| wd.holds(&i.path)) {
        fs::remove_file(&i.path).map_err(io_err(&i.path, "cannot remove staging file"))?;
    }
    Ok(())
}
