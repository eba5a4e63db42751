//! `strata`: a thin command-line front over the Strata crates.

mod cli;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    // A reader that stops early (`strata info DS | head -3`) ends the process quietly, as it
    // ends other command-line tools, rather than as a panic in the next print: Rust starts with
    // SIGPIPE ignored, so a closed pipe is an error on every write after it.
    #[cfg(unix)]
    // SAFETY: at the start of main, before any thread exists; restores the default action.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let args = cli::Cli::parse();
    match cli::run(args) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
