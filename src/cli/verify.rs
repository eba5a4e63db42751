use std::path::PathBuf;
use std::process::ExitCode;
use strata_format::verify_dataset;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The dataset directory.
    dataset: PathBuf,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let report = verify_dataset(&a.dataset);
    for f in &report.faults {
        eprintln!("fault: {}: {f}", a.dataset.display());
    }
    if report.is_ok() {
        println!(
            "ok: {} points in {} nodes, {} hierarchy pages, every checksum matches",
            report.points_checked, report.nodes_checked, report.pages_checked
        );
        Ok(ExitCode::SUCCESS)
    } else {
        eprintln!("{} fault(s) found", report.faults.len());
        Ok(ExitCode::FAILURE)
    }
}
