use anyhow::Context;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use strata_converter::replace::{Folder, check_output};
use strata_converter::sys::{format_bytes, parse_memory_limit};
use strata_converter::tasks::{finish_tasks, plan_tasks, run_task, step_for};
use strata_converter::{
    ConvertOptions, ConvertSummary, NormalMode, NormalOptions, Orient, Sampling, convert_with,
};

/// More would only cost memory and switching: no machine has that many cores.
const MAX_THREADS: u64 = 1024;
/// A batch engine's job array is far smaller (Slurm's default limit is 1001); every task has
/// its share files in the plan.
const MAX_TASKS: u64 = 100_000;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input files (.las, .laz, .ply, .e57); several make one dataset.
    #[arg(required_unless_present = "plan")]
    inputs: Vec<PathBuf>,
    /// The dataset directory to create.
    #[arg(short, long, required_unless_present_any = ["plan_only", "plan"])]
    output: Option<PathBuf>,
    /// Instead of converting, count the inputs and write into this folder (on storage every
    /// machine shares) a plan of --tasks independent tasks, for a batch engine to run with
    /// --plan PLAN --task K and then --plan PLAN --finish.
    #[arg(long, value_name = "PLAN", requires = "tasks",
          conflicts_with_all = ["output", "plan", "resume", "temp_dir"])]
    plan_only: Option<PathBuf>,
    /// How many tasks --plan-only groups the chunks into (at most 100000).
    #[arg(long, value_name = "N", requires = "plan_only",
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=MAX_TASKS))]
    tasks: Option<usize>,
    /// A plan --plan-only wrote, to run one of its tasks (--task K) or to finish it into the
    /// dataset (--finish -o DATASET). The plan fixes the inputs and every option that shapes
    /// the dataset (--memory-limit, --threads, --sampling, --normals...): give them to
    /// --plan-only, not here.
    #[arg(long, value_name = "PLAN",
          conflicts_with_all = ["inputs", "memory_limit", "threads", "sampling", "normals",
              "normal_k", "orient", "viewpoint", "normal_radius", "temp_dir", "plan_only"])]
    plan: Option<PathBuf>,
    /// Build task K (0 to N-1) of --plan: its chunks, continuing what an interrupted run of it
    /// left; a finished task is not run again.
    #[arg(long, value_name = "K", requires = "plan", conflicts_with_all = ["finish", "output"])]
    task: Option<usize>,
    /// Merge the tasks of --plan, all finished, into the dataset -o names; the plan folder is
    /// removed once the dataset is in place.
    #[arg(long, requires_all = ["plan", "output"])]
    finish: bool,
    /// Peak memory to stay within, e.g. 512MiB or 4GiB.
    #[arg(long, default_value = "2GiB", value_parser = parse_memory_limit)]
    memory_limit: u64,
    /// Worker threads (default: all cores; at most 1024).
    #[arg(long, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=MAX_THREADS))]
    threads: Option<usize>,
    /// How inner nodes choose their points.
    #[arg(long, value_enum, default_value = "poisson")]
    sampling: SamplingArg,
    /// Replace the output if it exists.
    #[arg(long)]
    overwrite: bool,
    /// Continue an interrupted conversion from its finished chunks.
    #[arg(long)]
    resume: bool,
    /// No progress bars and no summary.
    #[arg(short, long)]
    quiet: bool,
    /// Put the work files (staging rows, chunk files, halo bands) under this folder, e.g. on
    /// another disk; the dataset is still written beside the output and renamed. Give it again
    /// with --resume.
    #[arg(long, value_name = "DIR")]
    temp_dir: Option<PathBuf>,
    /// Also write the summary as JSON to this file.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// What -o becomes: a Strata dataset (the default), or `potree2`, a Potree 2.0 dataset for
    /// Potree and potree-core (the Strata dataset is built beside it as
    /// `.NAME.strata-for-potree2`, exported node by node and removed).
    #[arg(long, value_enum, default_value = "strata",
          conflicts_with_all = ["plan_only", "plan"])]
    format: OutputFormat,
    /// Estimate per-point normals, disc radii and surface variation from the k nearest
    /// neighbours. `keep` (the default) keeps the inputs' normals and disc radii where they
    /// have them; `compute` replaces them.
    #[arg(long, value_enum, num_args = 0..=1, default_missing_value = "keep", value_name = "MODE")]
    normals: Option<NormalsArg>,
    /// Neighbours per estimate, the point itself included.
    #[arg(long, default_value_t = 16, requires = "normals")]
    normal_k: usize,
    /// Which way normals face: towards the scanner where the input says where it stood (E57
    /// poses, --viewpoint), else up (the default); or always up, always the scanner, or as
    /// estimated (none). `up` and `scanner` turn kept input normals too; by default they stay
    /// as the inputs give them.
    #[arg(long, value_enum, requires = "normals")]
    orient: Option<OrientArg>,
    /// Where a single static scanner stood, X,Y,Z in the inputs' coordinates.
    #[arg(long, value_parser = parse_point, requires = "normals", allow_hyphen_values = true)]
    viewpoint: Option<[f64; 3]>,
    /// Neighbours farther than this (the inputs' units) are not used, so that estimates do not
    /// depend on how the cloud is cut into chunks (default: twice the k-th neighbour's
    /// distance expected where points are sparser than 90% of them).
    #[arg(long, requires = "normals", allow_negative_numbers = true)]
    normal_radius: Option<f64>,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum NormalsArg {
    Keep,
    Compute,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum OrientArg {
    Up,
    Scanner,
    None,
}

fn parse_point(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|c| c.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("\"{s}\" is not X,Y,Z"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([x, y, z]),
        _ => Err(format!("\"{s}\" is not three finite numbers X,Y,Z")),
    }
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum SamplingArg {
    Poisson,
    Random,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OutputFormat {
    Strata,
    Potree2,
}

/// Where `--format potree2` builds the Strata dataset it exports from.
fn potree2_source(output: &Path) -> PathBuf {
    let name = output.file_name().unwrap_or_default().to_string_lossy();
    output.with_file_name(format!(".{name}.strata-for-potree2"))
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    // Clap does not enforce `requires` between these two: without this, -o would silently
    // become a plan folder, and --plan would ignore it.
    if a.tasks.is_some() && a.plan_only.is_none() {
        anyhow::bail!(
            "--tasks N needs --plan-only PLAN (a conversion as tasks starts with a plan)"
        );
    }
    let plan = a.plan.as_deref().or(a.plan_only.as_deref());
    let owned: Vec<&Path> = plan.into_iter().collect();
    super::check_stats_path(&a.stats, a.output.as_deref(), &a.inputs, &owned)?;
    if let Some(plan) = &a.plan {
        return run_plan(plan, &a);
    }
    let threads = a
        .threads
        // All cores, within the 1024 a plan's tasks accept.
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get().min(1024)));
    let normals = normal_options(&a);
    let opts = ConvertOptions {
        inputs: a.inputs,
        // Clap requires one of them.
        output: a.plan_only.clone().or(a.output).unwrap_or_default(),
        memory_limit: a.memory_limit,
        threads,
        sampling: match a.sampling {
            SamplingArg::Poisson => Sampling::Poisson,
            SamplingArg::Random => Sampling::Random,
        },
        overwrite: a.overwrite,
        resume: a.resume,
        quiet: a.quiet,
        temp_dir: a.temp_dir,
    };
    if let Some(tasks) = a.tasks {
        let summary = plan_tasks(&opts, normals, tasks)?;
        for w in &summary.warnings {
            eprintln!("warning: {w}");
        }
        if !a.quiet {
            let empty = summary.tasks.iter().filter(|&&n| n == 0).count();
            println!(
                "planned {} points in {} chunks as {} tasks -> {} ({:.2} s){}",
                summary.points,
                summary.chunks,
                summary.tasks.len(),
                summary.plan.display(),
                summary.seconds,
                if empty > 0 {
                    format!("; {empty} tasks have no chunk (fewer chunks than tasks)")
                } else {
                    String::new()
                }
            );
        }
        return write_stats(&a.stats, serde_json::to_string_pretty(&summary));
    }
    let step = step_for(&normals)?;
    if a.format == OutputFormat::Potree2 {
        return convert_to_potree2(opts, step.as_ref(), &a.stats);
    }
    let summary = convert_with(&opts, step.as_ref())?;
    report(&summary, a.quiet, &a.stats)
}

/// `--format potree2`: the conversion into a Strata dataset beside the output, then its
/// export, then its removal. `--resume` continues the conversion where it stopped.
fn convert_to_potree2(
    mut opts: ConvertOptions,
    step: &dyn strata_converter::ChunkStep,
    stats: &Option<PathBuf>,
) -> anyhow::Result<ExitCode> {
    let output = opts.output.clone();
    check_output(&output, opts.overwrite, Folder::Dataset)?;
    strata_converter::potree2::refuse_file_name(&output)?;
    // Held through the export too: a second run would replace the hidden source this one
    // exports from.
    let _lock = strata_converter::workdir::WorkDir::for_output(&output).lock_only(&output)?;
    let source = potree2_source(&output);
    let replace = opts.overwrite;
    opts.output = source.clone();
    // A conversion interrupted before its end resumes; a source it left whole (the export
    // was interrupted) is built again, as there is nothing to resume.
    let work = strata_converter::workdir::WorkDir::new(&source, opts.temp_dir.as_deref());
    opts.resume &= work.plan().exists();
    // The hidden source is this command's own: one left by an earlier run, whole or not, is
    // replaced (a resumed run replaces it at its end too; refusing it left a run killed twice
    // that no --resume could continue).
    opts.overwrite = true;
    let summary = convert_with(&opts, step)?;
    let notes = strata_converter::export::export_notes(&source, &output, true);
    let exported = strata_converter::potree2::export_potree2(&source, &output, replace);
    std::fs::remove_dir_all(&source)
        .with_context(|| format!("cannot remove {}", source.display()))?;
    let exported = exported?;
    if !opts.quiet {
        print_summary(&summary);
        println!(
            "written as Potree 2.0: {} points in {} nodes, {} -> {}",
            exported.points,
            exported.nodes,
            format_bytes(exported.bytes),
            output.display()
        );
    }
    for w in summary.warnings.iter().chain(notes.iter().flatten()) {
        eprintln!("warning: {w}");
    }
    write_stats(stats, serde_json::to_string_pretty(&summary))
}

/// `--plan PLAN --task K` or `--plan PLAN --finish -o DATASET`.
fn run_plan(plan: &Path, a: &Args) -> anyhow::Result<ExitCode> {
    if let Some(k) = a.task {
        let summary = run_task(plan, k, a.quiet)?;
        if !a.quiet {
            println!(
                "task {} of {}: chunks {}..{}, {} points, {} of {} shares distributed here, {}{:.2} s",
                summary.task,
                summary.tasks,
                summary.chunks.start,
                summary.chunks.end,
                summary.points,
                summary.shares_distributed,
                summary.tasks,
                if summary.already_done {
                    "finished before, nothing to do, ".to_string()
                } else if summary.resumed_chunks > 0 {
                    format!("{} chunks resumed, ", summary.resumed_chunks)
                } else {
                    String::new()
                },
                summary.seconds
            );
        }
        return write_stats(&a.stats, serde_json::to_string_pretty(&summary));
    }
    let Some(output) = a.output.as_deref().filter(|_| a.finish) else {
        anyhow::bail!("--plan needs --task K (to run a task) or --finish -o DATASET (to finish)");
    };
    let summary = finish_tasks(plan, output, a.overwrite, a.quiet)?;
    report(&summary, a.quiet, &a.stats)
}

fn normal_options(a: &Args) -> Option<NormalOptions> {
    a.normals.map(|mode| NormalOptions {
        k: a.normal_k,
        mode: match mode {
            NormalsArg::Keep => NormalMode::Keep,
            NormalsArg::Compute => NormalMode::Compute,
        },
        orient: match a.orient {
            None => Orient::Auto,
            Some(OrientArg::Up) => Orient::Up,
            Some(OrientArg::Scanner) => Orient::Scanner,
            Some(OrientArg::None) => Orient::None,
        },
        viewpoint: a.viewpoint,
        radius: a.normal_radius,
    })
}

/// Prints a conversion's warnings and summary and writes its stats.
fn report(
    summary: &ConvertSummary,
    quiet: bool,
    stats: &Option<PathBuf>,
) -> anyhow::Result<ExitCode> {
    // Warnings say the result differs from the input (a coarsened scale): --quiet does not
    // hide them.
    for w in &summary.warnings {
        eprintln!("warning: {w}");
    }
    if !quiet {
        print_summary(summary);
    }
    write_stats(stats, serde_json::to_string_pretty(summary))
}

/// Writes `json` (a summary) to `--stats`, if given.
fn write_stats(
    stats: &Option<PathBuf>,
    json: serde_json::Result<String>,
) -> anyhow::Result<ExitCode> {
    if let Some(path) = stats {
        super::write_whole(path, json?.as_bytes())?;
    }
    Ok(ExitCode::SUCCESS)
}

pub fn print_summary(s: &ConvertSummary) {
    println!("converted {} -> {}", s.points, s.output.display());
    println!(
        "  points {}  nodes {}  depth {}  chunks {}{}",
        s.points,
        s.nodes,
        s.depth,
        s.chunks,
        if s.resumed_chunks > 0 {
            format!(" ({} resumed)", s.resumed_chunks)
        } else {
            String::new()
        }
    );
    println!(
        "  {:.2} s  {:.2} M points/s  peak memory {}  dataset {}  peak disk {}",
        s.seconds,
        s.points_per_second / 1e6,
        s.peak_memory_bytes
            .map_or_else(|| "unknown".into(), format_bytes),
        format_bytes(s.dataset_bytes),
        format_bytes(s.peak_disk_bytes)
    );
    let phases: Vec<String> = s
        .phases
        .iter()
        .map(|p| format!("{} {:.2}s", p.name, p.seconds))
        .collect();
    println!("  phases: {}", phases.join(", "));
}
