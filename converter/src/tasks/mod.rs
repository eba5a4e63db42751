//! Conversion as independent tasks, for a batch engine (Slurm, Kubernetes) over machines that
//! share storage: `plan_tasks` counts the inputs and writes a plan folder; `run_task`
//! distributes a share of the points into chunk files (`share`: each input is read once in
//! all, whatever the number of tasks) and builds one task's chunks from them (the per-chunk
//! step, indexing), in any order and any number at once; `finish_tasks` merges the top levels
//! into the dataset. The dataset is byte for byte the one `convert` makes of the same inputs
//! with the same options.
//!
//! The plan folder:
//! ```text
//! PLAN/plan.json                  the plan (written last, renamed into place)
//! PLAN/staging/                   rows decoded from LAZ, PLY, E57: what the shares read
//! PLAN/shares/S/                  share S distributed: its chunk part files, its class counts
//! PLAN/tasks/K.strata-tmp/        task K under way (its work files, journal, octree part)
//! PLAN/tasks/K/                   task K done: its nodes, journal and chunk roots
//! ```

mod finish;
mod run;
mod share;

pub use finish::finish_tasks;
pub use run::{TaskSummary, run_task};

use crate::build::ConvertOptions;
use crate::chunk_step::{ChunkStep, NoStep};
use crate::disk::DiskUse;
use crate::error::{ConvertError, Result, io_err};
use crate::input::PointSource;
use crate::input::las::LasSource;
use crate::journal::run_fingerprint;
use crate::normals::{NormalOptions, NormalStep};
use crate::plan::check_chunks;
use crate::prepare::{Plan, count_and_plan};
use crate::progress::{Phases, Progress};
use crate::replace::{Folder, UNFINISHED_PLAN, check_output};
use crate::rows::{RecordToRow, RowInput};
use crate::sampling::Sampling;
use crate::workdir::WorkDir;
use serde::{Deserialize, Serialize};
use std::fs;
use std::ops::Range;
use std::path::{Path, PathBuf};
use strata_format::RowLayout;

/// Changes whenever a plan written by one build means something else to another (3: work
/// files' blocks carry a checksum, `rowfile`).
const PLAN_VERSION: u32 = 3;

/// The most threads a plan may ask its tasks for, as `--threads` allows.
const MAX_THREADS: usize = 1024;

/// Everything the tasks and the finish need, and the options they must all use.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TaskPlan {
    pub version: u32,
    /// Absolute, so that a task started in another folder finds them.
    pub inputs: Vec<PathBuf>,
    pub memory_limit: u64,
    /// Threads of the counting machine: they decide the chunks and the order of the rows in
    /// them (one part of every input per thread), so every task works in as many parts.
    pub threads: usize,
    pub sampling: Sampling,
    pub normals: Option<NormalOptions>,
    pub plan: Plan,
    /// Where the rows come from, in the order the distribution reads them.
    pub sources: Vec<RowSource>,
    pub class_at: Option<usize>,
    /// Each task's chunks: consecutive runs of the plan's chunks, in plan order.
    pub tasks: Vec<Range<usize>>,
}

/// One input of the distribution.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub enum RowSource {
    /// A LAS input read in place: `inputs[input]`.
    Las { input: usize },
    /// A staging file of rows in the plan folder (`rowfile`), `blocks` where its blocks start.
    Rows {
        file: PathBuf,
        records: u64,
        record_len: usize,
        blocks: Vec<u64>,
    },
}

/// What `--plan-only` reports.
#[derive(Debug, Clone, Serialize)]
pub struct PlanSummary {
    pub plan: PathBuf,
    pub points: u64,
    pub chunks: usize,
    /// Points per task.
    pub tasks: Vec<u64>,
    pub seconds: f64,
    pub warnings: Vec<String>,
}

pub fn plan_file(plan_dir: &Path) -> PathBuf {
    plan_dir.join("plan.json")
}

/// Where task `k` works, and where it leaves its result once done.
pub fn task_dirs(plan_dir: &Path, k: usize) -> (PathBuf, PathBuf) {
    let tasks = plan_dir.join("tasks");
    (
        tasks.join(format!("{k}.strata-tmp")),
        tasks.join(k.to_string()),
    )
}

/// The work directory of task `k` under way, or of its result (`done`).
pub(crate) fn task_workdir(plan_dir: &Path, k: usize, done: bool) -> WorkDir {
    let (tmp, fin) = task_dirs(plan_dir, k);
    let root = if done { fin } else { tmp };
    let work = root.join("work");
    WorkDir::at(root, work)
}

/// The per-chunk step the options ask for.
pub fn step_for(normals: &Option<NormalOptions>) -> Result<Box<dyn ChunkStep>> {
    Ok(match normals {
        Some(n) => Box::new(NormalStep::new(n.clone())?),
        None => Box::new(NoStep),
    })
}

impl TaskPlan {
    /// Shares of the distribution: one per task.
    pub fn shares(&self) -> usize {
        self.tasks.len().max(1)
    }

    /// Reads the plan in `plan_dir`; an error in one sentence when there is none or it is
    /// not one this build understands.
    pub fn load(plan_dir: &Path) -> Result<TaskPlan> {
        let path = plan_file(plan_dir);
        let bytes = fs::read(&path).map_err(|e| {
            if e.kind() == std::io::ErrorKind::NotFound {
                ConvertError::input(
                    &path,
                    "no conversion plan here (make one with `strata convert INPUT... --plan-only PLAN --tasks N`)",
                )
            } else {
                ConvertError::io(&path, "cannot read the plan", e)
            }
        })?;
        let plan: TaskPlan = serde_json::from_slice(&bytes).map_err(|e| {
            ConvertError::input(
                &path,
                format!("not a conversion plan this strata can read ({e})"),
            )
        })?;
        if plan.version != PLAN_VERSION {
            return Err(ConvertError::input(
                &path,
                format!(
                    "the plan is of version {}, this strata reads version {PLAN_VERSION}; make the plan again",
                    plan.version
                ),
            ));
        }
        plan.check()
            .map_err(|what| ConvertError::input(&path, what))?;
        // Tasks index the chunks by these ranges: they must cover them in order, exactly.
        let mut next = 0;
        for (k, r) in plan.tasks.iter().enumerate() {
            if r.start != next || r.end < r.start || r.end > plan.plan.chunks.len() {
                return Err(ConvertError::input(
                    &path,
                    format!(
                        "task {k}'s chunks {}..{} do not follow on from chunk {next} within the plan's {} chunks",
                        r.start,
                        r.end,
                        plan.plan.chunks.len()
                    ),
                ));
            }
            next = r.end;
        }
        if next != plan.plan.chunks.len() {
            return Err(ConvertError::input(
                &path,
                format!(
                    "its tasks cover {next} of the plan's {} chunks",
                    plan.plan.chunks.len()
                ),
            ));
        }
        Ok(plan)
    }

    /// What is wrong with the plan's fields that size memory or index tables, if anything: a
    /// plan is a file anyone may edit, and a task must refuse it, not panic or abort.
    fn check(&self) -> std::result::Result<(), String> {
        let plan = &self.plan;
        check_chunks(&plan.chunks, &plan.cube, plan.points)
            .map_err(|e| format!("\"plan\": {e}"))?;
        if !(1..=MAX_THREADS).contains(&self.threads) {
            return Err(format!(
                "\"threads\" is {}, outside 1 to {MAX_THREADS}",
                self.threads
            ));
        }
        let stride = RowLayout::new(plan.attributes.clone()).stride;
        for (i, s) in self.sources.iter().enumerate() {
            match s {
                RowSource::Las { input } if *input >= self.inputs.len() => {
                    return Err(format!(
                        "source {i} names input {input}, but the plan lists {} inputs",
                        self.inputs.len()
                    ));
                }
                RowSource::Rows { record_len, .. } if *record_len != stride => {
                    return Err(format!(
                        "source {i}'s records are {record_len} bytes where the plan's rows are {stride}"
                    ));
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// The options of the conversion, writing to `output`.
    pub fn options(&self, output: PathBuf, overwrite: bool, quiet: bool) -> ConvertOptions {
        ConvertOptions {
            inputs: self.inputs.clone(),
            output,
            memory_limit: self.memory_limit,
            threads: self.threads,
            sampling: self.sampling,
            overwrite,
            resume: false,
            quiet,
            temp_dir: None,
        }
    }

    /// The step, checked against the inputs: an error naming the plan when they changed on
    /// disk since it was made (its chunks would not hold their points).
    pub fn checked_step(&self, plan_dir: &Path) -> Result<Box<dyn ChunkStep>> {
        let step = step_for(&self.normals)?;
        let opts = self.options(plan_dir.to_path_buf(), false, true);
        let now = run_fingerprint(&opts, step.as_ref());
        if now != self.plan.fingerprint {
            // The fingerprint lists the inputs first, one `|`-separated part each.
            let changed = now
                .split('|')
                .zip(self.plan.fingerprint.split('|'))
                .take(self.inputs.len())
                .position(|(a, b)| a != b)
                .and_then(|i| self.inputs.get(i));
            return Err(match changed {
                Some(input) => ConvertError::input(
                    input,
                    format!(
                        "{} since the plan was made ({}); make the plan again",
                        if input.is_file() {
                            "changed (its size, or the time it was last written or changed)"
                        } else {
                            "is gone"
                        },
                        plan_file(plan_dir).display()
                    ),
                ),
                None => ConvertError::input(
                    plan_file(plan_dir),
                    "its options or fingerprint are not those it was made with (the plan was \
                     edited, or made by another version of strata); make the plan again",
                ),
            });
        }
        // The rows are read by these attributes, the inputs' own and the step's: edited, the
        // inputs' bytes would be cut wrongly or read as another type.
        let mut expected = crate::scan::union_attributes(&self.inputs, &mut Vec::new())?.attributes;
        let added = step.attributes(&expected)?;
        expected.extend(added);
        if expected != self.plan.attributes {
            return Err(ConvertError::input(
                plan_file(plan_dir),
                "its \"attributes\" are not those its inputs and options give (the plan was \
                 edited); make the plan again",
            ));
        }
        Ok(step)
    }

    /// The distribution's inputs, as `count_and_plan` gave them.
    pub(crate) fn row_inputs(&self, plan_dir: &Path) -> Result<Vec<RowInput>> {
        let layout = RowLayout::new(self.plan.attributes.clone());
        let q = self.plan.quantization();
        let mut out = Vec::new();
        for s in &self.sources {
            out.push(match s {
                RowSource::Las { input } => {
                    let path = self.inputs.get(*input).ok_or_else(|| {
                        ConvertError::input(plan_file(plan_dir), "the plan names an input it lacks")
                    })?;
                    let src = LasSource::open(path)?;
                    let Some(start) = src.records_at() else {
                        return Err(ConvertError::input(
                            path,
                            "the plan reads it in place but it is compressed now; make the plan again",
                        ));
                    };
                    RowInput {
                        path: path.clone(),
                        start,
                        record_len: src.record_len(),
                        records: src.info().points,
                        convert: Some(RecordToRow::new(&src, &layout, &q, &self.plan.cube)),
                        blocks: None,
                    }
                }
                RowSource::Rows {
                    file,
                    records,
                    record_len,
                    blocks,
                } => RowInput {
                    path: plan_dir.join(file),
                    start: 0,
                    record_len: *record_len,
                    records: *records,
                    convert: None,
                    blocks: Some(blocks.clone()),
                },
            });
        }
        Ok(out)
    }
}

/// Cuts the chunks, in plan order, into `tasks` runs of about as many points each (a run may
/// be empty when there are fewer chunks than tasks).
pub fn group_chunks(points: &[u64], tasks: usize) -> Vec<Range<usize>> {
    let total: u64 = points.iter().sum();
    let mut out = Vec::with_capacity(tasks);
    let (mut start, mut seen) = (0usize, 0u64);
    for k in 0..tasks {
        let target = total as u128 * (k as u128 + 1) / tasks as u128;
        let mut end = start;
        // Each task takes chunks while that keeps it nearer its share; the last takes the rest.
        while end < points.len()
            && (k + 1 == tasks
                || (seen + points[end]) as u128 <= target
                || ((seen as u128) < target && end == start))
        {
            seen += points[end];
            end += 1;
        }
        out.push(start..end);
        start = end;
    }
    out
}

/// `strata convert INPUT... --plan-only PLAN --tasks N`: counts the inputs and writes the plan
/// into the folder `opts.output`. Nothing there is a plan until `plan.json` appears.
pub fn plan_tasks(
    opts: &ConvertOptions,
    normals: Option<NormalOptions>,
    tasks: usize,
) -> Result<PlanSummary> {
    let start = std::time::Instant::now();
    if tasks == 0 {
        return Err(ConvertError::Usage("--tasks must be at least 1".into()));
    }
    if opts.inputs.is_empty() {
        return Err(ConvertError::Usage("no input files given".into()));
    }
    let plan_dir = std::path::absolute(&opts.output)
        .map_err(io_err(&opts.output, "cannot resolve the plan folder"))?;
    // A plan whose making stopped part way (killed, a full disk) holds nothing of use: a
    // batch engine's retry of the same command replaces it.
    let unfinished = plan_dir.join(UNFINISHED_PLAN).is_file() && !plan_file(&plan_dir).exists();
    check_output(&plan_dir, opts.overwrite || unfinished, Folder::Plan)?;
    let mut inputs = Vec::new();
    for input in &opts.inputs {
        if !input.is_file() {
            return Err(ConvertError::input(input, "input file does not exist"));
        }
        inputs.push(std::path::absolute(input).map_err(io_err(input, "cannot resolve"))?);
    }
    // Only once the inputs are there: a plan whose tasks ran is not lost to a typo.
    if plan_dir.exists() {
        fs::remove_dir_all(&plan_dir).map_err(io_err(&plan_dir, "cannot remove the old plan"))?;
    }
    // The plan's fingerprint and every task use the thread count actually run (0 means 1).
    let opts = ConvertOptions {
        inputs,
        output: plan_dir.clone(),
        threads: opts.threads.max(1),
        ..opts.clone()
    };
    let threads = opts.threads;
    // The LAZ decompressor runs on rayon's global pool; size it once to --threads.
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global();
    let result = write_plan(&opts, normals, tasks, threads, &plan_dir);
    if result.is_err() {
        let _ = fs::remove_dir_all(&plan_dir);
    }
    let (plan, per_task) = result?;
    Ok(PlanSummary {
        plan: plan_dir,
        points: plan.points,
        chunks: plan.chunks.len(),
        tasks: per_task,
        seconds: start.elapsed().as_secs_f64(),
        warnings: plan.warnings,
    })
}

fn write_plan(
    opts: &ConvertOptions,
    normals: Option<NormalOptions>,
    tasks: usize,
    threads: usize,
    plan_dir: &Path,
) -> Result<(Plan, Vec<u64>)> {
    let step = step_for(&normals)?;
    let wd = WorkDir::at(plan_dir.to_path_buf(), plan_dir.join("staging"));
    fs::create_dir_all(plan_dir).map_err(io_err(plan_dir, "cannot create the plan folder"))?;
    let unfinished = plan_dir.join(UNFINISHED_PLAN);
    fs::write(&unfinished, b"").map_err(io_err(&unfinished, "cannot write"))?;
    for dir in [wd.work().to_path_buf(), plan_dir.join("tasks")] {
        fs::create_dir_all(&dir).map_err(io_err(&dir, "cannot create the plan folder"))?;
    }
    let mut phases = Phases::new(Progress::new(opts.quiet));
    let fp = run_fingerprint(opts, step.as_ref());
    let counted = count_and_plan(
        opts,
        &wd,
        threads,
        &mut phases,
        fp,
        step.as_ref(),
        DiskUse::Together,
    )?;
    let mut sources = Vec::new();
    for (i, input) in counted.inputs.iter().enumerate() {
        sources.push(match &input.blocks {
            None => RowSource::Las { input: i },
            Some(blocks) => RowSource::Rows {
                file: input
                    .path
                    .strip_prefix(plan_dir)
                    .map_err(|_| {
                        ConvertError::internal(
                            "writing the plan",
                            format!("staging file {} lies outside it", input.path.display()),
                        )
                    })?
                    .to_path_buf(),
                records: input.records,
                record_len: input.record_len,
                blocks: blocks.clone(),
            },
        });
    }
    let points: Vec<u64> = counted.plan.chunks.iter().map(|c| c.points).collect();
    let groups = group_chunks(&points, tasks);
    let per_task = groups
        .iter()
        .map(|r| points[r.clone()].iter().sum())
        .collect();
    let tp = TaskPlan {
        version: PLAN_VERSION,
        inputs: opts.inputs.clone(),
        memory_limit: opts.memory_limit,
        threads,
        sampling: opts.sampling,
        normals,
        plan: counted.plan,
        sources,
        class_at: counted.class_at,
        tasks: groups,
    };
    let path = plan_file(plan_dir);
    let part = path.with_extension("json.part");
    let text = serde_json::to_vec_pretty(&tp)
        .map_err(|e| ConvertError::internal("writing the plan", e.to_string()))?;
    fs::write(&part, text).map_err(io_err(&part, "cannot write"))?;
    fs::rename(&part, &path).map_err(io_err(&path, "cannot write"))?;
    fs::remove_file(&unfinished).map_err(io_err(&unfinished, "cannot remove"))?;
    Ok((tp.plan, per_task))
}

#[cfg(test)]
mod tests {
    use super::group_chunks;

    #[test]
    fn groups_cover_every_chunk_once_in_order() {
        for (points, tasks) in [
            (vec![50, 40, 30, 20, 10, 5, 5, 1], 3),
            (vec![10, 10, 10, 10], 4),
            (vec![10, 10], 5),
            (vec![100, 1, 1, 1], 2),
            (vec![7], 1),
        ] {
            let g = group_chunks(&points, tasks);
            assert_eq!(g.len(), tasks);
            assert_eq!(g[0].start, 0);
            assert_eq!(g[tasks - 1].end, points.len());
            for w in g.windows(2) {
                assert_eq!(w[0].end, w[1].start, "{g:?}");
            }
        }
        assert_eq!(
            group_chunks(&[10, 10, 10, 10], 4),
            vec![0..1, 1..2, 2..3, 3..4]
        );
        assert_eq!(group_chunks(&[10, 10], 3), vec![0..1, 1..2, 2..2]);
    }
}
