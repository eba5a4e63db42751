use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;
use strata_server::{ServerConfig, bind, run, shutdown_signal};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Directory holding datasets (each a subdirectory with metadata.json).
    dir: PathBuf,
    /// Address to listen on.
    #[arg(long, default_value = "127.0.0.1:8080")]
    bind: String,
    /// Require `Authorization: Bearer TOKEN` on every request.
    #[arg(long)]
    token: Option<String>,
    /// Send CORS headers allowing this origin (`*` for any) so browsers may fetch.
    #[arg(long)]
    cors: Option<String>,
    /// Open connections at most; more wait in the listen backlog.
    #[arg(long, default_value_t = 512)]
    max_connections: usize,
    /// Seconds to answer a request once its headers arrived.
    #[arg(long, default_value_t = 30)]
    request_timeout: u64,
    /// Seconds a connection may make no progress before it is closed.
    #[arg(long, default_value_t = 60)]
    idle_timeout: u64,
    /// Seconds a client has to send its request headers.
    #[arg(long, default_value_t = 10)]
    header_timeout: u64,
    /// No access log lines on stderr.
    #[arg(long)]
    quiet: bool,
}

pub fn run_serve(a: Args) -> anyhow::Result<ExitCode> {
    let mut config = ServerConfig::new(&a.dir)?;
    config.token = a.token.filter(|t| !t.is_empty());
    config.cors = a.cors;
    config.max_connections = a.max_connections.max(1);
    config.request_timeout = Duration::from_secs(a.request_timeout.max(1));
    config.idle_timeout = Duration::from_secs(a.idle_timeout.max(1));
    config.header_timeout = Duration::from_secs(a.header_timeout.max(1));
    config.access_log = !a.quiet;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    runtime.block_on(async {
        let listener = bind(&a.bind).await?;
        let addr = listener.local_addr()?;
        // Whoever started us may have closed stdout: a banner that cannot be printed is no
        // reason to stop serving.
        let token_note = if config.token.is_some() {
            " (token required)"
        } else {
            ""
        };
        let mut out = std::io::stdout();
        let _ = writeln!(
            out,
            "serving {} on http://{addr}/{token_note}",
            config.root.display()
        );
        let _ = out.flush();
        run(listener, config, shutdown_signal()).await?;
        let _ = writeln!(std::io::stdout(), "stopped");
        anyhow::Ok(())
    })?;
    Ok(ExitCode::SUCCESS)
}
