//! Every benchmark answers `--help` with its usage and exit 0, before it builds or runs anything.

use std::process::Command;

#[test]
fn every_benchmark_prints_its_usage_on_help() {
    for (name, exe) in [
        ("convert-bench", env!("CARGO_BIN_EXE_convert-bench")),
        ("normals-bench", env!("CARGO_BIN_EXE_normals-bench")),
        ("quality", env!("CARGO_BIN_EXE_quality")),
        ("render-bench", env!("CARGO_BIN_EXE_render-bench")),
        ("serve-bench", env!("CARGO_BIN_EXE_serve-bench")),
    ] {
        let run = Command::new(exe).arg("--help").output().expect("runs");
        let stdout = String::from_utf8_lossy(&run.stdout);
        assert!(run.status.success(), "{name} --help: {run:?}");
        assert!(
            stdout.contains(&format!("--bin {name} --")) && stdout.contains("[--"),
            "{name} --help printed {stdout:?}"
        );
    }
}
