use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The dataset directory.
    dataset: PathBuf,
    /// The file to write (.las, .laz, .ply, or .copc.laz for COPC), or with --format potree2
    /// the folder of the Potree 2.0 dataset.
    #[arg(short, long)]
    output: PathBuf,
    /// What to write: potree2 writes a Potree 2.0 dataset (metadata.json, hierarchy.bin,
    /// octree.bin) for Potree and potree-core; without it, the output's extension decides.
    #[arg(long, value_enum)]
    format: Option<ExportFormat>,
    /// Replace the output if it exists.
    #[arg(long)]
    overwrite: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportFormat {
    /// Potree 2.0 (PotreeConverter 2's layout, DEFAULT encoding).
    Potree2,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let potree2 = a.format == Some(ExportFormat::Potree2);
    for w in strata_converter::export::export_notes(&a.dataset, &a.output, potree2)? {
        eprintln!("warning: {w}");
    }
    match a.format {
        Some(ExportFormat::Potree2) => {
            let s = strata_converter::potree2::export_potree2(&a.dataset, &a.output, a.overwrite)?;
            println!(
                "exported {} points in {} nodes as Potree 2.0 -> {}",
                s.points,
                s.nodes,
                a.output.display()
            );
        }
        None => {
            let n = strata_converter::export::export(&a.dataset, &a.output, a.overwrite)?;
            println!("exported {n} points -> {}", a.output.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}
