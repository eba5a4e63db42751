use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;
use strata_server::{LogFormat, ServerConfig, bind, run, shutdown_signal};

/// A timeout longer than a year is a mistake, and one near 2^64 seconds overflows the clock.
const MAX_SECONDS: u64 = 366 * 24 * 3600;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Directory holding datasets (each a subdirectory with metadata.json).
    dir: PathBuf,
    /// Address to listen on.
    #[arg(long, default_value = "127.0.0.1:8080")]
    bind: String,
    /// Require `Authorization: Bearer TOKEN` on every request (an empty token is refused).
    #[arg(long, conflicts_with = "token_file")]
    token: Option<String>,
    /// As --token, with the token read from FILE (kept out of `ps`); surrounding whitespace
    /// is dropped.
    #[arg(long, value_name = "FILE")]
    token_file: Option<PathBuf>,
    /// Send CORS headers allowing this origin (`*` for any) so browsers may fetch.
    #[arg(long, value_parser = parse_origin)]
    cors: Option<String>,
    /// Open connections at most (up to 1048576); more wait in the listen backlog.
    #[arg(long, default_value_t = 512,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=1 << 20))]
    max_connections: usize,
    /// Seconds to answer a request once its headers arrived (up to a year).
    #[arg(long, default_value_t = 30, value_parser = clap::value_parser!(u64).range(1..=MAX_SECONDS))]
    request_timeout: u64,
    /// Seconds a connection may make no progress before it is closed (up to a year).
    #[arg(long, default_value_t = 60, value_parser = clap::value_parser!(u64).range(1..=MAX_SECONDS))]
    idle_timeout: u64,
    /// Seconds a client has to send its request headers (up to a year).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=MAX_SECONDS))]
    header_timeout: u64,
    /// Threads for file-system calls (open, stat, read) at most. A few per core serve the
    /// queue; a call stuck on a file that never answers keeps its thread and another takes its
    /// place, until this many (1 to 4096).
    #[arg(long, default_value_t = 64,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=4096))]
    blocking_threads: usize,
    /// Access log lines as `text` or `json` (one object a line).
    #[arg(long, value_enum, default_value_t = LogFormatArg::Text)]
    log_format: LogFormatArg,
    /// No access log lines on stderr.
    #[arg(long)]
    quiet: bool,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum LogFormatArg {
    Text,
    Json,
}

/// An origin for `Access-Control-Allow-Origin`: `*`, `null`, or `scheme://host[:port]`. Refused
/// here rather than left out of every response, where a browser would only say CORS failed.
fn parse_origin(s: &str) -> Result<String, String> {
    // Browsers send the scheme and host in lower case, with no user, path, query or fragment:
    // anything else never matches their `Origin`.
    let well_formed = s == "*"
        || s == "null"
        || s.split_once("://").is_some_and(|(scheme, host)| {
            scheme.starts_with(|c: char| c.is_ascii_lowercase())
                && scheme
                    .chars()
                    .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || "+-.".contains(c))
                && host_and_port(host)
        });
    if well_formed {
        Ok(s.to_string())
    } else {
        Err(format!(
            "\"{}\" is not an origin: give `*`, `null` or scheme://host[:port] in lower case, \
             such as https://viewer.example.org",
            s.escape_debug()
        ))
    }
}

/// `host[:port]` as an origin has it: a lower-case name, an IPv4 address or a bracketed IPv6
/// one, and a port that is a port.
fn host_and_port(s: &str) -> bool {
    let (host, port) = match s.rsplit_once(':') {
        Some((h, p)) if !s.ends_with(']') => (h, Some(p)),
        _ => (s, None),
    };
    let name_ok = match host.strip_prefix('[').and_then(|h| h.strip_suffix(']')) {
        Some(v6) => {
            v6.contains(':')
                && v6
                    .chars()
                    .all(|c| c.is_ascii_digit() || ('a'..='f').contains(&c) || c == ':')
        }
        // `_` too: browsers send it (container service names such as viewer_app).
        None => {
            !host.is_empty()
                && host
                    .chars()
                    .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || "-._".contains(c))
        }
    };
    // Digits as a browser writes them: no sign, no leading zero, 1 to 65535.
    let port_ok = |p: &str| {
        !p.starts_with('0')
            && p.bytes().all(|b| b.is_ascii_digit())
            && p.parse::<u16>().is_ok_and(|n| n > 0)
    };
    name_ok && port.is_none_or(port_ok)
}

pub fn run_serve(a: Args) -> anyhow::Result<ExitCode> {
    let mut config = ServerConfig::new(&a.dir)?;
    config.token = super::token::token(a.token.as_deref(), a.token_file.as_deref())?;
    config.cors = a.cors;
    config.max_connections = a.max_connections.max(1);
    config.request_timeout = Duration::from_secs(a.request_timeout.max(1));
    config.idle_timeout = Duration::from_secs(a.idle_timeout.max(1));
    config.header_timeout = Duration::from_secs(a.header_timeout.max(1));
    config.access_log = !a.quiet;
    config.log_format = match a.log_format {
        LogFormatArg::Text => LogFormat::Text,
        LogFormatArg::Json => LogFormat::Json,
    };
    config.blocking_threads = a.blocking_threads;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        // File-system calls go to the server's own pool; tokio's serves nothing of ours.
        .max_blocking_threads(4)
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

#[cfg(test)]
mod tests {
    use super::parse_origin;

    #[test]
    fn origins_are_what_a_browser_sends() {
        for good in [
            "*",
            "null",
            "https://viewer.example.org",
            "http://localhost:8080",
            "https://[::1]:3000",
            "https://[::1]",
            "http://127.0.0.1:8080",
            "http://viewer_app:8080",
            "app+x://a-b.c",
        ] {
            assert_eq!(parse_origin(good).as_deref(), Ok(good));
        }
        for bad in [
            "",
            "viewer",
            "https://",
            "://a.org",
            "https://a.org/viewer",
            "https://a.org\r\nX-Evil: 1",
            "HTTPS://A.ORG",
            "https://user@a.org",
            "https://a.org?x",
            "https://a.org#x",
            "https://a .org",
            "https://a.org:99999",
            "https://a.org:",
            "https://a.org:+80",
            "https://a.org:0080",
            "https://a.org:0",
            "https://[::ABCD]",
            "x://\"<>",
        ] {
            let e = parse_origin(bad).expect_err(bad);
            assert!(e.contains("is not an origin"), "{bad}: {e}");
        }
    }
}
