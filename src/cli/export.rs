use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The dataset directory.
    dataset: PathBuf,
    /// The file to write (.las, .laz or .ply).
    #[arg(short, long)]
    output: PathBuf,
    /// Replace the output if it exists.
    #[arg(long)]
    overwrite: bool,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let n = strata_converter::export::export(&a.dataset, &a.output, a.overwrite)?;
    println!("exported {n} points -> {}", a.output.display());
    Ok(ExitCode::SUCCESS)
}
