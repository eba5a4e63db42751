use anyhow::Context;
use std::path::PathBuf;
use std::process::ExitCode;
use strata_converter::sys::{format_bytes, parse_size};
use strata_converter::{ConvertOptions, ConvertSummary, Sampling, convert};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input files (.las, .laz, .ply); several make one dataset.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// The dataset directory to create.
    #[arg(short, long)]
    output: PathBuf,
    /// Peak memory to stay within, e.g. 512MiB or 4GiB.
    #[arg(long, default_value = "2GiB", value_parser = parse_size)]
    memory_limit: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
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
    /// Also write the summary as JSON to this file.
    #[arg(long)]
    stats: Option<PathBuf>,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum SamplingArg {
    Poisson,
    Random,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let threads = a
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let opts = ConvertOptions {
        inputs: a.inputs,
        output: a.output,
        memory_limit: a.memory_limit,
        threads,
        sampling: match a.sampling {
            SamplingArg::Poisson => Sampling::Poisson,
            SamplingArg::Random => Sampling::Random,
        },
        overwrite: a.overwrite,
        resume: a.resume,
        quiet: a.quiet,
    };
    let summary = convert(&opts)?;
    // Warnings say the result differs from the input (a coarsened scale): --quiet does not
    // hide them.
    for w in &summary.warnings {
        eprintln!("warning: {w}");
    }
    if !a.quiet {
        print_summary(&summary);
    }
    if let Some(path) = a.stats {
        std::fs::write(&path, serde_json::to_string_pretty(&summary)?)
            .with_context(|| format!("cannot write {}", path.display()))?;
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
        "  {:.2} s  {:.2} M points/s  peak memory {}  dataset {}",
        s.seconds,
        s.points_per_second / 1e6,
        s.peak_memory_bytes
            .map_or_else(|| "unknown".into(), format_bytes),
        format_bytes(s.dataset_bytes)
    );
    let phases: Vec<String> = s
        .phases
        .iter()
        .map(|p| format!("{} {:.2}s", p.name, p.seconds))
        .collect();
    println!("  phases: {}", phases.join(", "));
}
