//! `strata`: a thin command-line front over the Strata crates.

mod cli;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    // A reader that stops early (`strata info DS | head -3`) ends a command that only prints
    // quietly, as it ends other command-line tools, rather than as a panic in the next print:
    // Rust starts with SIGPIPE ignored, so a closed pipe is an error on every write after it.
    // Commands with sockets keep it ignored: a peer that went away is an error there (a
    // vectored socket write, as hyper makes, raises SIGPIPE).
    #[cfg(unix)]
    if args.prints_local_text() {
        // SAFETY: before any thread exists; restores the default action.
        unsafe {
            libc::signal(libc::SIGPIPE, libc::SIG_DFL);
        }
    }
    match cli::run(args) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
