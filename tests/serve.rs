//! `strata serve` and remote datasets: bytes served equal bytes on disk, refusals, validators,
//! renders over HTTP (from strata serve and from nginx) equal renders from disk, a server killed
//! mid-stream, timeouts and graceful shutdown; the attacks of issue 23 (serve/attacks.rs), HTTP/2
//! (serve/h2c.rs), a 20 s soak at 256 connections (serve/soak.rs), and format versions and mixed
//! files over HTTP (serve/versions.rs).

#[path = "serve/attacks.rs"]
mod attacks;
mod common;
#[path = "serve/h2c.rs"]
mod h2c;
#[path = "common/http.rs"]
mod http;
#[path = "serve/soak.rs"]
mod soak;
#[path = "serve/versions.rs"]
mod versions;

use common::{data, s};
use std::io::{BufRead, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

fn fixtures() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("serve-fixtures");
        let _ = std::fs::remove_dir_all(&dir);
        let root = dir.join("root");
        std::fs::create_dir_all(&root).expect("fixture dir");
        common::run_ok(&[
            "convert",
            s(&data("autzen_trim.laz")),
            "-o",
            s(&root.join("autzen.strata")),
            "--quiet",
        ]);
        let las = dir.join("city.las");
        common::run_ok(&["synth", "--points", "400k", "-o", s(&las), "--seed", "5"]);
        common::run_ok(&[
            "convert",
            s(&las),
            "-o",
            s(&root.join("city.strata")),
            "--quiet",
        ]);
        std::fs::write(dir.join("secret.txt"), "TOP-SECRET-CONTENT").expect("secret");
        std::os::unix::fs::symlink(&dir, root.join("escape")).expect("symlink");
        dir
    })
}

fn root() -> PathBuf {
    fixtures().join("root")
}

use common::servers::{KillOnDrop, Server};

fn gpu(args: &[&str]) -> std::process::Output {
    let backend = std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "vulkan".into());
    common::strata()
        .env("WGPU_BACKEND", backend)
        .args(args)
        .output()
        .expect("strata runs")
}

fn pixels(path: &Path) -> Vec<u8> {
    let dec = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(path).expect("png"),
    ));
    let mut r = dec.read_info().expect("png header");
    let mut buf = vec![0; r.output_buffer_size().expect("size")];
    let info = r.next_frame(&mut buf).expect("png data");
    buf.truncate(info.buffer_size());
    buf
}

#[test]
fn random_ranges_equal_the_bytes_on_disk() {
    let server = Server::start_in(&root(), &["--quiet"]);
    let file = root().join("city.strata/octree.bin");
    let disk = std::fs::read(&file).expect("read");
    let len = disk.len() as u64;
    let mut seed = 0x9e3779b97f4a7c15u64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    for _ in 0..40 {
        let a = next() % len;
        let b = (a + next() % 200_000).min(len - 1);
        let r = http::request(
            &server.addr,
            "GET",
            "/city.strata/octree.bin",
            &[("Range", &format!("bytes={a}-{b}"))],
        );
        assert_eq!(r.status, 206);
        assert_eq!(
            r.header("Content-Range"),
            Some(format!("bytes {a}-{b}/{len}").as_str())
        );
        assert_eq!(
            r.body,
            disk[a as usize..=b as usize],
            "bytes {a}-{b} differ"
        );
    }
    let suffix = http::request(
        &server.addr,
        "GET",
        "/city.strata/octree.bin",
        &[("Range", "bytes=-100")],
    );
    assert_eq!(suffix.body, disk[disk.len() - 100..]);
    let whole = http::request(&server.addr, "GET", "/city.strata/octree.bin", &[]);
    assert_eq!(whole.status, 200);
    assert_eq!(whole.body, disk);
    assert_eq!(whole.header("Accept-Ranges"), Some("bytes"));
}

#[test]
fn head_validators_multirange_and_listing() {
    let server = Server::start_in(&root(), &["--quiet", "--cors", "*"]);
    // A file's date is a validator only once its second is past (the fixture may be new).
    let written = std::fs::metadata(root().join("autzen.strata/metadata.json"))
        .and_then(|m| m.modified())
        .expect("modified");
    let whole_seconds = |t: std::time::SystemTime| {
        t.duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs())
    };
    while whole_seconds(std::time::SystemTime::now()) <= whole_seconds(written) {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let head = http::request(&server.addr, "HEAD", "/autzen.strata/metadata.json", &[]);
    let meta_len = std::fs::metadata(root().join("autzen.strata/metadata.json"))
        .expect("meta")
        .len();
    assert_eq!(head.status, 200);
    assert!(head.body.is_empty());
    assert_eq!(
        head.header("Content-Length"),
        Some(meta_len.to_string().as_str())
    );
    assert!(head.header("Last-Modified").is_some());
    assert!(head.header("Cache-Control").is_some());
    assert_eq!(head.header("Access-Control-Allow-Origin"), Some("*"));
    let etag = head.header("ETag").expect("etag").to_string();
    let meta_path = "/autzen.strata/metadata.json";
    let status_with = |h: &[(&str, &str)]| http::request(&server.addr, "GET", meta_path, h).status;
    assert_eq!(status_with(&[("If-None-Match", &etag)]), 304);
    // Weak comparison (RFC 9110, 13.1.2).
    assert_eq!(status_with(&[("If-None-Match", &format!("W/{etag}"))]), 304);
    // If-Match and If-Unmodified-Since (RFC 9110, 13.1.1 and 13.1.4): a resuming client never
    // splices two versions of a file.
    assert_eq!(status_with(&[("If-Match", "\"other\"")]), 412);
    assert_eq!(status_with(&[("If-Match", &etag)]), 200);
    let epoch = "Thu, 01 Jan 1970 00:00:00 GMT";
    assert_eq!(status_with(&[("If-Unmodified-Since", epoch)]), 412);
    // If-Range by date: the Last-Modified the client saw keeps its range.
    let modified = head
        .header("Last-Modified")
        .expect("last modified")
        .to_string();
    // If-Modified-Since (RFC 9110, 13.1.3), which If-None-Match overrides; it was ignored.
    assert_eq!(status_with(&[("If-Modified-Since", &modified)]), 304);
    assert_eq!(status_with(&[("If-Modified-Since", epoch)]), 200);
    let with_both = [
        ("If-None-Match", "\"other\""),
        ("If-Modified-Since", &modified),
    ];
    assert_eq!(status_with(&with_both), 200);
    // If-None-Match and If-Match are lists: their lines are one list (only the first line
    // was read).
    let lines = [("If-None-Match", "\"other\""), ("If-None-Match", &etag)];
    assert_eq!(status_with(&lines), 304);
    let lines = [("If-Match", "\"other\""), ("If-Match", &etag)];
    assert_eq!(status_with(&lines), 200);
    assert_eq!(
        status_with(&[("Range", "bytes=0-9"), ("If-Range", &modified)]),
        206
    );
    assert_eq!(
        status_with(&[("Range", "bytes=0-9"), ("If-Range", epoch)]),
        200
    );
    // If-Range given twice is no validator: the whole file (it was taken as absent, and the
    // range applied to whatever the file had become).
    let twice = [
        ("Range", "bytes=0-9"),
        ("If-Range", modified.as_str()),
        ("If-Range", modified.as_str()),
    ];
    assert_eq!(status_with(&twice), 200);
    // Range is for GET: HEAD answers for the whole file.
    let head_range = http::request(
        &server.addr,
        "HEAD",
        "/autzen.strata/metadata.json",
        &[("Range", "bytes=0-9")],
    );
    assert_eq!(head_range.status, 200);
    assert_eq!(
        head_range.header("Content-Length"),
        Some(meta_len.to_string().as_str())
    );
    let upper = http::request(
        &server.addr,
        "GET",
        "/autzen.strata/metadata.json",
        &[("Range", "Bytes=0-9")],
    );
    assert_eq!((upper.status, upper.body.len()), (206, 10));
    let multi = http::request(
        &server.addr,
        "GET",
        "/autzen.strata/octree.bin",
        &[("Range", "bytes=0-1,5-9")],
    );
    // Several ranges: the whole file (no multipart answers), not 416.
    let octree_len = std::fs::metadata(root().join("autzen.strata/octree.bin"))
        .expect("octree")
        .len() as usize;
    assert_eq!((multi.status, multi.body.len()), (200, octree_len));
    let past = http::request(
        &server.addr,
        "GET",
        "/autzen.strata/metadata.json",
        &[("Range", &format!("bytes={meta_len}-"))],
    );
    assert_eq!(past.status, 416);
    assert_eq!(
        past.header("Content-Range"),
        Some(format!("bytes */{meta_len}").as_str())
    );
    let post = http::request(&server.addr, "POST", "/autzen.strata/metadata.json", &[]);
    assert_eq!(post.status, 405);
    let list = http::request(&server.addr, "GET", "/", &[]);
    let v: serde_json::Value = serde_json::from_slice(&list.body).expect("listing JSON");
    let names: Vec<&str> = v
        .as_array()
        .expect("array")
        .iter()
        .filter_map(|d| d["name"].as_str())
        .collect();
    assert_eq!(names, ["autzen.strata", "city.strata"]);
    assert_eq!(v[0]["points"], 110_000);
    let meta: serde_json::Value = serde_json::from_slice(
        &std::fs::read(root().join("autzen.strata/metadata.json")).expect("metadata"),
    )
    .expect("json");
    assert_eq!(v[0]["version"], "1.1");
    assert_eq!(v[0]["id"], meta["id"]);
}

#[test]
fn traversal_and_missing_tokens_are_refused() {
    let server = Server::start_in(&root(), &["--quiet", "--token", "s3cret"]);
    let auth = [("Authorization", "Bearer s3cret")];
    let ok = http::request(&server.addr, "GET", "/autzen.strata/metadata.json", &auth);
    assert_eq!(ok.status, 200);
    // Behind a token no shared cache may keep an answer (RFC 9111, 3.5).
    assert_eq!(ok.header("Cache-Control"), Some("private, max-age=60"));
    // Without CORS, OPTIONS is not allowed, and Allow says so.
    let options = http::request(
        &server.addr,
        "OPTIONS",
        "/autzen.strata/metadata.json",
        &auth,
    );
    assert_eq!(
        (options.status, options.header("Allow")),
        (405, Some("GET, HEAD"))
    );
    for (path, headers) in [
        ("/autzen.strata/metadata.json", &[][..]),
        (
            "/autzen.strata/metadata.json",
            &[("Authorization", "Bearer wrong")][..],
        ),
        ("/", &[("Authorization", "Basic czNjcmV0")][..]),
    ] {
        let r = http::request(&server.addr, "GET", path, headers);
        assert_eq!(r.status, 401, "{path} {headers:?}");
        assert!(r.header("WWW-Authenticate").is_some());
    }
    for path in [
        "/../secret.txt",
        "/autzen.strata/../../secret.txt",
        "/%2e%2e/secret.txt",
        "/%2E%2E%2Fsecret.txt",
        "/autzen.strata%2f..%2f..%2fsecret.txt",
        "//etc/passwd",
        "/escape/secret.txt",
        "/.hidden",
    ] {
        let r = http::request(&server.addr, "GET", path, &auth);
        assert!(
            (400..500).contains(&r.status),
            "{path} answered {}",
            r.status
        );
        assert!(
            !String::from_utf8_lossy(&r.body).contains("TOP-SECRET"),
            "{path} leaked"
        );
    }
}

fn render_pair(url: &str, local: &Path, tag: &str, extra: &[&str]) {
    let dir = fixtures();
    let (a, b) = (
        dir.join(format!("{tag}-http.png")),
        dir.join(format!("{tag}-disk.png")),
    );
    for (src, out) in [(url.to_string(), &a), (local.display().to_string(), &b)] {
        let mut args = vec![
            "render",
            &src,
            "-o",
            s(out),
            "--size",
            "320x240",
            "--wait-complete",
        ];
        args.extend_from_slice(extra);
        let o = gpu(&args);
        assert!(
            o.status.success(),
            "render {src}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    // Two processes place nodes in GPU memory in arrival order, and an exact depth tie between
    // two points resolves by placement: those pixels (a handful at most) may differ. Coverage
    // must match exactly.
    let (pa, pb) = (pixels(&a), pixels(&b));
    assert_eq!(pa.len(), pb.len());
    let background = |p: &[u8]| p[..3] == [24, 26, 32];
    let coverage = |v: &[u8]| v.chunks_exact(4).filter(|p| !background(p)).count();
    assert_eq!(
        coverage(&pa),
        coverage(&pb),
        "{tag}: HTTP and disk cover different pixels"
    );
    let differing = pa
        .chunks_exact(4)
        .zip(pb.chunks_exact(4))
        .filter(|(x, y)| x != y)
        .count();
    assert!(
        differing * 2000 <= coverage(&pa),
        "{tag}: {differing} pixels differ between the render over HTTP and from disk"
    );
}

#[test]
fn render_over_http_equals_render_from_disk() {
    let server = Server::start_in(&root(), &["--quiet", "--token", "t0k"]);
    render_pair(
        &server.url("city.strata"),
        &root().join("city.strata"),
        "serve",
        &["--token", "t0k"],
    );
    let o = gpu(&[
        "render",
        &server.url("city.strata"),
        "-o",
        s(&fixtures().join("no-token.png")),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("401"));
    // The token from a file (kept out of `ps`), its newline dropped, as `serve` reads one;
    // an empty one is refused before any request, not sent as "Bearer ".
    let file = fixtures().join("client-token.txt");
    std::fs::write(&file, "t0k\n").expect("token file");
    let image = fixtures().join("token-file.png");
    let url = server.url("city.strata");
    let o = gpu(&["render", &url, "-o", s(&image), "--token-file", s(&file)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = gpu(&["render", &url, "-o", s(&image), "--token", ""]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("--token is empty"),
        "{err}"
    );
}

#[test]
fn render_from_nginx_equals_render_from_disk() {
    let Some((_nginx, addr)) = common::servers::nginx(&root(), &fixtures().join("nginx")) else {
        return;
    };
    render_pair(
        &format!("http://{addr}/autzen.strata"),
        &root().join("autzen.strata"),
        "nginx",
        &[],
    );
}

/// Starts a `--wait-complete` render of the city through `server` with `timeout` seconds of
/// patience, and kills the server once it has served 4 nodes. Returns the running render.
fn render_then_kill_server(server: &mut Server, tag: &str, timeout: &str) -> Child {
    let out = fixtures().join(format!("{tag}.png"));
    let stats = fixtures().join(format!("{tag}.json"));
    let backend = std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "vulkan".into());
    let url = server.url("city.strata");
    let render = common::strata()
        .env("WGPU_BACKEND", backend)
        .args(["render", &url, "-o", s(&out), "--stats", s(&stats)])
        .args(["--size", "1280x720", "--budget", "10M", "--wait-complete"])
        .args(["--timeout", timeout])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("render starts");
    let mut served = 0;
    let mut line = String::new();
    let log = server.log.as_mut().expect("the server's stderr");
    while served < 4 {
        line.clear();
        if log.read_line(&mut line).expect("log") == 0 {
            break;
        }
        served += line.contains("octree.bin") as u32;
    }
    server.child.kill().expect("kill server");
    let _ = server.child.wait();
    render
}

fn frame_stats(tag: &str) -> serde_json::Value {
    let path = fixtures().join(format!("{tag}.json"));
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&path).expect("stats")).expect("json");
    v["frames"][0].clone()
}

#[test]
fn a_server_killed_mid_stream_leaves_a_render_of_what_arrived() {
    let mut server = Server::start_in(&root(), &[]);
    let render = render_then_kill_server(&mut server, "killed", "3");
    let o = render.wait_with_output().expect("render ends");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "render failed: {err}");
    assert!(!err.contains("panicked"));
    let f = frame_stats("killed");
    assert_eq!(
        f["complete"], false,
        "the render completed before the server died"
    );
    assert!(f["nodes_missing"].as_u64().unwrap_or(0) > 0);
    assert!(
        f["points_drawn"].as_u64().unwrap_or(0) > 0,
        "nothing drawn of what arrived"
    );
    assert!(err.contains("missing"), "no report of missing nodes: {err}");
    assert!(fixtures().join("killed.png").exists());
}

#[test]
fn slow_clients_are_cut_off_and_sigterm_stops_gracefully() {
    let mut server = Server::start_in(
        &root(),
        &["--quiet", "--header-timeout", "1", "--idle-timeout", "2"],
    );
    let mut slow = std::net::TcpStream::connect(&server.addr).expect("connect");
    slow.write_all(b"GET / HTTP/1.1\r\nHost: x\r\n")
        .expect("partial request");
    slow.set_read_timeout(Some(Duration::from_secs(8)))
        .expect("timeout");
    let start = Instant::now();
    let mut buf = [0u8; 256];
    let n = slow.read(&mut buf).unwrap_or(0);
    assert!(
        start.elapsed() < Duration::from_secs(6),
        "a slow client held its connection"
    );
    assert!(n == 0 || String::from_utf8_lossy(&buf[..n]).contains("408"));
    // Before HTTP/1 and HTTP/2 are told apart: silence, or HTTP/2's preface a byte at a time,
    // has the header timeout too (they held the connection for the idle limit, and again with
    // each byte).
    for dripped in [&b""[..], b"PRI * HTTP/2.0"] {
        let mut quiet = std::net::TcpStream::connect(&server.addr).expect("connect");
        quiet
            .set_read_timeout(Some(Duration::from_secs(8)))
            .expect("timeout");
        let start = Instant::now();
        let mut closed = false;
        for b in dripped {
            if quiet.write_all(&[*b]).is_err() {
                closed = true;
                break;
            }
            std::thread::sleep(Duration::from_millis(300));
        }
        if !closed {
            let _ = quiet.read(&mut buf);
        }
        assert!(
            start.elapsed() < Duration::from_secs(6),
            "a connection sending {dripped:?} was held {:?}",
            start.elapsed()
        );
    }

    let status = Command::new("kill")
        .args(["-TERM", &server.child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(status.success());
    let exit = server.child.wait().expect("server exits");
    assert!(exit.success(), "server exited with {exit:?} on SIGTERM");
}

#[test]
fn a_render_picks_up_again_when_the_server_returns() {
    let mut server = Server::start_in(&root(), &[]);
    let addr = server.addr.clone();
    let render = render_then_kill_server(&mut server, "returned", "30");
    std::thread::sleep(Duration::from_millis(1500));
    // The same address again: the client's retries find it.
    let back = common::strata()
        .args(["serve", s(&root()), "--bind", &addr, "--quiet"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("server restarts");
    let _back = KillOnDrop(back);
    let o = render.wait_with_output().expect("render ends");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let f = frame_stats("returned");
    assert_eq!(f["complete"], true, "the render did not pick up: {f}");
    assert!(
        f["fetch_errors"].as_u64().unwrap_or(0) > 0,
        "the server was never missed: {f}"
    );
}

/// A `--cors` value no browser could match is refused at the start with what an origin looks
/// like, not dropped from every response unsaid. (The address cannot be bound either, so a
/// value wrongly taken fails here rather than serving forever.)
#[test]
fn a_malformed_cors_origin_is_refused_at_start() {
    let dir = tempfile::tempdir().expect("tempdir");
    let o = common::run(&[
        "serve",
        s(dir.path()),
        "--bind",
        "256.0.0.1:0",
        "--cors",
        "https://a.org\r\nX-Evil: 1",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("is not an origin"), "{err}");
}
