//! `strata convert --plan PLAN --task K`: distributes the plan's shares no other task is
//! distributing (`share`), then builds task K's chunks in its own folder of the plan (no two
//! tasks write the same file) and renames that folder into its result. A task run
//! again continues what an interrupted run of it left, as `--resume` does; a finished task is
//! not run again.

use super::share::{distribute_shares, shared_chunks};
use super::{TaskPlan, task_dirs, task_workdir};
use crate::chunk_step::ChunkStep;
use crate::distribute::Share;
use crate::error::{ConvertError, Result, io_err};
use crate::halo::Halos;
use crate::index::{Indexing, index_chunks};
use crate::journal::{Committer, read_resumable_journal_of, save_plan};
use crate::progress::{PhaseTime, Phases, Progress};
use crate::workdir::WorkDir;
use serde::Serialize;
use std::fs::{self, File, TryLockError};
use std::ops::Range;
use std::path::Path;
use std::time::Instant;
use strata_format::RowLayout;

/// What a task reports.
#[derive(Debug, Clone, Serialize)]
pub struct TaskSummary {
    pub task: usize,
    pub tasks: usize,
    pub chunks: Range<usize>,
    pub points: u64,
    /// Chunks an earlier, interrupted run of the task had finished.
    pub resumed_chunks: usize,
    /// Shares of the distribution this run distributed (the others another task did, or an
    /// earlier run).
    pub shares_distributed: usize,
    /// The task had finished before: nothing was done.
    pub already_done: bool,
    pub seconds: f64,
    /// Wall time of each phase the task ran.
    pub phases: Vec<PhaseTime>,
}

pub fn run_task(plan_dir: &Path, k: usize, quiet: bool) -> Result<TaskSummary> {
    let start = Instant::now();
    let tp = TaskPlan::load(plan_dir)?;
    let Some(range) = tp.tasks.get(k).cloned() else {
        return Err(ConvertError::Usage(format!(
            "task {k} is not in the plan {}: it has tasks 0 to {}",
            plan_dir.display(),
            tp.tasks.len().saturating_sub(1)
        )));
    };
    let points = tp.plan.chunks[range.clone()].iter().map(|c| c.points).sum();
    let summary = |resumed_chunks, shares_distributed, already_done, phases| TaskSummary {
        task: k,
        tasks: tp.tasks.len(),
        chunks: range.clone(),
        points,
        resumed_chunks,
        shares_distributed,
        already_done,
        seconds: start.elapsed().as_secs_f64(),
        phases,
    };
    let (tmp, done) = task_dirs(plan_dir, k);
    if done.is_dir() {
        return Ok(summary(range.len(), 0, true, Vec::new()));
    }
    let step = tp.checked_step(plan_dir)?;
    // --plan-only made it empty; a copy that drops empty folders loses it.
    if let Some(tasks_dir) = tmp.parent()
        && !tasks_dir.is_dir()
    {
        return Err(ConvertError::input(
            tasks_dir,
            "the plan has no tasks folder: copy the plan folder whole, empty folders included",
        ));
    }
    // Two runs of one task would write the same files: the second refuses.
    let lock_path = tmp.with_extension("lock");
    let lock = File::create(&lock_path).map_err(io_err(&lock_path, "cannot create"))?;
    match lock.try_lock() {
        Ok(()) => {}
        Err(TryLockError::WouldBlock) => {
            return Err(ConvertError::output(
                &tmp,
                format!("task {k} is already running (another process holds its lock)"),
            ));
        }
        Err(TryLockError::Error(e)) => return Err(ConvertError::io(&lock_path, "cannot lock", e)),
    }
    // Another run may have finished it between the first look and the lock.
    if done.is_dir() {
        return Ok(summary(range.len(), 0, true, Vec::new()));
    }
    let wd = task_workdir(plan_dir, k, false).with_shared_chunks(shared_chunks(&tp, plan_dir));
    let mut phases = Phases::new(Progress::new(quiet));
    let (resumed, shares) = build(&tp, plan_dir, k, &wd, &range, step.as_ref(), &mut phases)?;
    // Only the journal, the chunk roots and the nodes go on to the finish.
    for dir in [wd.chunks(), wd.bands()] {
        if dir.exists() {
            fs::remove_dir_all(&dir).map_err(io_err(&dir, "cannot remove work files"))?;
        }
    }
    let _ = fs::remove_file(wd.plan());
    fs::rename(wd.root(), &done)
        .map_err(io_err(&done, "cannot move the finished task into place"))?;
    // The lock file stays: deleting it would let a run that opened the old file and one that
    // creates a new one both hold "the" lock.
    drop(lock);
    Ok(summary(resumed, shares, false, phases.into_times()))
}

/// Distributes the shares no other task is distributing and waits for the others, then
/// writes the bands the task's chunks read and indexes its chunks that are not committed yet;
/// returns how many were, and how many shares this run distributed.
fn build(
    tp: &TaskPlan,
    plan_dir: &Path,
    k: usize,
    wd: &WorkDir,
    range: &Range<usize>,
    step: &dyn ChunkStep,
    phases: &mut Phases,
) -> Result<(usize, usize)> {
    let plan = &tp.plan;
    let layout = RowLayout::new(plan.attributes.clone());
    let threads = tp.threads.max(1);
    let shares = phases.timed("distribute", Some((plan.points, "points")), |bar| {
        distribute_shares(tp, plan_dir, k, bar)
    })?;
    // Its plan file marks a work directory an interrupted run of the task can continue.
    if !wd.plan().exists() {
        wd.create_fresh()?;
        save_plan(wd, plan)?;
    }
    // The task's chunk files stay until the finish: a chunk whose nodes were lost since its
    // commit (a crash before they reached the disk) is built again, with those after it.
    let (journal, _damaged) = read_resumable_journal_of(wd, range.clone())?;
    let resumed = journal.len();
    let first = range.start + resumed;
    let parts = Share::parts(tp.shares(), threads);
    let halos = Halos::new(plan, layout.stride, step.halo_margin(plan));
    if halos.needed() {
        // The bands of the chunks left and of their neighbours, whichever task owns them.
        let mut banded: Vec<usize> = (first..range.end)
            .flat_map(|i| std::iter::once(i).chain(halos.neighbours(i).iter().copied()))
            .collect();
        banded.sort_unstable();
        banded.dedup();
        // Bands for the chunks left, the only ones to read them.
        let left = first..range.end;
        phases.timed("halo", Some((banded.len() as u64, "chunks")), |bar| {
            halos.write_bands_of(wd, &banded, |r| left.contains(&r), parts, threads, bar)
        })?;
    }
    let remaining: u64 = plan.chunks[first..range.end].iter().map(|c| c.points).sum();
    phases.timed("index", Some((remaining, "points")), |bar| {
        let committer = Committer::open(wd, &journal)?;
        let ix = Indexing {
            plan,
            layout: &layout,
            sampling: tp.sampling,
            threads,
            memory_limit: tp.memory_limit,
            parts,
            step,
            halos: &halos,
            wd,
        };
        index_chunks(&ix, first..range.end, committer, bar).map(|_| ())
    })?;
    Ok((resumed, shares))
}
