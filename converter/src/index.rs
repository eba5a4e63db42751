//! Indexing: each chunk's rows are read, handed to the per-chunk step with their halo, and
//! built into a tree, `threads` chunks at a time; chunks commit in plan order, so the octree
//! file is the same whatever the timing.

use crate::chunk_step::{ChunkRows, ChunkStep, GridBox, Halo};
use crate::error::{ConvertError, Result, panic_message, spawn_worker};
use crate::halo::Halos;
use crate::journal::{BuiltChunk, Committer, JournalEntry};
use crate::plan::{index_room, index_workers};
use crate::prepare::Plan;
use crate::rowfile::{Scratch, read_rows};
use crate::sampling::Sampling;
use crate::tree::{ChunkMemory, TreeBuilder};
use crate::workdir::WorkDir;
use indicatif::ProgressBar;
use std::collections::BTreeMap;
use std::fs;
use std::ops::Range;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex, MutexGuard};
use strata_format::RowLayout;

/// What indexing needs besides the chunk files.
pub struct Indexing<'a> {
    pub plan: &'a Plan,
    pub layout: &'a RowLayout,
    pub sampling: Sampling,
    /// Workers asked for; fewer index at once where the memory limit holds fewer chunks
    /// (`index_workers`).
    pub threads: usize,
    pub memory_limit: u64,
    /// Part files per chunk (`Share::parts`).
    pub parts: usize,
    pub step: &'a dyn ChunkStep,
    pub halos: &'a Halos,
    pub wd: &'a WorkDir,
}

struct CommitState {
    /// `None` while a worker commits, outside the lock.
    committer: Option<Committer>,
    /// The first chunk not yet handed to the committer.
    next: usize,
    /// A commit failed: no later chunk may commit.
    commit_failed: bool,
    ready: BTreeMap<usize, BuiltChunk>,
    entries: Vec<JournalEntry>,
    error: Option<ConvertError>,
}

/// Indexes chunks `chunks` (all that are left of the plan, or of a task) and commits them
/// after `committer`'s; returns their journal entries and the committer, positioned after the
/// last one.
pub fn index_chunks(
    ix: &Indexing,
    chunks: Range<usize>,
    committer: Committer,
    bar: &ProgressBar,
) -> Result<(Vec<JournalEntry>, Committer)> {
    let (first, n) = (chunks.start, chunks.end);
    let threads = workers_for(ix, chunks.clone())?;
    let next_chunk = AtomicUsize::new(first);
    let abort = AtomicBool::new(false);
    let state = Mutex::new(CommitState {
        committer: Some(committer),
        next: first,
        commit_failed: false,
        ready: BTreeMap::new(),
        entries: Vec::new(),
        error: None,
    });
    let turn = Condvar::new();
    let fail = |e: ConvertError| {
        abort.store(true, Ordering::SeqCst);
        if let Ok(mut s) = state.lock()
            && s.error.is_none()
        {
            s.error = Some(e);
        }
        turn.notify_all();
    };
    std::thread::scope(|scope| {
        for k in 0..threads {
            let started = spawn_worker(scope, "indexing chunks", k, || {
                let mut memory: Option<ChunkMemory> = None;
                let mut halo = Halo::default();
                loop {
                    if abort.load(Ordering::SeqCst) {
                        return;
                    }
                    let i = next_chunk.fetch_add(1, Ordering::SeqCst);
                    if i >= n {
                        return;
                    }
                    // Wait so at most `threads` chunks are ahead of those handed to the
                    // committer.
                    {
                        let Ok(mut s) = state.lock() else { return };
                        while i >= s.next + threads && !abort.load(Ordering::SeqCst) {
                            s = match turn.wait(s) {
                                Ok(s) => s,
                                Err(_) => return,
                            };
                        }
                    }
                    let mem = memory.take().unwrap_or_default();
                    // A panic is a bug of ours, not a fault of the input: say which chunk.
                    let built =
                        catch_unwind(AssertUnwindSafe(|| build_chunk(ix, i, mem, &mut halo)))
                            .unwrap_or_else(|p| {
                                Err(chunk_fault(ix.plan, i, panic_message(p.as_ref())))
                            });
                    let built = match built {
                        Ok((built, mem)) => {
                            memory = Some(mem);
                            built
                        }
                        Err(e) => return fail(e),
                    };
                    let Ok(mut s) = state.lock() else { return };
                    s.ready.insert(i, built);
                    commit_ready(ix, s, &state, &turn, &abort, bar);
                }
            });
            if let Err(e) = started {
                fail(e);
                break;
            }
        }
    });
    let s = state.into_inner().map_err(|_| {
        ConvertError::internal("indexing chunks", "a worker panicked while committing")
    })?;
    if let Some(e) = s.error {
        return Err(e);
    }
    let committer = s.committer.ok_or_else(|| {
        ConvertError::internal("indexing chunks", "a worker panicked while committing")
    })?;
    Ok((s.entries, committer))
}

/// Reads chunk `i`, runs the step on it and builds its tree, in `mem`'s buffers, which it
/// hands back for the next chunk.
fn build_chunk(
    ix: &Indexing,
    i: usize,
    mut mem: ChunkMemory,
    halo: &mut Halo,
) -> Result<(BuiltChunk, ChunkMemory)> {
    read_chunk(ix, i, &mut mem.rows)?;
    ix.halos.gather(ix.wd, i, halo)?;
    let chunk = &ix.plan.chunks[i];
    let step = ix.step.process(
        &mut ChunkRows {
            index: i,
            bounds: GridBox::of_chunk(chunk, &ix.plan.cube),
            scale: ix.plan.scale,
            offset: ix.plan.offset,
            layout: ix.layout,
            rows: &mut mem.rows,
            scanners: &ix.plan.scanners,
        },
        halo,
    )?;
    let mut builder = TreeBuilder::with_memory(mem, ix.layout, ix.plan.cube, ix.sampling);
    let root = builder.build_chunk(chunk.key());
    let root_rows = builder.rows_of(&root);
    let finished = std::mem::take(&mut builder.finished);
    Ok((
        BuiltChunk {
            finished,
            root_rows,
            stride: ix.layout.stride,
            root_mask: root.child_mask,
            step,
        },
        builder.into_memory(),
    ))
}

/// Commits the chunks that are ready, in plan order from the commit point on, unless another
/// worker is committing (it takes them when it is done). The writing happens outside the lock,
/// and a chunk counts as handed over as it starts, so that a worker waiting for its turn
/// starts its next chunk instead of waiting out the writes.
fn commit_ready<'s>(
    ix: &Indexing,
    mut s: MutexGuard<'s, CommitState>,
    state: &'s Mutex<CommitState>,
    turn: &Condvar,
    abort: &AtomicBool,
    bar: &ProgressBar,
) {
    loop {
        // After a failed commit nothing later may commit: a resumed run starts at the failed
        // chunk, and needs the files of those after it. (A chunk that failed to build stops
        // nothing before it.)
        if s.commit_failed || s.committer.is_none() {
            return;
        }
        let idx = s.next;
        let Some(done) = s.ready.remove(&idx) else {
            return;
        };
        let Some(mut committer) = s.committer.take() else {
            return;
        };
        s.next += 1;
        turn.notify_all();
        drop(s);
        let committed = catch_unwind(AssertUnwindSafe(|| {
            committer.commit(ix.wd, idx, done).and_then(|entry| {
                // Consumed: its files go now, so the work files shrink as the dataset grows.
                // Shared ones stay: other tasks read them to write their own bands.
                for part in (0..ix.parts).filter(|_| ix.wd.owns_chunks()) {
                    let _ = fs::remove_file(ix.wd.chunk_part(idx, part));
                }
                ix.halos.release(ix.wd, idx)?;
                bar.inc(ix.plan.chunks[idx].points);
                Ok(entry)
            })
        }))
        .unwrap_or_else(|p| {
            Err(ConvertError::internal(
                format!("committing chunk {idx}"),
                panic_message(p.as_ref()),
            ))
        });
        s = match state.lock() {
            Ok(s) => s,
            Err(_) => return,
        };
        s.committer = Some(committer);
        match committed {
            Ok(entry) => s.entries.push(entry),
            Err(e) => {
                s.commit_failed = true;
                s.error.get_or_insert(e);
                abort.store(true, Ordering::SeqCst);
                turn.notify_all();
                return;
            }
        }
    }
}

/// Workers that index `chunks` at once (`index_workers`, for their largest chunk and their
/// widest halo); an error where one chunk with its halo does not fit in the memory limit.
fn workers_for(ix: &Indexing, chunks: Range<usize>) -> Result<usize> {
    let stride = ix.layout.stride;
    let (mut largest, mut widest) = (0, (0, 0));
    for i in chunks {
        largest = largest.max(ix.plan.chunks.get(i).map_or(0, |c| c.points));
        if ix.halos.needed() {
            let rows = ix.halos.rows_for(ix.wd, i)?;
            widest = widest.max((rows, i));
        }
    }
    let step = ix.step.bytes_per_point(stride);
    index_workers(ix.memory_limit, ix.threads, stride, step, largest, widest.0).map_err(|need| {
        let (rows, i) = widest;
        ConvertError::Usage(format!(
            "the {rows} points within {} of chunk {i} {}, which its normals are estimated from, \
             take {} MiB with the largest chunk's own, more than the {} MiB --memory-limit {} MiB \
             leaves for indexing; give a smaller --normal-radius or a larger --memory-limit",
            ix.halos.margin(),
            chunk_place(ix.plan, i),
            need.div_ceil(1 << 20),
            index_room(ix.memory_limit) >> 20,
            ix.memory_limit >> 20
        ))
    })
}

/// The fault of a worker that panicked on chunk `i`, named with the chunk's real bounds.
fn chunk_fault(plan: &Plan, i: usize, message: String) -> ConvertError {
    ConvertError::internal(
        format!("indexing chunk {i} {}", chunk_place(plan, i)),
        message,
    )
}

/// Where chunk `i` lies, in real units.
fn chunk_place(plan: &Plan, i: usize) -> String {
    let Some(chunk) = plan.chunks.get(i) else {
        return String::new();
    };
    let b = GridBox::of_chunk(chunk, &plan.cube);
    let (lo, hi) = (plan.to_real(b.min), plan.to_real(b.max));
    format!(
        "(x {:.3}..{:.3}, y {:.3}..{:.3}, z {:.3}..{:.3})",
        lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]
    )
}

/// A chunk's rows: its part files in order (a part with no rows has no file).
fn read_chunk(ix: &Indexing, chunk: usize, rows: &mut Vec<u8>) -> Result<()> {
    let stride = ix.layout.stride;
    rows.clear();
    // Its size is known: reserved at once rather than grown (and copied) part by part. The
    // count comes from the plan, a file: one too large is an error, not an abort.
    let points = ix.plan.chunks.get(chunk).map_or(0, |c| c.points);
    let bytes = usize::try_from(points)
        .ok()
        .and_then(|p| p.checked_mul(stride));
    if bytes.is_none_or(|b| rows.try_reserve(b).is_err()) {
        return Err(ConvertError::input(
            ix.wd.plan(),
            format!(
                "chunk {chunk}'s {points} points, as the plan counts them, do not fit in memory ({stride} bytes each)"
            ),
        ));
    }
    let mut scratch = Scratch::default();
    for part in 0..ix.parts {
        read_rows(&ix.wd.chunk_part(chunk, part), stride, rows, &mut scratch)?;
    }
    // A part file that is missing reads as no rows: what the plan counted says whether one is.
    let read = rows.len() / stride.max(1);
    if read as u64 != points {
        return Err(ConvertError::input(
            ix.wd.chunk_part(chunk, 0),
            format!(
                "chunk {chunk}'s work files hold {read} points where the plan counted {points}; they were removed or cut short since they were written: convert again from the start (or, for a plan's task, make the plan again)"
            ),
        ));
    }
    Ok(())
}
