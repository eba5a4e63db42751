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
        let version = report
            .version
            .map_or(String::new(), |[a, b]| format!("format {a}.{b}"));
        let id = report
            .id
            .map_or("no id".to_string(), |id| format!("id {id}"));
        println!(
            "ok: {version}, {id}: {} points in {} nodes ({} without points), {} hierarchy pages ({} proxies), every checksum matches",
            report.points_checked,
            report.nodes_checked,
            report.empty_nodes,
            report.pages_checked,
            report.proxies_checked
        );
        Ok(ExitCode::SUCCESS)
    } else {
        eprintln!("{} fault(s) found", report.faults.len());
        Ok(ExitCode::FAILURE)
    }
}
