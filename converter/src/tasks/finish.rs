//! `strata convert --plan PLAN --finish -o DATASET`: the tasks' nodes, copied into one octree
//! file in plan order (as the single run commits them), then the top levels merged from the
//! chunk roots and the dataset written and renamed into place, as `convert` finishes.

use super::share::{remove_chunk_files, share_classes};
use super::{TaskPlan, task_dirs, task_workdir};
use crate::build::ConvertSummary;
use crate::chunk_step::add_totals;
use crate::disk::{check_space, tree_bytes};
use crate::error::{ConvertError, Result, io_err};
use crate::finish::{finish, merge_top};
use crate::journal::{Committer, JournalEntry, read_journal_of};
use crate::prepare::class_list;
use crate::progress::{Phases, Progress};
use crate::replace::{Folder, check_output};
use crate::sys::peak_rss_bytes;
use crate::uncached::UncachedWriter;
use crate::workdir::WorkDir;
use std::fs;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::time::Instant;
use strata_format::{DatasetFile, DatasetId, NodeKey, OCTREE_HEAD_SIZE, RowLayout, octree_head};

/// Finishes the dataset at `output` from the tasks of the plan in `plan_dir`, then removes the
/// plan folder (its tasks' results are in the dataset now).
pub fn finish_tasks(
    plan_dir: &Path,
    output: &Path,
    overwrite: bool,
    quiet: bool,
) -> Result<ConvertSummary> {
    let start = Instant::now();
    // The plan folder is removed at the end, with anything inside it.
    let absolute = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    if absolute(output).starts_with(absolute(plan_dir)) {
        return Err(ConvertError::output(
            output,
            format!(
                "lies inside the plan folder {}, which is removed once the dataset is \
                 finished; give -o a place outside it",
                plan_dir.display()
            ),
        ));
    }
    if !super::plan_file(plan_dir).is_file() {
        // A finish stopped while it removed the plan folder has put the dataset in place.
        if output.join(DatasetFile::Metadata.name()).is_file() {
            return Err(ConvertError::input(
                super::plan_file(plan_dir),
                format!(
                    "no conversion plan here, and {} holds a dataset: a finish stopped while it \
                     removed the plan folder leaves the dataset whole (check it with `strata \
                     verify`), and what is left of the folder may be removed",
                    output.display()
                ),
            ));
        }
        TaskPlan::load(plan_dir)?;
    }
    // Two finishes of one plan would build in the same temporary folder, each clearing what
    // the other wrote: the second refuses. The lock is on the plan folder itself, held until
    // the folder is gone, and taken before the plan is read, so a finish that waited finds
    // no plan rather than half of one.
    let Some(lock) = crate::workdir::lock_folder(plan_dir)? else {
        return Err(ConvertError::output(
            plan_dir,
            "is being finished by another process (it holds the plan's lock)",
        ));
    };
    let tp = TaskPlan::load(plan_dir)?;
    let missing: Vec<usize> = (0..tp.tasks.len())
        .filter(|&k| !task_dirs(plan_dir, k).1.is_dir())
        .collect();
    if !missing.is_empty() {
        return Err(ConvertError::TasksUnfinished {
            plan: plan_dir.to_path_buf(),
            missing,
            total: tp.tasks.len(),
        });
    }
    check_output(output, overwrite, Folder::Dataset)?;
    let opts = tp.options(output.to_path_buf(), overwrite, quiet);
    let step = tp.checked_step(plan_dir)?;
    // Every task's journal is whole before the chunk files go: until then a damaged task can
    // still be run again.
    let journals = tp
        .tasks
        .iter()
        .enumerate()
        .map(|(k, range)| task_journal(plan_dir, k, range))
        .collect::<Result<Vec<_>>>()?;
    // So are the chunk roots the merge reads; and the dataset takes about what the tasks'
    // nodes and roots take, copied before they go: refuse now, not once the disk is full.
    let mut bytes = 0u64;
    for (k, range) in tp.tasks.iter().enumerate() {
        let twd = task_workdir(plan_dir, k, true);
        let part = twd.dataset_file(DatasetFile::Octree);
        bytes += fs::metadata(part).map_or(0, |m| m.len());
        for chunk in range.clone() {
            let root = twd.chunk_root(chunk);
            let len = fs::metadata(&root).map(|m| m.len()).map_err(|_| {
                ConvertError::input(
                    &root,
                    format!(
                        "is missing: task {k}'s work files are damaged; remove {} and run \
                         --plan {} --task {k} again, then finish",
                        task_dirs(plan_dir, k).1.display(),
                        plan_dir.display()
                    ),
                )
            })?;
            bytes += len;
        }
    }
    check_space(&[(output, bytes)])?;
    let wd = WorkDir::new(output, None);
    // Before anything is removed: another conversion may be writing into this output.
    let _lock = wd.lock(output)?;
    if let Err(e) = remove_chunk_files(&tp, plan_dir).and_then(|()| wd.create_fresh()) {
        wd.remove_all();
        return Err(e);
    }
    let mut phases = Phases::new(Progress::new(quiet));
    let result = (|| {
        let (journal, classes) =
            phases.timed("gather", None, |_| gather(&tp, plan_dir, &wd, journals))?;
        let mut plan = tp.plan.clone();
        plan.classes = class_list(tp.class_at, &classes);
        let layout = RowLayout::new(plan.attributes.clone());
        let committer = Committer::open(&wd, &journal)?;
        // Where each chunk's root rows are: in the result of the task that built it.
        let owner: Vec<usize> = tp
            .tasks
            .iter()
            .enumerate()
            .flat_map(|(k, r)| r.clone().map(move |_| k))
            .collect();
        let root_of = |chunk: usize| -> PathBuf {
            let k = owner.get(chunk).copied().unwrap_or(0);
            task_workdir(plan_dir, k, true).chunk_root(chunk)
        };
        let merged = phases.timed("merge", None, |_| {
            merge_top(&root_of, &plan, &layout, tp.sampling, &journal, committer)
        })?;
        let mut totals = Vec::new();
        for entry in &journal {
            add_totals(&mut totals, &entry.step);
        }
        // The step's metadata (the normals' search radius) comes from the plan, as in a run.
        step.halo_margin(&plan);
        phases
            .timed("finish", None, |_| {
                finish(&opts, &wd, &plan, merged, &|meta| {
                    step.record(&totals, meta)
                })
            })
            .map(|done| (done, step.warnings(&totals)))
    })();
    let (done, step_warnings) = match result {
        Ok(done) => done,
        Err(e) => {
            // The tasks' results are untouched: --finish can run again.
            wd.remove_all();
            return Err(e);
        }
    };
    let plan_bytes = tree_bytes(plan_dir);
    fs::remove_dir_all(plan_dir).map_err(io_err(plan_dir, "cannot remove the finished plan"))?;
    drop(lock);
    let seconds = start.elapsed().as_secs_f64();
    Ok(ConvertSummary {
        output: output.to_path_buf(),
        points: done.points,
        nodes: done.nodes,
        depth: done.depth,
        chunks: tp.plan.chunks.len(),
        seconds,
        points_per_second: done.points as f64 / seconds.max(1e-9),
        peak_memory_bytes: peak_rss_bytes(),
        dataset_bytes: done.dataset_bytes,
        peak_disk_bytes: plan_bytes + done.dataset_bytes,
        resumed_chunks: 0,
        phases: phases.into_times(),
        warnings: tp
            .plan
            .warnings
            .iter()
            .cloned()
            .chain(step_warnings)
            .collect(),
    })
}

/// Task `k`'s journal, refused unless it lists every chunk of the task.
fn task_journal(plan_dir: &Path, k: usize, range: &Range<usize>) -> Result<Vec<JournalEntry>> {
    let twd = task_workdir(plan_dir, k, true);
    let entries = read_journal_of(&twd, range.clone());
    if entries.len() != range.len() {
        return Err(ConvertError::input(
            twd.journal(),
            format!(
                "task {k}'s journal holds {} of its {} chunks; run the task again after removing {}",
                entries.len(),
                range.len(),
                twd.root().display()
            ),
        ));
    }
    Ok(entries)
}

/// Copies every task's nodes into the work directory's octree file, in task (so plan)
/// order, past the page cache (`UncachedWriter`); returns the journal of every chunk (`journals`, one per task, checked whole), its
/// offsets moved to where the nodes are now, and the class counts of all shares together.
fn gather(
    tp: &TaskPlan,
    plan_dir: &Path,
    wd: &WorkDir,
    journals: Vec<Vec<JournalEntry>>,
) -> Result<(Vec<JournalEntry>, [u64; 256])> {
    let octree_path = wd.dataset_file(DatasetFile::Octree);
    let mut octree = UncachedWriter::create(&octree_path)?;
    octree.write_all(&octree_head(DatasetId::default()))?;
    let mut end = OCTREE_HEAD_SIZE;
    let mut journal = Vec::new();
    let classes = share_classes(tp, plan_dir)?;
    for (k, entries) in journals.into_iter().enumerate() {
        let twd = task_workdir(plan_dir, k, true);
        let task_end = entries.last().map_or(OCTREE_HEAD_SIZE, |e| e.end);
        let part = twd.dataset_file(DatasetFile::Octree);
        let len = task_end.checked_sub(OCTREE_HEAD_SIZE).ok_or_else(|| {
            ConvertError::input(
                &part,
                format!("its journal ends its nodes at byte {task_end}, inside the file head"),
            )
        })?;
        let mut check = NodeCheck::new(&part, k, &entries, task_end)?;
        let copied = octree.copy_file(&part, OCTREE_HEAD_SIZE, len, &mut |b| check.see(b))?;
        if copied != len {
            return Err(ConvertError::input(
                &part,
                format!("holds {copied} bytes of nodes where its journal says {len}"),
            ));
        }
        check.all_seen()?;
        let by = end - OCTREE_HEAD_SIZE;
        journal.extend(entries.into_iter().map(|e| e.moved(by)));
        end += len;
    }
    octree.finish()?;
    Ok((journal, classes))
}

/// A node of a task's octree file: where its payload lies, its checksum, and which it is.
struct NodeSpan {
    start: u64,
    end: u64,
    checksum: u32,
    key: NodeKey,
    chunk: usize,
}

/// Checks a task's node payloads against the checksums its journal records as the bytes are
/// copied, so that a task file damaged since the task ran stops the finish instead of passing
/// into the dataset (where only `strata verify` would find it).
struct NodeCheck<'a> {
    part: &'a Path,
    task: usize,
    nodes: Vec<NodeSpan>,
    next: usize,
    /// Where in the task's file the next byte shown is.
    at: u64,
    /// `strata_format::payload_checksum` (CRC-32), taken a piece at a time as the copy goes.
    hasher: crc32fast::Hasher,
}

impl<'a> NodeCheck<'a> {
    fn new(part: &'a Path, task: usize, entries: &[JournalEntry], task_end: u64) -> Result<Self> {
        let mut nodes = Vec::new();
        let mut end = OCTREE_HEAD_SIZE;
        for e in entries {
            for (key, r) in e.records().filter(|(_, r)| r.size > 0) {
                let start = r.offset;
                let stop = start.checked_add(u64::from(r.size));
                // In order, apart and within the nodes: as the task wrote them.
                let Some(stop) = stop.filter(|&s| start >= end && s <= task_end) else {
                    return Err(ConvertError::input(
                        part,
                        format!(
                            "task {task}'s journal puts node {} of chunk {} at bytes {start}+{}, outside the nodes or over another's; run the task again after making the plan again",
                            key, e.chunk, r.size
                        ),
                    ));
                };
                nodes.push(NodeSpan {
                    start,
                    end: stop,
                    checksum: r.checksum,
                    key,
                    chunk: e.chunk,
                });
                end = stop;
            }
        }
        Ok(NodeCheck {
            part,
            task,
            nodes,
            next: 0,
            at: OCTREE_HEAD_SIZE,
            hasher: crc32fast::Hasher::new(),
        })
    }

    /// Takes the next bytes of the file.
    fn see(&mut self, mut bytes: &[u8]) -> Result<()> {
        while let Some(n) = self.nodes.get(self.next) {
            if bytes.is_empty() {
                return Ok(());
            }
            let take = if self.at < n.start {
                // Between nodes: nothing to check.
                (n.start - self.at).min(bytes.len() as u64) as usize
            } else {
                let take = (n.end - self.at).min(bytes.len() as u64) as usize;
                self.hasher.update(&bytes[..take]);
                take
            };
            bytes = &bytes[take..];
            self.at += take as u64;
            if self.at == n.end {
                let got = std::mem::take(&mut self.hasher).finalize();
                if got != n.checksum {
                    return Err(self.damaged(n));
                }
                self.next += 1;
            }
        }
        Ok(())
    }

    /// An error unless every node was seen whole.
    fn all_seen(&self) -> Result<()> {
        match self.nodes.get(self.next) {
            Some(n) => Err(self.damaged(n)),
            None => Ok(()),
        }
    }

    fn damaged(&self, n: &NodeSpan) -> ConvertError {
        ConvertError::input(
            self.part,
            format!(
                "node {} of chunk {} (bytes {}..{}) does not match the checksum task {}'s journal records: the task's result was damaged since it ran; make the plan again and run its tasks",
                n.key, n.chunk, n.start, n.end, self.task
            ),
        )
    }
}
