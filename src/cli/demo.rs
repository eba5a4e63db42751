use super::convert::print_summary;
use std::path::PathBuf;
use std::process::ExitCode;
use strata_converter::synth::{Scene, synth};
use strata_converter::{ConvertOptions, Sampling, convert};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Where to put the demo's files (default: a "strata-demo" folder in the system temp dir).
    #[arg(long)]
    dir: Option<PathBuf>,
    /// Points in the synthetic scene.
    #[arg(long, default_value = "2M", value_parser = super::synth::parse_count)]
    points: u64,
}

/// Synthesizes a city, converts it, verifies it and prints what a viewer would open.
/// (The viewer is a later stage; until it lands the demo ends with the dataset's summary.)
pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let dir = a
        .dir
        .unwrap_or_else(|| std::env::temp_dir().join("strata-demo"));
    std::fs::create_dir_all(&dir)?;
    let las = dir.join("city.laz");
    let dataset = dir.join("city.strata");
    println!("1/3 synthesizing {} points -> {}", a.points, las.display());
    synth(&las, a.points, Scene::City, 1, true)?;
    println!("2/3 converting -> {}", dataset.display());
    let summary = convert(&ConvertOptions {
        inputs: vec![las],
        output: dataset.clone(),
        memory_limit: 1 << 30,
        threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        sampling: Sampling::Poisson,
        overwrite: true,
        resume: false,
        quiet: false,
    })?;
    print_summary(&summary);
    println!("3/3 verifying");
    let report = strata_format::verify_dataset(&dataset);
    if !report.is_ok() {
        for f in &report.faults {
            eprintln!("fault: {f}");
        }
        anyhow::bail!(
            "{}: the demo dataset failed verification",
            dataset.display()
        );
    }
    println!(
        "ok: {} points in {} nodes verified; inspect it with `strata info {}`",
        report.points_checked,
        report.nodes_checked,
        dataset.display()
    );
    Ok(ExitCode::SUCCESS)
}
