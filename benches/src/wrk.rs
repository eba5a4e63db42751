//! wrk against a server, and nginx as the server to compare with: random byte ranges of one file
//! (1 B to 64 KiB, a wrk Lua script), requests/s and latency percentiles from wrk's report.

use anyhow::{Context, bail};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Each request asks for a random range of 1 B to 64 KiB lying inside a file of `args[1]`
/// bytes; each wrk thread seeds its own generator.
const RANGES_LUA: &str = r#"
local len = 0
local counter = 0
function setup(thread)
  counter = counter + 1
  thread:set("seed", counter)
end
function init(args)
  len = tonumber(args[1])
  math.randomseed(os.time() * 1000 + (seed or 0))
end
function request()
  local size = math.random(1, math.min(65536, len))
  local start = math.random(0, len - size)
  return wrk.format(nil, nil, { ["Range"] = "bytes=" .. start .. "-" .. (start + size - 1) })
end
"#;

#[derive(Debug, Clone, Copy)]
pub struct WrkResult {
    pub requests_per_s: f64,
    pub p50_ms: f64,
    pub p99_ms: f64,
    /// Socket errors plus answers other than 2xx/3xx.
    pub errors: u64,
}

fn ms(value: &str) -> Option<f64> {
    let (num, factor) = if let Some(v) = value.strip_suffix("us") {
        (v, 1e-3)
    } else if let Some(v) = value.strip_suffix("ms") {
        (v, 1.0)
    } else if let Some(v) = value.strip_suffix('s') {
        (v, 1e3)
    } else {
        (value, 1.0)
    };
    num.parse::<f64>().ok().map(|n| n * factor)
}

fn parse_report(out: &str) -> anyhow::Result<WrkResult> {
    let field = |prefix: &str| {
        out.lines()
            .map(str::trim)
            .find(|l| l.starts_with(prefix))
            .map(|l| l[prefix.len()..].trim().to_string())
    };
    let requests_per_s = field("Requests/sec:")
        .and_then(|v| v.parse().ok())
        .context("no Requests/sec in wrk's report")?;
    let p50_ms = field("50%").and_then(|v| ms(&v)).context("no p50")?;
    let p99_ms = field("99%").and_then(|v| ms(&v)).context("no p99")?;
    let mut errors = field("Non-2xx or 3xx responses:")
        .and_then(|v| v.parse().ok())
        .unwrap_or(0u64);
    if let Some(socket) = field("Socket errors:") {
        // "connect 0, read 0, write 0, timeout 0"
        errors += socket
            .split(',')
            .filter_map(|p| p.split_whitespace().nth(1)?.parse::<u64>().ok())
            .sum::<u64>();
    }
    Ok(WrkResult {
        requests_per_s,
        p50_ms,
        p99_ms,
        errors,
    })
}

/// Runs wrk with `connections` on `url` (a file of `len` bytes) for `seconds`.
pub fn run_wrk(
    url: &str,
    len: u64,
    connections: usize,
    threads: usize,
    seconds: u64,
    work: &Path,
) -> anyhow::Result<WrkResult> {
    let script = work.join("ranges.lua");
    std::fs::write(&script, RANGES_LUA)?;
    let out = Command::new("wrk")
        .args(["-t", &threads.to_string(), "-c", &connections.to_string()])
        .args(["-d", &format!("{seconds}s"), "--latency", "-s"])
        .arg(&script)
        .args([url, "--", &len.to_string()])
        .output()
        .context("cannot run wrk (Debian package `wrk`)")?;
    let text = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        bail!("wrk failed: {}", String::from_utf8_lossy(&out.stderr));
    }
    parse_report(&text)
}

/// nginx serving `root` on a free loopback port, stopped on drop.
pub struct Nginx {
    child: Child,
    pub addr: String,
}

impl Drop for Nginx {
    fn drop(&mut self) {
        // SIGTERM: the master stops its workers; SIGKILL would leave them running.
        let stopped = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .is_ok_and(|s| s.success());
        if !stopped {
            let _ = self.child.kill();
        }
        let _ = self.child.wait();
    }
}

fn free_port() -> anyhow::Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

/// Starts nginx as a static server of `root` the way one would deploy it: one worker process
/// per core, sendfile, no access log (strata runs with `--quiet` in the same comparison).
pub fn start_nginx(root: &Path, work: &Path) -> anyhow::Result<Nginx> {
    // nginx reads a relative root against its prefix, not our working directory.
    let root = std::fs::canonicalize(root)
        .with_context(|| format!("{}: cannot serve this folder", root.display()))?;
    let nginx = ["/usr/sbin/nginx", "/usr/bin/nginx"]
        .into_iter()
        .map(PathBuf::from)
        .find(|p| p.exists())
        .context("nginx is not installed (Debian package `nginx`)")?;
    let prefix = work.join("nginx");
    std::fs::create_dir_all(prefix.join("logs"))?;
    let port = free_port()?;
    let conf = prefix.join("nginx.conf");
    let p = prefix.display();
    std::fs::write(
        &conf,
        format!(
            "worker_processes auto;\nerror_log {p}/logs/error.log;\npid {p}/nginx.pid;\n\
             events {{ worker_connections 4096; }}\n\
             http {{\n  access_log off;\n  sendfile on;\n  tcp_nopush on;\n  keepalive_requests 100000;\n\
               client_body_temp_path {p}/tmp;\n  proxy_temp_path {p}/tmp;\n  fastcgi_temp_path {p}/tmp;\n\
               uwsgi_temp_path {p}/tmp;\n  scgi_temp_path {p}/tmp;\n\
               server {{ listen 127.0.0.1:{port}; root {root}; }}\n}}\n",
            root = root.display()
        ),
    )?;
    let child = Command::new(&nginx)
        .args([
            "-p".as_ref(),
            prefix.as_os_str(),
            "-c".as_ref(),
            conf.as_os_str(),
        ])
        .args(["-g", "daemon off; user root;"])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .context("cannot start nginx")?;
    let server = Nginx {
        child,
        addr: format!("127.0.0.1:{port}"),
    };
    let deadline = Instant::now() + Duration::from_secs(10);
    while std::net::TcpStream::connect(&server.addr).is_err() {
        if Instant::now() > deadline {
            bail!("nginx did not start; see {p}/logs/error.log");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    Ok(server)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_wrks_report() {
        let report = "Running 10s test @ http://127.0.0.1:1/a\n  2 threads and 64 connections\n\
          Latency Distribution\n     50%  820.00us\n     75%    1.10ms\n     90%    1.50ms\n     99%    3.25ms\n\
          123456 requests in 10.00s, 3.9GB read\n  Socket errors: connect 0, read 2, write 0, timeout 1\n\
          Non-2xx or 3xx responses: 4\nRequests/sec:  12345.60\nTransfer/sec:    390.1MB\n";
        let r = parse_report(report).expect("parses");
        assert_eq!(r.requests_per_s, 12345.6);
        assert!((r.p50_ms - 0.82).abs() < 1e-9);
        assert_eq!(r.p99_ms, 3.25);
        assert_eq!(r.errors, 7);
    }
}
