//! `strata convert`: the phases in order, in a temporary directory that becomes the dataset
//! only when complete. Chunks commit in plan order, so output is byte-for-byte reproducible,
//! and a journal of committed chunks lets `--resume` pick up after an interruption.

use crate::distribute::{chunk_path, distribute};
use crate::error::{ConvertError, Result};
use crate::plan::{Chunk, count, cube_for, max_chunk_points, plan_chunks, root_spacing};
use crate::progress::Progress;
use crate::quantize::{Quantization, choose};
use crate::sampling::Sampling;
use crate::scan::{scan, staging_stride, union_attributes};
use crate::sys::peak_rss_bytes;
use crate::tree::{FinishedNode, OpenNode, TreeBuilder, merge_top};
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
            let plan = prepare(opts, &work, &chunk_dir, threads, &progress, &mut phases, fp)?;
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
    let mut roots = Vec::with_capacity(plan.chunks.len());
    for (entry, chunk) in journal.iter().zip(&plan.chunks) {
        let p = roots_dir.join(format!("c{}.bin", entry.chunk));
        let rows = fs::read(&p).map_err(io_err(&p, "cannot read chunk root"))?;
        roots.push((chunk.key(), rows, entry.root_mask));
    }
    let top = merge_top(roots, &layout, plan.cube, sampling);
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
    for n in &top {
        octree
            .write_all(&n.payload)
            .map_err(io_err(&octree_path, "cannot write"))?;
        records.insert(n.key, record_of(n, at));
        at += n.payload.len() as u64;
    }
    octree
        .sync_all()
        .map_err(io_err(&octree_path, "cannot sync"))?;
    drop(octree);
    phases.push(PhaseTime {
        name: "merge",
        seconds: t.elapsed().as_secs_f64(),
    });

    // Hierarchy, metadata, and the rename that makes the dataset appear.
    let t = Instant::now();
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

/// Scan, quantize, count, plan and distribute.
fn prepare(
    opts: &ConvertOptions,
    work: &Path,
    chunk_dir: &Path,
    threads: usize,
    progress: &Progress,
    phases: &mut Vec<PhaseTime>,
    fingerprint: String,
) -> Result<Plan> {
    let t = Instant::now();
    let (attributes, declared) = union_attributes(&opts.inputs)?;
    let staging = work.join("staging.bin");
    let bar = progress.phase("read", declared, "points");
    let scanned = scan(&opts.inputs, &attributes, &staging, &bar)?;
    bar.finish_and_clear();
    phases.push(PhaseTime {
        name: "read",
        seconds: t.elapsed().as_secs_f64(),
    });
    if scanned.points == 0 {
        return Err(ConvertError::input(
            &opts.inputs[0],
            "the inputs hold no points",
        ));
    }
    if scanned.points > u32::MAX as u64 * 64 {
        return Err(ConvertError::Usage(format!(
            "{} points is more than this converter supports",
            scanned.points
        )));
    }
    let q = choose(&scanned.extents, scanned.min, scanned.max);
    let cube = cube_for(&q, scanned.min, scanned.max);
    let stride = staging_stride(&attributes);
    let layout = RowLayout::new(attributes.clone());

    let t = Instant::now();
    let bar = progress.phase("count", scanned.points, "points");
    let counts = count(&staging, stride, &q, &cube, &bar)?;
    bar.finish_and_clear();
    let max_chunk = max_chunk_points(opts.memory_limit, threads, layout.stride);
    let (chunks, lut) = plan_chunks(&counts, &cube, max_chunk);
    drop(counts);
    phases.push(PhaseTime {
        name: "count",
        seconds: t.elapsed().as_secs_f64(),
    });

    let t = Instant::now();
    let bar = progress.phase("distribute", scanned.points, "points");
    let buffer_budget = (opts.memory_limit / 6).min(256 << 20);
    distribute(
        &staging,
        stride,
        layout.stride,
        &q,
        &cube,
        &lut,
        chunks.len(),
        chunk_dir,
        buffer_budget,
        &bar,
    )?;
    bar.finish_and_clear();
    fs::remove_file(&staging).map_err(io_err(&staging, "cannot remove staging file"))?;
    phases.push(PhaseTime {
        name: "distribute",
        seconds: t.elapsed().as_secs_f64(),
    });
    Ok(Plan {
        fingerprint,
        attributes,
        points: scanned.points,
        scale: q.scale,
        offset: q.offset,
        coarsened: q.coarsened,
        min: scanned.min,
        max: scanned.max,
        cube,
        chunks,
    })
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
                    let path = chunk_path(chunk_dir, i);
                    let rows = match fs::read(&path) {
                        Ok(r) => r,
                        Err(e) => {
                            return fail(&state, ConvertError::io(&path, "cannot read chunk", e));
                        }
                    };
                    let count = rows.len() / layout.stride;
                    let mut builder = TreeBuilder::new(&rows, layout, plan.cube, sampling);
                    let root: OpenNode =
                        builder.build(plan.chunks[i].key(), (0..count as u32).collect());
                    let root_rows = builder.rows_of(&root);
                    let finished = std::mem::take(&mut builder.finished);
                    drop(rows);
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
                                let _ = fs::remove_file(chunk_path(chunk_dir, idx));
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
