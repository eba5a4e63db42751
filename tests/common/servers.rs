//! Servers the tests start: `strata serve` on a free port, and nginx as a plain static server.
//! Each is stopped when dropped, even when an assertion fails.

use super::s;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

pub struct Server {
    pub child: Child,
    pub addr: String,
    pub log: Option<BufReader<std::process::ChildStderr>>,
}

impl Server {
    /// `strata serve DIR` on a free port, with `extra` options.
    pub fn start_in(dir: &Path, extra: &[&str]) -> Server {
        let mut child = super::strata()
            .args(["serve", s(dir), "--bind", "127.0.0.1:0"])
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("server starts");
        let mut first = String::new();
        BufReader::new(child.stdout.take().expect("stdout"))
            .read_line(&mut first)
            .expect("banner");
        let addr = first
            .split("http://")
            .nth(1)
            .and_then(|r| r.split('/').next())
            .unwrap_or_else(|| panic!("no address in {first:?}"))
            .to_string();
        let log = Some(BufReader::new(child.stderr.take().expect("stderr")));
        Server { child, addr, log }
    }

    pub fn url(&self, dataset: &str) -> String {
        format!("http://{}/{dataset}", self.addr)
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

pub struct KillOnDrop(pub Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// nginx serving `root` on a free port, its configuration and logs under `prefix`; `None`
/// (after saying so) where nginx is not installed, a failure where STRATA_REQUIRE_NGINX is set.
pub fn nginx(root: &Path, prefix: &Path) -> Option<(KillOnDrop, String)> {
    let Some(nginx) = ["/usr/sbin/nginx", "/usr/bin/nginx"]
        .into_iter()
        .find(|p| Path::new(p).exists())
    else {
        assert!(
            std::env::var_os("STRATA_REQUIRE_NGINX").is_none(),
            "nginx is missing but STRATA_REQUIRE_NGINX is set"
        );
        eprintln!("skipping: nginx is not installed");
        return None;
    };
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .expect("port")
        .local_addr()
        .expect("addr")
        .port();
    std::fs::create_dir_all(prefix.join("logs")).expect("nginx dir");
    let conf = prefix.join("nginx.conf");
    std::fs::write(
        &conf,
        format!(
            "master_process off;\nworker_processes 1;\nerror_log {p}/logs/error.log;\npid {p}/nginx.pid;\n\
             events {{ worker_connections 64; }}\n\
             http {{\n  access_log off;\n  client_body_temp_path {p}/tmp;\n  proxy_temp_path {p}/tmp;\n  fastcgi_temp_path {p}/tmp;\n  uwsgi_temp_path {p}/tmp;\n  scgi_temp_path {p}/tmp;\n\
               server {{ listen 127.0.0.1:{port}; root {root}; }}\n}}\n",
            p = prefix.display(),
            root = root.display()
        ),
    )
    .expect("nginx.conf");
    let child = Command::new(nginx)
        .args([
            "-p",
            s(prefix),
            "-c",
            s(&conf),
            "-g",
            "daemon off; user root;",
        ])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("nginx starts");
    // One process (master_process off).
    let guard = KillOnDrop(child);
    let addr = format!("127.0.0.1:{port}");
    let deadline = Instant::now() + Duration::from_secs(10);
    while std::net::TcpStream::connect(&addr).is_err() {
        assert!(Instant::now() < deadline, "nginx did not start");
        std::thread::sleep(Duration::from_millis(50));
    }
    Some((guard, addr))
}
