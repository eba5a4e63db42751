//! `strata convert`: the phases in order, in a work directory that becomes the dataset only
//! when complete. Chunks commit in plan order, so output is byte-for-byte reproducible, and a
//! journal of committed chunks lets `--resume` pick up after an interruption.

use crate::chunk_step::{ChunkStep, NoStep, add_totals};
use crate::disk::PeakWatch;
use crate::error::{ConvertError, Result};
use crate::finish::{finish, merge_top};
use crate::halo::Halos;
use crate::index::{Indexing, index_chunks};
use crate::journal::{Committer, read_journal, resumable_plan, run_fingerprint, save_plan};
use crate::prepare::prepare;
use crate::progress::{Phases, Progress};
use crate::replace::{Folder, check_output};
use crate::sampling::Sampling;
use crate::sys::peak_rss_bytes;
use crate::workdir::WorkDir;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;
use strata_format::RowLayout;

pub use crate::progress::PhaseTime;

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
    /// Where the work files go (`--temp-dir`); beside the output when `None`.
    pub temp_dir: Option<PathBuf>,
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
    /// The most disk the conversion took at once, work files and output together (sampled).
    pub peak_disk_bytes: u64,
    pub resumed_chunks: usize,
    pub phases: Vec<PhaseTime>,
    pub warnings: Vec<String>,
}

/// Converts with no per-chunk step.
pub fn convert(opts: &ConvertOptions) -> Result<ConvertSummary> {
    convert_with(opts, &NoStep)
}

/// Converts, running `step` on every chunk between reading it and building its tree.
pub fn convert_with(opts: &ConvertOptions, step: &dyn ChunkStep) -> Result<ConvertSummary> {
    if opts.inputs.is_empty() {
        return Err(ConvertError::Usage("no input files given".into()));
    }
    check_output(&opts.output, opts.overwrite, Folder::Dataset)?;
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
    // A folder that does not exist yet is made; a file (or a link to nothing) in its place is a
    // mistake.
    if let Some(temp) = &opts.temp_dir
        && temp.symlink_metadata().is_ok()
        && !temp.is_dir()
    {
        return Err(ConvertError::Usage(format!(
            "--temp-dir {} is not a folder",
            temp.display()
        )));
    }
    let threads = opts.threads.max(1);
    // The LAZ decompressor runs on rayon's global pool; size it once to --threads.
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global();
    // The folders of --temp-dir this run makes, deepest first: removed again once the work
    // in them is gone (a plan kept for --resume keeps them). Only up to a `..`: in
    // `gone/../kept` the run makes `gone`, and `kept`, which does not exist as written, may.
    let made: Vec<PathBuf> = opts
        .temp_dir
        .iter()
        .flat_map(|t| {
            let before_up: PathBuf = t
                .components()
                .take_while(|c| *c != std::path::Component::ParentDir)
                .collect();
            let missing: Vec<PathBuf> = before_up
                .ancestors()
                .take_while(|a| !a.as_os_str().is_empty() && a.symlink_metadata().is_err())
                .map(Path::to_path_buf)
                .collect();
            missing
        })
        .collect();
    let wd = WorkDir::new(&opts.output, opts.temp_dir.as_deref());
    // Refused here, before the run whose failure would clear the folder the other run owns.
    let _lock = wd.lock(&opts.output)?;
    let mut watched = vec![wd.root().to_path_buf()];
    if wd.separate() {
        watched.push(wd.work().to_path_buf());
    }
    let watch = PeakWatch::start(watched);
    let result = run(opts, &wd, threads, step, &watch);
    // Once the plan is saved the work directory is worth keeping for --resume (this run's,
    // or an earlier one's under another --temp-dir).
    if result.is_err() && !wd.plan().exists() && wd.plan_elsewhere().is_none() {
        wd.remove_all();
    }
    for folder in &made {
        if std::fs::remove_dir(folder).is_err() {
            break;
        }
    }
    result
}

fn run(
    opts: &ConvertOptions,
    wd: &WorkDir,
    threads: usize,
    step: &dyn ChunkStep,
    watch: &PeakWatch,
) -> Result<ConvertSummary> {
    let start = Instant::now();
    let mut phases = Phases::new(Progress::new(opts.quiet));
    let fp = run_fingerprint(opts, step);
    let plan = match resumable_plan(opts, wd, &fp)? {
        Some(plan) => plan,
        None => {
            wd.create_fresh()?;
            let plan = prepare(opts, wd, threads, &mut phases, fp, step)?;
            save_plan(wd, &plan)?;
            plan
        }
    };
    // A resumed run says again what the first run said.
    let mut warnings = plan.warnings.clone();
    let layout = RowLayout::new(plan.attributes.clone());
    let mut journal = read_journal(wd, plan.chunks.len())?;
    let resumed = journal.len();
    let halos = Halos::new(&plan, layout.stride, step.halo_margin(&plan));
    if halos.needed() {
        let bands = (plan.chunks.len() - resumed) as u64;
        phases.timed("halo", Some((bands, "chunks")), |bar| {
            halos.write_bands(wd, resumed, threads, threads, bar)
        })?;
    }
    let remaining: u64 = plan.chunks[resumed..].iter().map(|c| c.points).sum();
    let committer = phases.timed("index", Some((remaining, "points")), |bar| {
        let committer = Committer::open(wd, &journal)?;
        let ix = Indexing {
            plan: &plan,
            layout: &layout,
            sampling: opts.sampling,
            threads,
            memory_limit: opts.memory_limit,
            parts: threads,
            step,
            halos: &halos,
            wd,
        };
        let (entries, committer) = index_chunks(&ix, resumed..plan.chunks.len(), committer, bar)?;
        journal.extend(entries);
        Ok(committer)
    })?;
    let merged = phases.timed("merge", None, |_| {
        merge_top(
            &|i| wd.chunk_root(i),
            &plan,
            &layout,
            opts.sampling,
            &journal,
            committer,
        )
    })?;
    let mut totals = Vec::new();
    for entry in &journal {
        add_totals(&mut totals, &entry.step);
    }
    // The dataset is complete in the folder just before the rename.
    let done = phases.timed("finish", None, |_| {
        watch.sample();
        finish(opts, wd, &plan, merged, &|meta| step.record(&totals, meta))
    })?;
    warnings.extend(step.warnings(&totals));
    let seconds = start.elapsed().as_secs_f64();
    Ok(ConvertSummary {
        output: opts.output.clone(),
        points: done.points,
        nodes: done.nodes,
        depth: done.depth,
        chunks: plan.chunks.len(),
        seconds,
        points_per_second: done.points as f64 / seconds.max(1e-9),
        peak_memory_bytes: peak_rss_bytes(),
        dataset_bytes: done.dataset_bytes,
        peak_disk_bytes: watch.sample().max(done.dataset_bytes),
        resumed_chunks: resumed,
        phases: phases.into_times(),
        warnings,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::chunk_step::{ChunkRows, GridBox, Halo, StepTotals};
    use crate::prepare::Plan;
    use crate::synth::{Scene, synth};
    use std::collections::BTreeMap;
    use std::fs;
    use std::path::Path;
    use std::sync::Mutex;
    use strata_format::row_position;

    /// A city of 300k points, cut into several chunks by a small memory limit.
    pub(crate) fn city(dir: &Path, output: &str) -> ConvertOptions {
        let las = dir.join("city.las");
        if !las.exists() {
            synth(&las, 300_000, Scene::City, 7, 0.0, false).expect("synth");
        }
        ConvertOptions {
            inputs: vec![las],
            output: dir.join(output),
            memory_limit: 64 << 20,
            threads: 2,
            sampling: Sampling::Poisson,
            overwrite: false,
            resume: false,
            quiet: true,
            temp_dir: None,
        }
    }

    /// Every file of dataset `a` has the same bytes in dataset `b`, and there are no others.
    pub(crate) fn assert_same_dataset(a: &Path, b: &Path) {
        let names = |d: &Path| -> Vec<_> {
            let mut v: Vec<_> = fs::read_dir(d)
                .expect("dataset dir")
                .map(|e| e.expect("entry").file_name())
                .collect();
            v.sort();
            v
        };
        assert_eq!(names(a), names(b));
        for name in names(a) {
            let (x, y) = (fs::read(a.join(&name)), fs::read(b.join(&name)));
            assert!(x.expect("read") == y.expect("read"), "{name:?} differs");
        }
    }

    /// What the step saw of one chunk: its bounds, its halo's reach, its rows' positions and
    /// its halo's size.
    type Seen = (GridBox, GridBox, Vec<[i32; 3]>, usize);

    /// Records what each chunk saw.
    struct Recording {
        margin: f64,
        seen: Mutex<BTreeMap<usize, Seen>>,
    }

    impl ChunkStep for Recording {
        fn halo_margin(&self, _plan: &Plan) -> f64 {
            self.margin
        }

        fn process(&self, chunk: &mut ChunkRows, halo: &Halo) -> Result<StepTotals> {
            let steps = [0, 1, 2].map(|a| (self.margin / chunk.scale[a]).round() as i64);
            assert_eq!(halo.reach(), chunk.bounds.grown(steps));
            let own: Vec<[i32; 3]> = chunk
                .rows
                .chunks_exact(chunk.layout.stride)
                .map(row_position)
                .collect();
            assert!(own.iter().all(|&p| chunk.bounds.contains(p)));
            for row in halo.rows() {
                let p = row_position(row);
                assert!(
                    !chunk.bounds.contains(p),
                    "halo point {p:?} inside its chunk"
                );
                assert!(
                    halo.reach().contains(p),
                    "halo point {p:?} beyond the margin"
                );
            }
            let mut seen = self.seen.lock().expect("lock");
            seen.insert(chunk.index, (chunk.bounds, halo.reach(), own, halo.len()));
            Ok(Vec::new())
        }
    }

    #[test]
    fn step_sees_every_chunk_with_the_points_within_its_margin() {
        let dir = tempfile::tempdir().expect("tempdir");
        let plain = convert(&city(dir.path(), "plain")).expect("plain convert");
        let step = Recording {
            margin: 1.0,
            seen: Mutex::new(BTreeMap::new()),
        };
        let summary = convert_with(&city(dir.path(), "step"), &step).expect("convert");
        assert!(summary.chunks >= 4, "{} chunks", summary.chunks);
        assert!(summary.phases.iter().any(|p| p.name == "halo"));
        let seen = step.seen.into_inner().expect("lock");
        assert_eq!(seen.len(), summary.chunks);
        // The halo is every point of the other chunks within the margin, none missed.
        let mut with_halo = 0;
        for (i, (_, reach, _, got)) in &seen {
            let expected: usize = seen
                .iter()
                .filter(|(j, _)| *j != i)
                .map(|(_, (_, _, pts, _))| pts.iter().filter(|&&p| reach.contains(p)).count())
                .sum();
            assert_eq!(*got, expected, "chunk {i}");
            with_halo += (*got > 0) as usize;
        }
        assert!(with_halo >= 2, "{with_halo} chunks had a halo");
        // A step that changes nothing changes nothing in the output.
        assert_same_dataset(&plain.output, &summary.output);
    }

    #[test]
    fn a_second_conversion_into_one_output_is_refused_and_clears_nothing() {
        let dir = tempfile::tempdir().expect("tempdir");
        let opts = city(dir.path(), "ds");
        // The first conversion, as far as the second can see: it holds the folder and has
        // written into it.
        let wd = WorkDir::for_output(&opts.output);
        let first = wd.lock(&opts.output).expect("first lock");
        let theirs = wd.root().join("theirs.bin");
        fs::write(&theirs, b"the first run's").expect("write");
        let err = convert(&opts).expect_err("a second conversion must be refused");
        assert!(
            err.to_string()
                .contains("is being written by another conversion"),
            "{err}"
        );
        assert!(theirs.exists(), "the first run's files are left alone");
        assert!(!opts.output.exists());
        // Once the first is gone, a conversion clears what it left and runs.
        drop(first);
        convert(&opts).expect("convert");
        assert!(!wd.root().exists() && opts.output.is_dir());
    }

    #[test]
    fn without_a_margin_the_halo_is_empty() {
        let dir = tempfile::tempdir().expect("tempdir");
        let step = Recording {
            margin: 0.0,
            seen: Mutex::new(BTreeMap::new()),
        };
        let summary = convert_with(&city(dir.path(), "ds"), &step).expect("convert");
        let seen = step.seen.into_inner().expect("lock");
        assert_eq!(seen.len(), summary.chunks);
        assert!(
            seen.values()
                .all(|(b, reach, _, halo)| *halo == 0 && b == reach)
        );
        assert!(summary.phases.iter().all(|p| p.name != "halo"));
    }

    struct PanicsOn(usize);

    impl ChunkStep for PanicsOn {
        fn process(&self, chunk: &mut ChunkRows, _halo: &Halo) -> Result<StepTotals> {
            if chunk.index == self.0 {
                panic!("test step gives up on chunk {}", chunk.index);
            }
            Ok(Vec::new())
        }
    }

    #[test]
    fn a_panicking_worker_is_an_internal_fault_naming_its_chunk() {
        let dir = tempfile::tempdir().expect("tempdir");
        let opts = city(dir.path(), "ds");
        let err = convert_with(&opts, &PanicsOn(1)).expect_err("the step panics");
        let text = err.to_string();
        match &err {
            ConvertError::Internal { during, message } => {
                assert!(during.starts_with("indexing chunk 1 (x "), "{text}");
                assert_eq!(message, "test step gives up on chunk 1");
            }
            other => panic!("not an internal fault: {other:?}"),
        }
        assert!(text.ends_with("; please report this"), "{text}");
        // The chunks before it stay committed: a resumed run finishes the same dataset.
        let resumed = convert(&ConvertOptions {
            resume: true,
            ..opts.clone()
        })
        .expect("resume");
        let plain = convert(&city(dir.path(), "plain")).expect("plain convert");
        assert_same_dataset(&plain.output, &resumed.output);
    }

    #[test]
    fn a_normals_run_begun_by_a_build_with_other_rules_does_not_resume() {
        let dir = tempfile::tempdir().expect("tempdir");
        let opts = city(dir.path(), "ds");
        convert_with(&opts, &PanicsOn(1)).expect_err("the step panics");
        let wd = WorkDir::new(&opts.output, None);
        let step = crate::normals::NormalStep::new(crate::normals::NormalOptions::default())
            .expect("step");
        // The plan as a build before the rules were named would have saved it.
        let now = crate::journal::run_fingerprint(&opts, &step);
        let rules = format!("normals:{}:", crate::normals::RULES);
        assert!(now.contains(&rules), "{now}");
        let mut plan: serde_json::Value =
            serde_json::from_slice(&fs::read(wd.plan()).expect("plan")).expect("plan JSON");
        plan["fingerprint"] = now.replacen(&rules, "normals:", 1).into();
        fs::write(wd.plan(), serde_json::to_vec(&plan).expect("JSON")).expect("write");
        let resume = ConvertOptions {
            resume: true,
            ..opts.clone()
        };
        let e = convert_with(&resume, &step)
            .expect_err("refused")
            .to_string();
        assert!(
            e.contains("begun by a build that computes them otherwise"),
            "{e}"
        );
    }

    #[test]
    fn a_resume_refuses_an_octree_file_damaged_since() {
        let dir = tempfile::tempdir().expect("tempdir");
        let opts = city(dir.path(), "ds");
        convert_with(&opts, &PanicsOn(1)).expect_err("the step panics");
        let wd = WorkDir::new(&opts.output, None);
        let octree = wd.dataset_file(strata_format::DatasetFile::Octree);
        let good = std::fs::read(&octree).expect("octree");
        let head = strata_format::OCTREE_HEAD_SIZE as usize;
        assert!(good.len() > head + 1, "chunk 0 committed nodes");
        let resume = || {
            convert(&ConvertOptions {
                resume: true,
                ..opts.clone()
            })
        };
        // A byte changed in chunk 0's nodes, then the file cut inside them.
        let mut flipped = good.clone();
        flipped[head + 1] ^= 0x40;
        std::fs::write(&octree, &flipped).expect("write");
        let e = resume().expect_err("damaged").to_string();
        assert!(
            e.contains("octree.bin")
                && e.contains("chunk 0's nodes")
                && e.contains("cannot resume"),
            "{e}"
        );
        std::fs::write(&octree, &good[..head + 1]).expect("write");
        let e = resume().expect_err("cut").to_string();
        assert!(e.contains(&format!("is {} bytes long", head + 1)), "{e}");
        assert!(
            !opts.output.exists(),
            "no dataset from a damaged work directory"
        );
        // Whole again, it resumes to the dataset a single run makes.
        std::fs::write(&octree, &good).expect("write");
        let resumed = resume().expect("resume");
        let plain = convert(&city(dir.path(), "plain")).expect("plain convert");
        assert_same_dataset(&plain.output, &resumed.output);
    }
}
