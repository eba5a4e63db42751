//! `strata convert`: the phases in order, in a temporary directory that becomes the dataset
//! only when complete. Chunks commit in plan order, so output is byte-for-byte reproducible,
//! and a journal of committed chunks lets `--resume` pick up after an interruption.

use crate::distribute::{Distribution, chunk_path, distribute};
use crate::error::{ConvertError, Result};
use crate::input::las::LasSource;
use crate::input::{PointSource, Precision};
use crate::merge::TopMerge;
use crate::plan::{Chunk, Counts, count, cube_for, max_chunk_points, plan_chunks, root_spacing};
use crate::progress::Progress;
use crate::quantize::{Quantization, SourceExtent, choose};
use crate::rows::{RecordToRow, RowInput};
use crate::sampling::Sampling;
use crate::scan::{scan, staging_stride, union_attributes};
use crate::staging::{decode_to_rows, quantize_staging};
use crate::sys::peak_rss_bytes;
use crate::tree::{ChunkMemory, FinishedNode, OpenNode, TreeBuilder};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fs::{self, File, OpenOptions};
use std::io::{BufRead, BufReader, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex};
use std::time::Instant;
use strata_format::{
    Attribute, Bounds, Cube, DatasetFile, FileInfo, Files, HierarchyInfo, Metadata, NodeKey,
    NodeRecord, OCTREE_MAGIC, PAGE_LEVELS, RowLayout, build_hierarchy,
};

#[derive(Debug, Clone)]
pub struct ConvertOptions {
    pub inputs: Vec<PathBuf>,
    pub output: PathBuf,
    pub memory_limit: u64,
    pub threads: usize,
    pub sampling: Sampling,
    pub overwrite: bool,
    pub resume: bool,
    pub quiet: bool,
}

#[derive(Debug, Clone, Serialize)]
pub struct PhaseTime {
    pub name: &'static str,
    pub seconds: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct ConvertSummary {
    pub output: PathBuf,
    pub points: u64,
    pub nodes: u64,
    pub depth: u32,
    pub chunks: usize,
    pub seconds: f64,
    pub points_per_second: f64,
    pub peak_memory_bytes: Option<u64>,
    pub dataset_bytes: u64,
    pub resumed_chunks: usize,
    pub phases: Vec<PhaseTime>,
    pub warnings: Vec<String>,
}

/// What the work directory must hold for `--resume`: the result of everything before indexing.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
struct Plan {
    fingerprint: String,
    attributes: Vec<Attribute>,
    points: u64,
    scale: [f64; 3],
    offset: [f64; 3],
    coarsened: bool,
    min: [f64; 3],
    max: [f64; 3],
    cube: Cube,
    chunks: Vec<Chunk>,
}

/// A node as the journal stores it: (level, x, y, z, points, offset, size, crc, child mask).
type JournalNode = (u8, u32, u32, u32, u32, u64, u32, u32, u8);

/// One committed chunk in the journal.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct JournalEntry {
    chunk: usize,
    end: u64,
    root_mask: u8,
    nodes: Vec<JournalNode>,
}

fn temp_dir_for(output: &Path) -> PathBuf {
    let mut name = output.file_name().unwrap_or_default().to_os_string();
    name.push(".strata-tmp");
    output.with_file_name(name)
}

fn fingerprint(opts: &ConvertOptions) -> String {
    let mut parts = Vec::new();
    for p in &opts.inputs {
        let meta = fs::metadata(p).ok();
        let len = meta.as_ref().map_or(0, |m| m.len());
        let mtime = meta
            .and_then(|m| m.modified().ok())
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map_or(0, |d| d.as_secs());
        let abs = fs::canonicalize(p).unwrap_or_else(|_| p.clone());
        parts.push(format!("{}:{len}:{mtime}", abs.display()));
    }
    parts.push(format!(
        "{}:{}:{}",
        opts.sampling.name(),
        opts.memory_limit,
        opts.threads
    ));
    parts.join("|")
}

fn io_err(path: &Path, what: &str) -> impl FnOnce(std::io::Error) -> ConvertError {
    let path = path.to_path_buf();
    let what = what.to_string();
    move |e| ConvertError::io(path, what, e)
}

pub fn convert(opts: &ConvertOptions) -> Result<ConvertSummary> {
    if opts.inputs.is_empty() {
        return Err(ConvertError::Usage("no input files given".into()));
    }
    if opts.output.exists() && !opts.overwrite {
        return Err(ConvertError::output(
            &opts.output,
            "output already exists (pass --overwrite to replace it)",
        ));
    }
    for input in &opts.inputs {
        if !input.is_file() {
            let what = if input.exists() {
                "input is not a regular file"
            } else {
                "input file does not exist"
            };
            return Err(ConvertError::input(input, what));
        }
    }
    let threads = opts.threads.max(1);
    // The LAZ decompressor runs on rayon's global pool; size it once to --threads.
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global();
    let tmp = temp_dir_for(&opts.output);
    let result = run(opts, &tmp, threads);
    if result.is_err() && !tmp.join("work").join("plan.json").exists() {
        let _ = fs::remove_dir_all(&tmp);
    }
    result
}

fn run(opts: &ConvertOptions, tmp: &Path, threads: usize) -> Result<ConvertSummary> {
    let start = Instant::now();
    let progress = Progress::new(opts.quiet);
    let work = tmp.join("work");
    let chunk_dir = work.join("chunks");
    let roots_dir = work.join("roots");
    let plan_path = work.join("plan.json");
    let journal_path = work.join("journal.jsonl");
    let octree_path = tmp.join(DatasetFile::Octree.name());
    let fp = fingerprint(opts);
    let mut phases = Vec::new();
    let mut warnings = Vec::new();

    let existing: Option<Plan> = if opts.resume {
        fs::read(&plan_path)
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok())
    } else {
        None
    };
    let plan = match existing {
        Some(plan) if plan.fingerprint == fp => plan,
        Some(_) => {
            return Err(ConvertError::output(
                tmp,
                "cannot resume: the inputs or options differ from the interrupted run (run without --resume to start over)",
            ));
        }
        None => {
            if tmp.exists() {
                fs::remove_dir_all(tmp).map_err(io_err(tmp, "cannot clear old work directory"))?;
            }
            fs::create_dir_all(&chunk_dir)
                .map_err(io_err(&chunk_dir, "cannot create work directory"))?;
            fs::create_dir_all(&roots_dir)
                .map_err(io_err(&roots_dir, "cannot create work directory"))?;
            let plan = prepare(
                opts,
                &work,
                &chunk_dir,
                threads,
                &progress,
                &mut phases,
                &mut warnings,
                fp,
            )?;
            let mut f =
                File::create(&octree_path).map_err(io_err(&octree_path, "cannot create"))?;
            f.write_all(OCTREE_MAGIC)
                .map_err(io_err(&octree_path, "cannot write"))?;
            File::create(&journal_path).map_err(io_err(&journal_path, "cannot create"))?;
            let plan_tmp = work.join("plan.json.part");
            fs::write(&plan_tmp, serde_json::to_vec(&plan).unwrap_or_default())
                .map_err(io_err(&plan_tmp, "cannot write"))?;
            fs::rename(&plan_tmp, &plan_path).map_err(io_err(&plan_path, "cannot write"))?;
            plan
        }
    };
    if plan.coarsened {
        warnings.push(format!(
            "the inputs span too far for 32-bit positions at their own resolution; scale coarsened to {:?}",
            plan.scale
        ));
    }
    let layout = RowLayout::new(plan.attributes.clone());
    let sampling = opts.sampling;

    // Index chunks, committing in plan order.
    let t = Instant::now();
    let mut journal = read_journal(&journal_path, plan.chunks.len());
    let resumed = journal.len();
    let end = journal.last().map_or(OCTREE_MAGIC.len() as u64, |j| j.end);
    let mut octree = OpenOptions::new()
        .write(true)
        .open(&octree_path)
        .map_err(io_err(&octree_path, "cannot open"))?;
    octree
        .set_len(end)
        .map_err(io_err(&octree_path, "cannot truncate"))?;
    octree
        .seek(SeekFrom::Start(end))
        .map_err(io_err(&octree_path, "cannot seek"))?;
    let remaining: u64 = plan.chunks[resumed..].iter().map(|c| c.points).sum();
    let bar = progress.phase("index", remaining, "points");
    let new_entries = index_chunks(
        &plan,
        &layout,
        sampling,
        threads,
        resumed,
        &chunk_dir,
        &roots_dir,
        &journal_path,
        &octree_path,
        &mut octree,
        end,
        &bar,
    )?;
    bar.finish_and_clear();
    journal.extend(new_entries);
    phases.push(PhaseTime {
        name: "index",
        seconds: t.elapsed().as_secs_f64(),
    });

    // Merge the levels above the chunks.
    let t = Instant::now();
    let mut records: BTreeMap<NodeKey, NodeRecord> = BTreeMap::new();
    for j in &journal {
        for &(level, x, y, z, count, offset, size, checksum, child_mask) in &j.nodes {
            records.insert(
                NodeKey { level, x, y, z },
                NodeRecord {
                    point_count: count,
                    offset,
                    size,
                    checksum,
                    child_mask,
                },
            );
        }
    }
    let mut at = journal.last().map_or(OCTREE_MAGIC.len() as u64, |j| j.end);
    let roots: Vec<(NodeKey, u8)> = journal
        .iter()
        .zip(&plan.chunks)
        .map(|(entry, chunk)| (chunk.key(), entry.root_mask))
        .collect();
    let load = |i: usize| {
        let p = roots_dir.join(format!("c{}.bin", journal[i].chunk));
        fs::read(&p).map_err(io_err(&p, "cannot read chunk root"))
    };
    let emit = |n: FinishedNode| {
        octree
            .write_all(&n.payload)
            .map_err(io_err(&octree_path, "cannot write"))?;
        records.insert(n.key, record_of(&n, at));
        at += n.payload.len() as u64;
        Ok(())
    };
    TopMerge::new(&roots, &layout, plan.cube, sampling, load, emit).run()?;
    phases.push(PhaseTime {
        name: "merge",
        seconds: t.elapsed().as_secs_f64(),
    });

    // Hierarchy, metadata, and the rename that makes the dataset appear.
    let t = Instant::now();
    octree
        .sync_all()
        .map_err(io_err(&octree_path, "cannot sync"))?;
    drop(octree);
    let (hier, root_off, root_size) = build_hierarchy(&records, PAGE_LEVELS);
    let hier_path = tmp.join(DatasetFile::Hierarchy.name());
    let mut hf = File::create(&hier_path).map_err(io_err(&hier_path, "cannot create"))?;
    hf.write_all(&hier)
        .map_err(io_err(&hier_path, "cannot write"))?;
    hf.sync_all().map_err(io_err(&hier_path, "cannot sync"))?;
    let points: u64 = records.values().map(|r| r.point_count as u64).sum();
    if points != plan.points {
        return Err(ConvertError::output(
            tmp,
            format!(
                "internal error: {} points read but {points} stored",
                plan.points
            ),
        ));
    }
    let depth = records.keys().map(|k| k.level as u32).max().unwrap_or(0);
    let q = Quantization {
        scale: plan.scale,
        offset: plan.offset,
        coarsened: plan.coarsened,
    };
    let to_real = |p: [i32; 3]| -> [f64; 3] {
        [0, 1, 2].map(|a| plan.offset[a] + plan.scale[a] * p[a] as f64)
    };
    let meta = Metadata {
        format: strata_format::FORMAT_NAME.into(),
        version: [strata_format::VERSION_MAJOR, strata_format::VERSION_MINOR],
        points,
        nodes: records.len() as u64,
        depth,
        scale: plan.scale,
        offset: plan.offset,
        bounds: Bounds {
            min: to_real(q.quantize(&plan.min)),
            max: to_real(q.quantize(&plan.max)),
        },
        cube: plan.cube,
        spacing: root_spacing(&plan.cube, plan.scale[0]),
        sampling: sampling.name().into(),
        attributes: plan.attributes.clone(),
        files: Files {
            hierarchy: FileInfo {
                name: DatasetFile::Hierarchy.name().into(),
                size: hier.len() as u64,
            },
            octree: FileInfo {
                name: DatasetFile::Octree.name().into(),
                size: at,
            },
        },
        hierarchy: HierarchyInfo {
            root_page_offset: root_off,
            root_page_size: root_size,
            page_levels: PAGE_LEVELS,
        },
        sources: opts
            .inputs
            .iter()
            .map(|p| {
                p.file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default()
            })
            .collect(),
        generator: format!("strata {}", env!("CARGO_PKG_VERSION")),
    };
    let meta_path = tmp.join(DatasetFile::Metadata.name());
    let mut mf = File::create(&meta_path).map_err(io_err(&meta_path, "cannot create"))?;
    mf.write_all(meta.to_json().as_bytes())
        .map_err(io_err(&meta_path, "cannot write"))?;
    mf.sync_all().map_err(io_err(&meta_path, "cannot sync"))?;
    fs::remove_dir_all(&work).map_err(io_err(&work, "cannot remove work directory"))?;
    if opts.output.exists() {
        let old = temp_dir_for(&opts.output).with_extension("old");
        fs::rename(&opts.output, &old).map_err(io_err(&opts.output, "cannot replace"))?;
        fs::remove_dir_all(&old).map_err(io_err(&old, "cannot remove the replaced dataset"))?;
    }
    fs::rename(tmp, &opts.output).map_err(io_err(
        &opts.output,
        "cannot move the finished dataset into place",
    ))?;
    phases.push(PhaseTime {
        name: "finish",
        seconds: t.elapsed().as_secs_f64(),
    });
    let seconds = start.elapsed().as_secs_f64();
    Ok(ConvertSummary {
        output: opts.output.clone(),
        points,
        nodes: records.len() as u64,
        depth,
        chunks: plan.chunks.len(),
        seconds,
        points_per_second: points as f64 / seconds.max(1e-9),
        peak_memory_bytes: peak_rss_bytes(),
        dataset_bytes: at + hier.len() as u64,
        resumed_chunks: resumed,
        phases,
        warnings,
    })
}

fn record_of(n: &FinishedNode, offset: u64) -> NodeRecord {
    NodeRecord {
        point_count: n.point_count,
        offset,
        size: n.payload.len() as u32,
        checksum: n.crc,
        child_mask: n.child_mask,
    }
}

/// Every input as rows the count and distribute phases can read, with the dataset's scale,
/// offset and cube.
struct Staged {
    inputs: Vec<RowInput>,
    q: Quantization,
    cube: Cube,
    /// What decoding already counted: the inputs in the work directory.
    counted: Counts,
}

/// LAS and LAZ inputs: scale, offset and cube from their headers, so uncompressed records are
/// read in place and LAZ is decoded only once. `None` when an input is not LAS or LAZ, or a
/// header's bounds are unusable.
fn stage_from_headers(
    opts: &ConvertOptions,
    layout: &RowLayout,
    work: &Path,
    progress: &Progress,
    phases: &mut Vec<PhaseTime>,
    warnings: &mut Vec<String>,
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
        // One step of the input's grid on each side absorbs bounds written rounded.
        let lo = [0, 1, 2].map(|a| lo[a] - scale[a].abs());
        let hi = [0, 1, 2].map(|a| hi[a] + scale[a].abs());
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
    let q = choose(&extents, min, max);
    let cube = cube_for(&q, min, max);
    let t = Instant::now();
    let compressed: u64 = sources
        .iter()
        .filter(|s| s.records_at().is_none())
        .map(|s| s.info().points)
        .sum();
    let bar = progress.phase("read", compressed, "points");
    let mut inputs = Vec::new();
    let mut counted = Counts::new(&cube);
    for (i, mut src) in sources.into_iter().enumerate() {
        let conv = RecordToRow::new(&src, layout, &q, &cube);
        let input = match src.records_at() {
            Some(start) => RowInput {
                path: src.info().path.clone(),
                start,
                record_len: src.record_len(),
                records: src.info().points,
                convert: Some(conv),
            },
            None => {
                let staging = work.join(format!("rows{i}.bin"));
                match decode_to_rows(&mut src, &conv, layout.stride, &staging, &mut counted, &bar) {
                    Err(ConvertError::OutsideHeaderBounds { path, record }) => {
                        warnings.push(bounds_warning(&path, record));
                        remove_staging(&inputs, work)?;
                        let _ = fs::remove_file(&staging);
                        return Ok(None);
                    }
                    r => r?,
                }
            }
        };
        inputs.push(input);
    }
    bar.finish_and_clear();
    if compressed > 0 {
        phases.push(PhaseTime {
            name: "read",
            seconds: t.elapsed().as_secs_f64(),
        });
    }
    Ok(Some(Staged {
        inputs,
        q,
        cube,
        counted,
    }))
}

/// Any inputs: decode into f64 positions, measure, then quantize into rows.
fn stage_measured(
    opts: &ConvertOptions,
    attributes: &[Attribute],
    layout: &RowLayout,
    work: &Path,
    progress: &Progress,
    phases: &mut Vec<PhaseTime>,
    declared: u64,
) -> Result<Staged> {
    let t = Instant::now();
    let staging = work.join("staging.bin");
    let bar = progress.phase("read", declared, "points");
    let scanned = scan(&opts.inputs, attributes, &staging, &bar)?;
    bar.finish_and_clear();
    if scanned.points == 0 {
        return Err(ConvertError::input(
            &opts.inputs[0],
            "the inputs hold no points",
        ));
    }
    let q = choose(&scanned.extents, scanned.min, scanned.max);
    let cube = cube_for(&q, scanned.min, scanned.max);
    let rows = work.join("rows.bin");
    let input = quantize_staging(
        &staging,
        staging_stride(attributes),
        &q,
        layout.stride,
        &rows,
        &bar,
    )?;
    fs::remove_file(&staging).map_err(io_err(&staging, "cannot remove staging file"))?;
    phases.push(PhaseTime {
        name: "read",
        seconds: t.elapsed().as_secs_f64(),
    });
    Ok(Staged {
        inputs: vec![input],
        q,
        counted: Counts::new(&cube),
        cube,
    })
}

/// Read, count, plan and distribute.
#[allow(clippy::too_many_arguments)]
fn prepare(
    opts: &ConvertOptions,
    work: &Path,
    chunk_dir: &Path,
    threads: usize,
    progress: &Progress,
    phases: &mut Vec<PhaseTime>,
    warnings: &mut Vec<String>,
    fingerprint: String,
) -> Result<Plan> {
    let (attributes, declared) = union_attributes(&opts.inputs)?;
    let layout = RowLayout::new(attributes.clone());
    let from_headers = stage_from_headers(opts, &layout, work, progress, phases, warnings)?;
    let t = Instant::now();
    // Inputs read in place are counted here; decoded ones were counted as they were decoded.
    let count_rest = |staged: &mut Staged| {
        let rest: Vec<&RowInput> = staged
            .inputs
            .iter()
            .filter(|i| !i.path.starts_with(work))
            .collect();
        let bar = progress.phase("count", rest.iter().map(|i| i.records).sum(), "points");
        let r = count(&rest, &mut staged.counted, threads, &bar);
        bar.finish_and_clear();
        r
    };
    let mut counted = None;
    if let Some(mut staged) = from_headers {
        match count_rest(&mut staged) {
            Err(ConvertError::OutsideHeaderBounds { path, record }) => {
                warnings.push(bounds_warning(&path, record));
                remove_staging(&staged.inputs, work)?;
            }
            r => counted = Some(r.map(|_| staged)?),
        }
    }
    let staged = match counted {
        Some(s) => s,
        None => {
            let mut staged =
                stage_measured(opts, &attributes, &layout, work, progress, phases, declared)?;
            let bar = progress.phase("count", declared, "points");
            let all: Vec<&RowInput> = staged.inputs.iter().collect();
            let mut counts = Counts::new(&staged.cube);
            count(&all, &mut counts, threads, &bar)?;
            bar.finish_and_clear();
            staged.counted = counts;
            staged
        }
    };
    let counts = &staged.counted;
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
    let max_chunk = max_chunk_points(opts.memory_limit, threads, layout.stride).min(balanced);
    let (chunks, lut) = plan_chunks(&counts.cells, &staged.cube, max_chunk);
    phases.push(PhaseTime {
        name: "count",
        seconds: t.elapsed().as_secs_f64(),
    });

    let t = Instant::now();
    let bar = progress.phase("distribute", points, "points");
    distribute(
        &Distribution {
            inputs: &staged.inputs,
            stride: layout.stride,
            cube: &staged.cube,
            lut: &lut,
            chunk_count: chunks.len(),
            chunk_dir,
            buffer_budget: (opts.memory_limit / 6).min(256 << 20),
            threads,
        },
        &bar,
    )?;
    bar.finish_and_clear();
    remove_staging(&staged.inputs, work)?;
    phases.push(PhaseTime {
        name: "distribute",
        seconds: t.elapsed().as_secs_f64(),
    });
    let q = staged.q;
    let to_real =
        |p: [i32; 3]| -> [f64; 3] { [0, 1, 2].map(|a| q.offset[a] + q.scale[a] * p[a] as f64) };
    Ok(Plan {
        fingerprint,
        attributes,
        points,
        scale: q.scale,
        offset: q.offset,
        coarsened: q.coarsened,
        min: to_real(counts.min),
        max: to_real(counts.max),
        cube: staged.cube,
        chunks,
    })
}

fn bounds_warning(path: &Path, record: u64) -> String {
    format!(
        "{}: point {record} lies outside the bounds the header declares; bounds measured from the points instead",
        path.display()
    )
}

/// Removes the staging files among `inputs` (those in the work directory).
fn remove_staging(inputs: &[RowInput], work: &Path) -> Result<()> {
    for i in inputs.iter().filter(|i| i.path.starts_with(work)) {
        fs::remove_file(&i.path).map_err(io_err(&i.path, "cannot remove staging file"))?;
    }
    Ok(())
}

/// The valid prefix of the journal: whole lines for chunks 0, 1, 2... in order.
fn read_journal(path: &Path, chunks: usize) -> Vec<JournalEntry> {
    let Ok(f) = File::open(path) else {
        return Vec::new();
    };
    let mut out: Vec<JournalEntry> = Vec::new();
    for line in BufReader::new(f).lines() {
        let Ok(line) = line else { break };
        match serde_json::from_str::<JournalEntry>(&line) {
            Ok(e) if e.chunk == out.len() && e.chunk < chunks => out.push(e),
            _ => break,
        }
    }
    out
}

struct CommitState<'a> {
    octree: &'a mut File,
    journal: File,
    next: usize,
    ready: BTreeMap<usize, (Vec<FinishedNode>, Vec<u8>, u8)>,
    entries: Vec<JournalEntry>,
    end: u64,
    error: Option<ConvertError>,
}

#[allow(clippy::too_many_arguments)]
fn index_chunks(
    plan: &Plan,
    layout: &RowLayout,
    sampling: Sampling,
    threads: usize,
    first: usize,
    chunk_dir: &Path,
    roots_dir: &Path,
    journal_path: &Path,
    octree_path: &Path,
    octree: &mut File,
    end: u64,
    bar: &indicatif::ProgressBar,
) -> Result<Vec<JournalEntry>> {
    let n = plan.chunks.len();
    // Rewrite the journal as its valid prefix so appends follow whole lines.
    let valid = read_journal(journal_path, n);
    let mut text = String::new();
    for e in valid.iter().take(first) {
        text.push_str(&serde_json::to_string(e).unwrap_or_default());
        text.push('\n');
    }
    fs::write(journal_path, text).map_err(io_err(journal_path, "cannot write journal"))?;
    let journal = OpenOptions::new()
        .append(true)
        .open(journal_path)
        .map_err(io_err(journal_path, "cannot open journal"))?;
    let next_chunk = AtomicUsize::new(first);
    let abort = AtomicBool::new(false);
    let state = Mutex::new(CommitState {
        octree,
        journal,
        next: first,
        ready: BTreeMap::new(),
        entries: Vec::new(),
        end,
        error: None,
    });
    let turn = Condvar::new();
    let fail = |state: &Mutex<CommitState>, e: ConvertError| {
        abort.store(true, Ordering::SeqCst);
        if let Ok(mut s) = state.lock()
            && s.error.is_none()
        {
            s.error = Some(e);
        }
        turn.notify_all();
    };
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| {
                let mut memory: Option<ChunkMemory> = None;
                loop {
                    if abort.load(Ordering::SeqCst) {
                        return;
                    }
                    let i = next_chunk.fetch_add(1, Ordering::SeqCst);
                    if i >= n {
                        return;
                    }
                    // Wait so at most `threads` chunks are ahead of the commit point.
                    {
                        let Ok(mut s) = state.lock() else { return };
                        while i >= s.next + threads && !abort.load(Ordering::SeqCst) {
                            s = match turn.wait(s) {
                                Ok(s) => s,
                                Err(_) => return,
                            };
                        }
                    }
                    let mut mem = memory.take().unwrap_or_default();
                    if let Err(e) = read_chunk(chunk_dir, i, threads, &mut mem.rows) {
                        return fail(&state, e);
                    }
                    let mut builder = TreeBuilder::with_memory(mem, layout, plan.cube, sampling);
                    let root: OpenNode = builder.build_chunk(plan.chunks[i].key());
                    let root_rows = builder.rows_of(&root);
                    let finished = std::mem::take(&mut builder.finished);
                    memory = Some(builder.into_memory());
                    let Ok(mut s) = state.lock() else { return };
                    s.ready.insert(i, (finished, root_rows, root.child_mask));
                    while let Some(done) = {
                        let next = s.next;
                        s.ready.remove(&next)
                    } {
                        let idx = s.next;
                        let s = &mut *s;
                        match commit(
                            idx,
                            done,
                            &mut s.end,
                            s.octree,
                            octree_path,
                            roots_dir,
                            &mut s.journal,
                            journal_path,
                        ) {
                            Ok(entry) => {
                                s.entries.push(entry);
                                for part in 0..threads {
                                    let _ = fs::remove_file(chunk_path(chunk_dir, idx, part));
                                }
                                bar.inc(plan.chunks[idx].points);
                                s.next += 1;
                            }
                            Err(e) => {
                                s.error.get_or_insert(e);
                                abort.store(true, Ordering::SeqCst);
                                break;
                            }
                        }
                    }
                    turn.notify_all();
                }
            });
        }
    });
    let s = state
        .into_inner()
        .map_err(|_| ConvertError::Usage("a conversion worker panicked".into()))?;
    if let Some(e) = s.error {
        return Err(e);
    }
    Ok(s.entries)
}

/// A chunk's rows: its part files in order (a part with no rows has no file).
fn read_chunk(dir: &Path, chunk: usize, parts: usize, rows: &mut Vec<u8>) -> Result<()> {
    let paths: Vec<PathBuf> = (0..parts).map(|p| chunk_path(dir, chunk, p)).collect();
    let total: u64 = paths
        .iter()
        .filter_map(|p| fs::metadata(p).ok())
        .map(|m| m.len())
        .sum();
    rows.clear();
    rows.reserve(total as usize);
    for path in paths {
        match File::open(&path) {
            Ok(mut f) => {
                use std::io::Read;
                f.read_to_end(rows)
                    .map_err(io_err(&path, "cannot read chunk"))?;
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(ConvertError::io(&path, "cannot read chunk", e)),
        }
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn commit(
    chunk: usize,
    (finished, root_rows, root_mask): (Vec<FinishedNode>, Vec<u8>, u8),
    end: &mut u64,
    octree: &mut File,
    octree_path: &Path,
    roots_dir: &Path,
    journal: &mut File,
    journal_path: &Path,
) -> Result<JournalEntry> {
    let mut nodes = Vec::with_capacity(finished.len());
    for n in &finished {
        octree
            .write_all(&n.payload)
            .map_err(io_err(octree_path, "cannot write"))?;
        let r = record_of(n, *end);
        nodes.push((
            n.key.level,
            n.key.x,
            n.key.y,
            n.key.z,
            r.point_count,
            r.offset,
            r.size,
            r.checksum,
            r.child_mask,
        ));
        *end += n.payload.len() as u64;
    }
    let root_path = roots_dir.join(format!("c{chunk}.bin"));
    fs::write(&root_path, &root_rows).map_err(io_err(&root_path, "cannot write chunk root"))?;
    let entry = JournalEntry {
        chunk,
        end: *end,
        root_mask,
        nodes,
    };
    let mut line = serde_json::to_string(&entry).unwrap_or_default();
    line.push('\n');
    journal
        .write_all(line.as_bytes())
        .map_err(io_err(journal_path, "cannot write journal"))?;
    Ok(entry)
}
