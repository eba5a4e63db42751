//! A plan's distribution, in shares: as many as tasks, share s taking the s-th part of every
//! worker's records (`distribute::Share`), so that every input is read once whatever the
//! number of tasks, and the chunk files, read in part order, hold the rows the single run's
//! distribution would. A task distributes the shares nobody is distributing, its own first,
//! and waits for those other tasks are distributing: with the tasks run all at once each
//! distributes its own; run one after the other, the first distributes them all. A share a
//! stopped task left unfinished is distributed again from the start.
//!
//! The lock only saves work twice done: each process writes a share into a folder of its own
//! and renames it into place, and a share already in place wins, so that a file system whose
//! locks do not reach across machines still gets every share whole, once.
//!
//! ```text
//! PLAN/shares/S.PID-NANOS.strata-tmp/   share S under way in one process
//! PLAN/shares/S.lock                    held by the process distributing share S
//! PLAN/shares/S/                        share S done: its chunk part files and counts.json
//! PLAN/shares/consumed                  the finish has begun: the chunk files are going
//! ```

use super::{TaskPlan, plan_file};
use crate::distribute::{ClassCounts, Distribution, RowBuffers, Share, distribute};
use crate::error::{ConvertError, Result, io_err};
use crate::plan::chunk_lut;
use crate::prepare::{distribute_budget, distribute_room};
use crate::workdir::SharedChunks;
use indicatif::ProgressBar;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::fs::{self, File, TryLockError};
use std::path::{Path, PathBuf};
use std::time::Duration;
use strata_format::RowLayout;

/// How often a task waiting for another's share looks again.
const POLL: Duration = Duration::from_millis(200);

/// The points per classification code of a share's rows, written when the share is done.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub(crate) struct ShareCounts {
    pub classes: Vec<u64>,
}

fn shares_dir(plan_dir: &Path) -> PathBuf {
    plan_dir.join("shares")
}

/// Share `s`'s lock file, and its folder once done.
fn share_paths(plan_dir: &Path, s: usize) -> (PathBuf, PathBuf) {
    let dir = shares_dir(plan_dir);
    (dir.join(format!("{s}.lock")), dir.join(s.to_string()))
}

/// Where this process writes share `s`: a name no other process uses.
fn share_tmp(plan_dir: &Path, s: usize) -> PathBuf {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    shares_dir(plan_dir).join(format!("{s}.{}-{nanos}.strata-tmp", std::process::id()))
}

/// Its presence says the finish has begun and the chunk files are going.
fn consumed_marker(plan_dir: &Path) -> PathBuf {
    shares_dir(plan_dir).join("consumed")
}

fn counts_path(done: &Path) -> PathBuf {
    done.join("counts.json")
}

/// The chunk files of the plan's shares, for a task's work directory.
pub(crate) fn shared_chunks(tp: &TaskPlan, plan_dir: &Path) -> SharedChunks {
    SharedChunks {
        dir: shares_dir(plan_dir),
        shares: tp.shares(),
    }
}

/// Makes sure every share is distributed, starting with `first`; returns how many this
/// process distributed.
pub(crate) fn distribute_shares(
    tp: &TaskPlan,
    plan_dir: &Path,
    first: usize,
    bar: &ProgressBar,
) -> Result<usize> {
    let n = tp.shares();
    let dir = shares_dir(plan_dir);
    fs::create_dir_all(&dir).map_err(io_err(&dir, "cannot create the plan's shares folder"))?;
    if consumed_marker(plan_dir).exists() {
        return Err(ConvertError::input(
            plan_file(plan_dir),
            "its finish has begun and removed the points the tasks read; make the plan again",
        ));
    }
    let mut pending: VecDeque<usize> = (0..n).map(|i| (first + i) % n).collect();
    let (mut here, mut idle) = (0, 0);
    let memory = RowBuffers::new(tp.threads.max(1));
    while let Some(s) = pending.pop_front() {
        let (lock_path, done) = share_paths(plan_dir, s);
        if done.is_dir() {
            idle = 0;
            continue;
        }
        let lock = File::create(&lock_path).map_err(io_err(&lock_path, "cannot create"))?;
        match lock.try_lock() {
            Ok(()) => {
                // Another process may have finished it between the first look and the lock.
                if !done.is_dir() && distribute_share(tp, plan_dir, s, bar, &memory)? {
                    here += 1;
                }
                idle = 0;
            }
            Err(TryLockError::WouldBlock) => {
                // Another task is distributing it: look at the others, then again.
                pending.push_back(s);
                idle += 1;
                if idle >= pending.len() {
                    std::thread::sleep(POLL);
                    idle = 0;
                }
            }
            Err(TryLockError::Error(e)) => {
                return Err(ConvertError::io(&lock_path, "cannot lock", e));
            }
        }
        // The lock file stays, as a task's does: see `run_task`.
        drop(lock);
    }
    Ok(here)
}

/// Distributes share `s` into a folder of this process's and renames it into place; false
/// when another process's copy took the place first (this one is dropped).
fn distribute_share(
    tp: &TaskPlan,
    plan_dir: &Path,
    s: usize,
    bar: &ProgressBar,
    memory: &RowBuffers,
) -> Result<bool> {
    let done = share_paths(plan_dir, s).1;
    // Copies stopped processes left: under the lock no other process is writing one (where
    // locks do not reach across machines, one that is fails at its next write: no rows mix).
    let prefix = format!("{s}.");
    let dir = shares_dir(plan_dir);
    for entry in fs::read_dir(&dir)
        .map_err(io_err(&dir, "cannot list"))?
        .flatten()
    {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with(&prefix) && name.ends_with(".strata-tmp") {
            let path = entry.path();
            fs::remove_dir_all(&path).map_err(io_err(&path, "cannot clear an unfinished share"))?;
        }
    }
    let tmp = share_tmp(plan_dir, s);
    fs::create_dir_all(&tmp).map_err(io_err(&tmp, "cannot create"))?;
    let plan = &tp.plan;
    let layout = RowLayout::new(plan.attributes.clone());
    let inputs = tp.row_inputs(plan_dir)?;
    let lut = chunk_lut(&plan.chunks, &plan.cube)
        .map_err(|e| ConvertError::input(plan_file(plan_dir), e))?;
    let classes: ClassCounts = distribute(
        &Distribution {
            inputs: &inputs,
            stride: layout.stride,
            cube: &plan.cube,
            lut: &lut,
            chunk_count: plan.chunks.len(),
            chunk_dir: &tmp,
            buffer_budget: distribute_budget(tp.memory_limit),
            room: distribute_room(tp.memory_limit),
            threads: tp.threads.max(1),
            class_at: tp.class_at,
            share: Share {
                index: s,
                count: tp.shares(),
            },
        },
        bar,
        memory,
    )?;
    let counts = ShareCounts {
        classes: classes.to_vec(),
    };
    let text = serde_json::to_vec(&counts)
        .map_err(|e| ConvertError::internal("writing a share's counts", e.to_string()))?;
    let path = counts_path(&tmp);
    fs::write(&path, text).map_err(io_err(&path, "cannot write"))?;
    match fs::rename(&tmp, &done) {
        Ok(()) => Ok(true),
        // A copy of another process's is there (its file system's locks did not reach this
        // one, or its listing came late): the two are the same rows; this one goes.
        Err(_) if done.join("counts.json").is_file() => {
            fs::remove_dir_all(&tmp).map_err(io_err(&tmp, "cannot remove a share copy"))?;
            Ok(false)
        }
        Err(e) => Err(ConvertError::io(
            &done,
            "cannot move the finished share into place",
            e,
        )),
    }
}

/// Removes the shares' chunk files, which no task reads once every task is done (their class
/// counts stay, for the finish), so that they are gone before the finish writes the dataset.
pub(crate) fn remove_chunk_files(tp: &TaskPlan, plan_dir: &Path) -> Result<()> {
    // Marked first: a task run from now on would find every share done and no rows in it.
    let marker = consumed_marker(plan_dir);
    fs::write(&marker, b"").map_err(io_err(&marker, "cannot write"))?;
    for s in 0..tp.shares() {
        let done = share_paths(plan_dir, s).1;
        let Ok(entries) = fs::read_dir(&done) else {
            continue;
        };
        for entry in entries.flatten() {
            let path = entry.path();
            if path != counts_path(&done) {
                fs::remove_file(&path).map_err(io_err(&path, "cannot remove work file"))?;
            }
        }
    }
    Ok(())
}

/// The points per classification code of every share together.
pub(crate) fn share_classes(tp: &TaskPlan, plan_dir: &Path) -> Result<[u64; 256]> {
    let mut total = [0u64; 256];
    for s in 0..tp.shares() {
        let path = counts_path(&share_paths(plan_dir, s).1);
        let bytes = fs::read(&path).map_err(io_err(&path, "cannot read the share's counts"))?;
        let counts: ShareCounts = serde_json::from_slice(&bytes).map_err(|e| {
            ConvertError::input(&path, format!("the share's counts do not parse ({e})"))
        })?;
        if counts.classes.len() > total.len() {
            return Err(ConvertError::input(
                &path,
                format!("counts {} classes; there are 256", counts.classes.len()),
            ));
        }
        for (t, c) in total.iter_mut().zip(&counts.classes) {
            *t = t.saturating_add(*c);
        }
    }
    // Each point is counted in one class: counts that do not add up to the plan's points were
    // edited or damaged, and the dataset would state them.
    let sum = total.iter().fold(0u64, |a, &c| a.saturating_add(c));
    if tp.class_at.is_some() && sum != tp.plan.points {
        return Err(ConvertError::input(
            shares_dir(plan_dir),
            format!(
                "the shares' class counts add up to {sum} points, not the plan's {}; make the \
                 plan again",
                tp.plan.points
            ),
        ));
    }
    Ok(total)
}
