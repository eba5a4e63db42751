//! Helpers the benchmark binaries share, and the quality harness.

pub mod quality;
pub mod wrk;

use anyhow::Context;
use std::path::{Path, PathBuf};
use strata_converter::synth::{Scene, synth};
use strata_converter::{ConvertOptions, ConvertSummary, Sampling, convert};

/// Where the command line asks for help (`--help` or `-h`), prints `usage` and returns true.
pub fn answered_help(usage: &str) -> bool {
    let asked = std::env::args().skip(1).any(|a| a == "--help" || a == "-h");
    if asked {
        println!("{usage}");
    }
    asked
}

/// Parses `100000`, `100k`, `10M`, `1G`.
pub fn parse_count(s: &str) -> anyhow::Result<u64> {
    let t = s.trim();
    let (n, m) = match t.chars().last() {
        Some('k' | 'K') => (&t[..t.len() - 1], 1e3),
        Some('m' | 'M') => (&t[..t.len() - 1], 1e6),
        Some('g' | 'G') => (&t[..t.len() - 1], 1e9),
        _ => (t, 1.0),
    };
    Ok((n.parse::<f64>().with_context(|| format!("bad count {s}"))? * m) as u64)
}

/// Where benchmarks keep their generated inputs (`target/bench-data`).
pub fn bench_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/bench-data")
}

/// A converted synthetic city of `points` points in `dir`, built (and kept) on first use.
pub fn ensure_city_dataset(points: u64, dir: &Path) -> anyhow::Result<PathBuf> {
    let dataset = dir.join(format!("city_{points}.strata"));
    if dataset.join("metadata.json").exists() {
        return Ok(dataset);
    }
    std::fs::create_dir_all(dir)?;
    let las = dir.join(format!("city_{points}.las"));
    if !las.exists() {
        eprintln!("synthesizing {points} points -> {}", las.display());
        synth(&las, points, Scene::City, 1, 0.0, true)?;
    }
    eprintln!("converting -> {}", dataset.display());
    convert_quietly(&las, &dataset, 2 << 30)?;
    Ok(dataset)
}

/// `convert_quietly` with `--normals` (kept where the input has them, else estimated with
/// k = 16 and the default orientation).
pub fn convert_with_normals(
    input: &Path,
    output: &Path,
    memory_limit: u64,
) -> anyhow::Result<ConvertSummary> {
    let step = strata_converter::NormalStep::new(strata_converter::NormalOptions::default())?;
    Ok(strata_converter::convert_with(
        &quiet_options(input, output, memory_limit),
        &step,
    )?)
}

fn quiet_options(input: &Path, output: &Path, memory_limit: u64) -> ConvertOptions {
    ConvertOptions {
        inputs: vec![input.to_path_buf()],
        output: output.to_path_buf(),
        memory_limit,
        threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        sampling: Sampling::Poisson,
        overwrite: true,
        resume: false,
        quiet: true,
        temp_dir: None,
    }
}

/// Converts one input with the default sampling on all cores, replacing `output`, silently.
pub fn convert_quietly(
    input: &Path,
    output: &Path,
    memory_limit: u64,
) -> anyhow::Result<ConvertSummary> {
    Ok(convert(&quiet_options(input, output, memory_limit))?)
}
