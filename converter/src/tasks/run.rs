//! `strata convert --plan PLAN --task K`: builds task K's chunks in its own folder of the plan
//! (no two tasks write the same file), then renames that folder into its result. A task run
//! again continues what an interrupted run of it left, as `--resume` does; a finished task is
//! not run again.

use super::distribute::{Role, TaskDistribution, distribute_task};
use super::{TaskPlan, task_dirs, task_workdir};
use crate::chunk_step::ChunkStep;
use crate::distribute::ClassCounts;
use crate::error::{ConvertError, Result, io_err};
use crate::halo::Halos;
use crate::index::{Indexing, index_chunks};
use crate::journal::{Committer, read_journal_of, save_plan};
use crate::plan::chunk_lut;
use crate::prepare::distribute_budget;
use crate::progress::{Phases, Progress};
use crate::workdir::WorkDir;
use serde::{Deserialize, Serialize};
use std::fs::{self, File};
use std::ops::Range;
use std::path::{Path, PathBuf};
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
    /// The task had finished before: nothing was done.
    pub already_done: bool,
    pub seconds: f64,
}

/// The class counts of a task's chunks, written once its distribution is whole (so it also
/// marks a task whose indexing can resume) and read by the finish.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub(crate) struct TaskCounts {
    pub classes: Vec<u64>,
}

pub(crate) fn counts_file(wd: &WorkDir) -> PathBuf {
    wd.work().join("task.json")
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
    let summary = |resumed_chunks, already_done| TaskSummary {
        task: k,
        tasks: tp.tasks.len(),
        chunks: range.clone(),
        points,
        resumed_chunks,
        already_done,
        seconds: start.elapsed().as_secs_f64(),
    };
    let (tmp, done) = task_dirs(plan_dir, k);
    if done.is_dir() {
        return Ok(summary(range.len(), true));
    }
    let step = tp.checked_step(plan_dir)?;
    // Two runs of one task would write the same files: the second refuses.
    let lock_path = tmp.with_extension("lock");
    let lock = File::create(&lock_path).map_err(io_err(&lock_path, "cannot create"))?;
    if lock.try_lock().is_err() {
        return Err(ConvertError::output(
            &tmp,
            format!("task {k} is already running (another process holds its lock)"),
        ));
    }
    // Another run may have finished it between the first look and the lock.
    if done.is_dir() {
        return Ok(summary(range.len(), true));
    }
    let wd = task_workdir(plan_dir, k, false);
    let mut phases = Phases::new(Progress::new(quiet));
    let resumed = build(&tp, plan_dir, &wd, &range, step.as_ref(), &mut phases)?;
    // Only the journal, the chunk roots, the nodes and the class counts go on to the finish.
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
    Ok(summary(resumed, false))
}

/// Distributes the task's rows (unless an earlier run did), then indexes its chunks that
/// are not committed yet; returns how many were.
fn build(
    tp: &TaskPlan,
    plan_dir: &Path,
    wd: &WorkDir,
    range: &Range<usize>,
    step: &dyn ChunkStep,
    phases: &mut Phases,
) -> Result<usize> {
    let plan = &tp.plan;
    let layout = RowLayout::new(plan.attributes.clone());
    let threads = tp.threads.max(1);
    let halos = Halos::new(plan, layout.stride, step.halo_margin(plan));
    // Written once the chunk files and bands are whole: from then on indexing can resume.
    if !counts_file(wd).exists() {
        wd.create_fresh()?;
        let classes = distribute(tp, plan_dir, wd, range, &halos, &layout, phases)?;
        save_plan(wd, plan)?;
        let done = TaskCounts {
            classes: classes.to_vec(),
        };
        let path = counts_file(wd);
        let part = path.with_extension("part");
        let text = serde_json::to_vec(&done)
            .map_err(|e| ConvertError::internal("writing a task's counts", e.to_string()))?;
        fs::write(&part, text).map_err(io_err(&part, "cannot write"))?;
        fs::rename(&part, &path).map_err(io_err(&path, "cannot write"))?;
    }
    let journal = read_journal_of(wd, range.clone());
    let resumed = journal.len();
    let first = range.start + resumed;
    let remaining: u64 = plan.chunks[first..range.end].iter().map(|c| c.points).sum();
    phases.timed("index", Some((remaining, "points")), |bar| {
        let committer = Committer::open(wd, &journal)?;
        let ix = Indexing {
            plan,
            layout: &layout,
            sampling: tp.sampling,
            threads,
            step,
            halos: &halos,
            wd,
        };
        index_chunks(&ix, first..range.end, committer, bar).map(|_| ())
    })?;
    Ok(resumed)
}

/// The task's rows into its chunk files, and the bands its chunks' halos read.
fn distribute(
    tp: &TaskPlan,
    plan_dir: &Path,
    wd: &WorkDir,
    range: &Range<usize>,
    halos: &Halos,
    layout: &RowLayout,
    phases: &mut Phases,
) -> Result<ClassCounts> {
    let plan = &tp.plan;
    let n = plan.chunks.len();
    let mut roles = vec![Role::Skip; n];
    for i in range.clone() {
        roles[i] = Role::Own;
    }
    if halos.needed() {
        for i in range.clone() {
            for &j in halos.neighbours(i) {
                if range.contains(&j) {
                    continue;
                }
                if let Role::Skip = roles[j] {
                    roles[j] = Role::Band {
                        inner: halos.inner(j),
                        reaches: Vec::new(),
                    };
                }
                if let Role::Band { reaches, .. } = &mut roles[j] {
                    reaches.push(halos.reach(i));
                }
            }
        }
    }
    let inputs = tp.row_inputs(plan_dir)?;
    let cells = tp.cell_files(plan_dir);
    let lut = chunk_lut(&plan.chunks, &plan.cube);
    let threads = tp.threads.max(1);
    let classes = phases.timed("distribute", Some((plan.points, "points")), |bar| {
        distribute_task(
            &TaskDistribution {
                inputs: &inputs,
                cells: &cells,
                stride: layout.stride,
                cube: &plan.cube,
                lut: &lut,
                roles: &roles,
                chunk_dir: &wd.chunks(),
                buffer_budget: distribute_budget(tp.memory_limit),
                parts: threads,
                class_at: tp.class_at,
            },
            bar,
        )
    })?;
    if halos.needed() {
        let banded: Vec<usize> = (0..n)
            .filter(|&j| !matches!(roles[j], Role::Skip))
            .collect();
        phases.timed("halo", Some((banded.len() as u64, "chunks")), |bar| {
            halos.write_bands_of(wd, &banded, threads, threads, bar)
        })?;
        // Other tasks' rows were only wanted for their bands.
        for j in banded.iter().filter(|j| !range.contains(j)) {
            for part in 0..threads {
                let path = wd.chunk_part(*j, part);
                match fs::remove_file(&path) {
                    Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                        return Err(ConvertError::io(&path, "cannot remove work file", e));
                    }
                    _ => {}
                }
            }
        }
    }
    Ok(classes)
}
