//! The attacks of issue 23, each as a test: an empty token, FIFOs where dataset files belong, a
//! symlink out of the directory in the listing, stray files, a lower-case scheme, requests
//! without `Host` or with two, parser rejections missing from the log.

use super::{Server, root};
use crate::common::{self, s};
use crate::http;
use std::io::BufRead;
use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

/// A fresh folder under the target's temporary directory.
pub fn scratch(tag: &str) -> tempfile::TempDir {
    let base = Path::new(env!("CARGO_TARGET_TMPDIR")).join("serve-attacks");
    std::fs::create_dir_all(&base).expect("scratch base");
    tempfile::Builder::new()
        .prefix(tag)
        .tempdir_in(base)
        .expect("scratch dir")
}

/// Copies `files` of the autzen fixture into `dir`.
fn copy_autzen(dir: &Path, files: &[&str]) {
    std::fs::create_dir_all(dir).expect("dataset dir");
    for f in files {
        std::fs::copy(root().join("autzen.strata").join(f), dir.join(f)).expect("copy");
    }
}

const ALL: [&str; 3] = ["metadata.json", "hierarchy.bin", "octree.bin"];

/// Threads, open descriptors and resident KiB of process `pid`.
pub fn process_counts(pid: u32) -> (u64, usize, u64) {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("status");
    let field = |key: &str| {
        status
            .lines()
            .find(|l| l.starts_with(key))
            .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
            .expect("field")
    };
    let fds = std::fs::read_dir(format!("/proc/{pid}/fd"))
        .expect("fd dir")
        .count();
    (field("Threads:"), fds, field("VmRSS:"))
}

/// GET `path` with a 5 s limit on every wait: a hung server fails the test, it never hangs it.
fn get(addr: &str, path: &str, headers: &[(&str, &str)]) -> std::io::Result<http::Reply> {
    let mut req = format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    for (k, v) in headers {
        req.push_str(&format!("{k}: {v}\r\n"));
    }
    req.push_str("\r\n");
    http::exchange(addr, req.as_bytes(), Duration::from_secs(5))
}

fn listed(reply: &http::Reply) -> Vec<String> {
    let v: serde_json::Value = serde_json::from_slice(&reply.body).expect("listing JSON");
    v.as_array()
        .expect("array")
        .iter()
        .filter_map(|d| d["name"].as_str().map(str::to_string))
        .collect()
}

/// Starts `strata serve` with `args` and waits up to 10 s for it to exit: (code, stderr).
fn start_expecting_exit(args: &[&str]) -> (Option<i32>, String) {
    let mut child = common::strata()
        .args(["serve", s(&root()), "--bind", "127.0.0.1:0"])
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("strata starts");
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            let out = child.wait_with_output().expect("output");
            return (
                status.code(),
                String::from_utf8_lossy(&out.stderr).to_string(),
            );
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("strata serve {args:?} kept serving");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn an_empty_or_blank_token_is_refused_at_start_up() {
    let dir = scratch("token");
    let (empty, blank) = (dir.path().join("empty"), dir.path().join("blank"));
    std::fs::write(&empty, "").expect("write");
    std::fs::write(&blank, " \n\t\n").expect("write");
    for args in [
        vec!["--token", ""],
        vec!["--token", "   "],
        vec!["--token-file", s(&empty)],
        vec!["--token-file", s(&blank)],
    ] {
        let (code, err) = start_expecting_exit(&args);
        assert_eq!(code, Some(1), "{args:?}: {err}");
        assert!(err.contains("empty or blank"), "{args:?}: {err}");
        assert_eq!(
            err.trim().lines().count(),
            1,
            "{args:?}: not one sentence: {err}"
        );
    }
    let (code, err) = start_expecting_exit(&["--token-file", s(&dir.path().join("missing"))]);
    assert_eq!(code, Some(1));
    assert!(
        err.contains("missing") && err.contains("token file"),
        "{err}"
    );
}

#[test]
fn a_token_file_guards_like_a_token() {
    let dir = scratch("token-file");
    let file = dir.path().join("token");
    std::fs::write(&file, "s3cret\n").expect("write");
    let server = Server::start_in(&super::root(), &["--quiet", "--token-file", s(&file)]);
    let path = "/autzen.strata/metadata.json";
    assert_eq!(get(&server.addr, path, &[]).expect("reply").status, 401);
    for scheme in ["Bearer", "bearer", "BEARER"] {
        let auth = format!("{scheme} s3cret");
        let r = get(&server.addr, path, &[("Authorization", &auth)]).expect("reply");
        assert_eq!(r.status, 200, "{scheme}");
    }
    let wrong = get(&server.addr, path, &[("Authorization", "bearer s3cre")]).expect("reply");
    assert_eq!(wrong.status, 401);
}

#[test]
fn a_fifo_metadata_json_blocks_neither_the_listing_nor_the_server() {
    let dir = scratch("fifo-meta");
    copy_autzen(&dir.path().join("good.strata"), &ALL);
    std::fs::create_dir_all(dir.path().join("trap.strata")).expect("dir");
    common::mkfifo(&dir.path().join("trap.strata/metadata.json"));
    let server = Server::start_in(dir.path(), &["--quiet", "--request-timeout", "2"]);
    let addr = server.addr.clone();
    // More listings at once than the runtime has workers.
    let listings: Vec<_> = (0..6)
        .map(|_| {
            let addr = addr.clone();
            std::thread::spawn(move || get(&addr, "/", &[]))
        })
        .collect();
    for l in listings {
        let r = l.join().expect("thread").expect("the listing answered");
        assert_eq!(r.status, 200);
        assert_eq!(listed(&r), ["good.strata"]);
    }
    let fifo = get(&addr, "/trap.strata/metadata.json", &[]).expect("answered");
    let missing = get(&addr, "/nothing.strata/metadata.json", &[]).expect("answered");
    assert_eq!((fifo.status, &fifo.body), (404, &missing.body));
    let good = get(&addr, "/good.strata/metadata.json", &[]).expect("answered");
    assert_eq!(good.status, 200);
}

#[test]
fn a_fifo_octree_bin_answers_404_and_leaves_no_thread_behind() {
    let dir = scratch("fifo-octree");
    let ds = dir.path().join("trap.strata");
    copy_autzen(&ds, &["metadata.json", "hierarchy.bin"]);
    common::mkfifo(&ds.join("octree.bin"));
    let server = Server::start_in(
        dir.path(),
        &[
            "--quiet",
            "--request-timeout",
            "1",
            "--blocking-threads",
            "4",
        ],
    );
    let addr = server.addr.clone();
    assert_eq!(
        get(&addr, "/trap.strata/hierarchy.bin", &[])
            .expect("reply")
            .status,
        200
    );
    let (threads_before, fds_before, _) = process_counts(server.child.id());
    for _ in 0..100 {
        let r = get(&addr, "/trap.strata/octree.bin", &[]).expect("answered");
        assert_eq!(r.status, 404);
    }
    // A burst wider than the pool: the pool's bound holds.
    let burst: Vec<_> = (0..32)
        .map(|_| {
            let addr = addr.clone();
            std::thread::spawn(move || get(&addr, "/trap.strata/octree.bin", &[]))
        })
        .collect();
    for b in burst {
        assert_eq!(b.join().expect("thread").expect("answered").status, 404);
    }
    assert_eq!(
        get(&addr, "/trap.strata/hierarchy.bin", &[])
            .expect("reply")
            .status,
        200
    );
    std::thread::sleep(Duration::from_millis(300));
    let (threads, fds, _) = process_counts(server.child.id());
    assert!(
        threads <= threads_before + 4,
        "threads grew from {threads_before} to {threads}"
    );
    assert!(
        fds <= fds_before,
        "descriptors grew from {fds_before} to {fds}"
    );
}

#[test]
fn the_listing_and_the_files_stay_inside_the_directory() {
    let dir = scratch("confined");
    let served = dir.path().join("root");
    copy_autzen(&served.join("good.strata"), &ALL);
    copy_autzen(&dir.path().join("outside/elsewhere.strata"), &ALL);
    std::os::unix::fs::symlink(
        dir.path().join("outside/elsewhere.strata"),
        served.join("evil"),
    )
    .expect("symlink");
    std::os::unix::fs::symlink(served.join("good.strata"), served.join("alias.strata"))
        .expect("symlink");
    std::fs::write(served.join("notes.txt"), "stray").expect("write");
    std::fs::write(served.join("good.strata/notes.txt"), "stray").expect("write");
    std::fs::create_dir_all(served.join("good.strata/sub")).expect("dir");
    std::fs::write(served.join("good.strata/sub/x.bin"), "stray").expect("write");
    let server = Server::start_in(&served, &["--quiet"]);
    let addr = &server.addr;
    let list = get(addr, "/", &[]).expect("listing");
    assert_eq!(listed(&list), ["alias.strata", "good.strata"]);
    let missing = get(addr, "/good.strata/missing.bin", &[]).expect("reply");
    assert_eq!(missing.status, 404);
    for path in [
        "/evil/metadata.json",
        "/evil/octree.bin",
        "/notes.txt",
        "/good.strata/notes.txt",
        "/good.strata/sub/x.bin",
        "/good.strata/sub",
        "/good.strata",
        "/escape/secret.txt",
    ] {
        let r = get(addr, path, &[]).expect("reply");
        assert_eq!(
            (r.status, &r.body),
            (404, &missing.body),
            "{path} answers differently from a missing file"
        );
    }
    for path in ["/alias.strata/octree.bin", "/good.strata/hierarchy.bin"] {
        assert_eq!(get(addr, path, &[]).expect("reply").status, 200, "{path}");
    }
}

/// A server that logs, with a thread that forwards its log lines.
fn logging_server(extra: &[&str]) -> (Server, std::sync::mpsc::Receiver<String>) {
    logging_server_in(&super::root(), extra)
}

/// A server of `dir` that logs, with a thread that forwards its log lines.
fn logging_server_in(dir: &Path, extra: &[&str]) -> (Server, std::sync::mpsc::Receiver<String>) {
    let mut server = Server::start_in(dir, extra);
    let mut log = server.log.take().expect("the server's stderr");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        while log.read_line(&mut line).is_ok_and(|n| n > 0) {
            if tx.send(std::mem::take(&mut line)).is_err() {
                break;
            }
        }
    });
    (server, rx)
}

fn next_line_with(rx: &std::sync::mpsc::Receiver<String>, needle: &str) -> Option<String> {
    let deadline = Instant::now() + Duration::from_secs(5);
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        match rx.recv_timeout(left) {
            Ok(line) if line.contains(needle) => return Some(line),
            Ok(_) => {}
            Err(_) => return None,
        }
    }
    None
}

#[test]
fn host_rules_of_rfc_9112_and_every_answer_logged() {
    let (server, log) = logging_server(&[]);
    let addr = &server.addr;
    let send =
        |raw: &str| http::exchange(addr, raw.as_bytes(), Duration::from_secs(5)).expect("answered");
    let path = "/autzen.strata/metadata.json";
    for (raw, want) in [
        (
            format!("GET {path} HTTP/1.1\r\nConnection: close\r\n\r\n"),
            400,
        ),
        (
            format!("GET {path} HTTP/1.1\r\nHost: a\r\nHost: b\r\nConnection: close\r\n\r\n"),
            400,
        ),
        (
            format!("GET {path} HTTP/1.1\r\nHost: a@b\r\nConnection: close\r\n\r\n"),
            400,
        ),
        (
            format!("GET {path} HTTP/1.1\r\nHost: x:8080\r\nConnection: close\r\n\r\n"),
            200,
        ),
        (format!("GET {path} HTTP/1.0\r\n\r\n"), 200),
    ] {
        assert_eq!(send(&raw).status, want, "{raw:?}");
    }
    assert!(
        next_line_with(&log, " 400 ").is_some(),
        "a Host refusal was not logged"
    );
    // Requests hyper's parser rejects before any handler runs: a header line without a colon.
    let r = send("GET / HTTP/1.1\r\nHost: x\r\nno colon here\r\n\r\n");
    assert_eq!(r.status, 400);
    let line = next_line_with(&log, "\"- - -\" 400").expect("the parser's 400 was not logged");
    assert!(line.contains("127.0.0.1"), "no client in {line}");
}

#[test]
fn json_access_log_lines() {
    let (server, log) = logging_server(&["--log-format", "json"]);
    let len = std::fs::metadata(root().join("autzen.strata/metadata.json"))
        .expect("meta")
        .len();
    let r = get(&server.addr, "/autzen.strata/metadata.json", &[]).expect("reply");
    assert_eq!(r.status, 200);
    let line = next_line_with(&log, "metadata.json").expect("logged");
    let v: serde_json::Value = serde_json::from_str(&line).expect("a JSON line");
    assert_eq!(v["status"], 200);
    assert_eq!(v["bytes"], len);
    assert_eq!(v["method"], "GET");
    assert_eq!(v["path"], "/autzen.strata/metadata.json");
    assert!(
        v["client"]
            .as_str()
            .is_some_and(|c| c.starts_with("127.0.0.1:"))
    );
    assert!(v["ms"].as_f64().is_some_and(|ms| ms >= 0.0));
}

#[test]
fn requests_sent_before_the_client_shuts_its_side_are_all_answered() {
    use std::io::{Read, Write};
    let server = Server::start_in(&super::root(), &["--quiet"]);
    let mut stream = std::net::TcpStream::connect(&server.addr).expect("connect");
    stream
        .set_read_timeout(Some(Duration::from_secs(10)))
        .expect("timeout");
    let mut requests = String::new();
    for k in 0..5 {
        requests.push_str(&format!(
            "GET /autzen.strata/octree.bin HTTP/1.1\r\nHost: {}\r\nRange: bytes={}-{}\r\n\r\n",
            server.addr,
            k * 100,
            k * 100 + 9
        ));
    }
    stream.write_all(requests.as_bytes()).expect("send");
    // As `nc -N` does once its input ends: no more requests, the answers still awaited.
    stream
        .shutdown(std::net::Shutdown::Write)
        .expect("half-close");
    let mut raw = Vec::new();
    stream.read_to_end(&mut raw).expect("the answers");
    let answered = raw.windows(12).filter(|w| w == b"HTTP/1.1 206").count();
    assert_eq!(answered, 5, "{}", String::from_utf8_lossy(&raw));
}

#[test]
fn a_dataset_whose_metadata_is_not_json_is_reported_once_and_not_served() {
    let dir = scratch("garbage");
    copy_autzen(&dir.path().join("good.strata"), &ALL);
    copy_autzen(&dir.path().join("bad.strata"), &ALL);
    std::fs::write(dir.path().join("bad.strata/metadata.json"), "{ not json").expect("write");
    let (server, log) = logging_server_in(dir.path(), &["--quiet"]);
    for _ in 0..3 {
        let reply = get(&server.addr, "/bad.strata/metadata.json", &[]).expect("reply");
        assert_eq!(reply.status, 404);
    }
    let listing = get(&server.addr, "/", &[]).expect("listing");
    assert_eq!(listed(&listing), vec!["good.strata".to_string()]);
    let line = next_line_with(&log, "bad.strata").expect("the fault reported");
    assert!(
        line.contains("metadata.json: not valid JSON") && line.contains("is not served"),
        "{line}"
    );
    assert!(
        next_line_with(&log, "bad.strata").is_none(),
        "reported more than once"
    );
}

/// A download the client leaves is logged with the bytes that went out, not those the answer
/// promised (the log said the whole file, and the milliseconds its headers took).
#[test]
fn a_download_the_client_leaves_is_logged_with_what_was_sent() {
    use std::io::{Read, Write};
    // An octree.bin of 256 MiB (the city's, padded): far more than a loopback connection's
    // buffers hold, however they are tuned, so that most of it cannot have gone out.
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("big.strata");
    std::fs::create_dir(&ds).expect("mkdir");
    for name in ["metadata.json", "hierarchy.bin", "octree.bin"] {
        std::fs::copy(root().join("city.strata").join(name), ds.join(name)).expect("copy");
    }
    let len = 256u64 << 20;
    std::fs::File::options()
        .write(true)
        .open(ds.join("octree.bin"))
        .and_then(|f| f.set_len(len))
        .expect("pad");
    let (server, log) = logging_server_in(dir.path(), &["--log-format", "json"]);
    let path = "/big.strata/octree.bin";
    let mut stream = std::net::TcpStream::connect(&server.addr).expect("connect");
    write!(
        stream,
        "GET {path} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"
    )
    .expect("request");
    let mut first = vec![0u8; 64 << 10];
    stream.read_exact(&mut first).expect("the answer's start");
    drop(stream);
    let line = next_line_with(&log, path).expect("logged");
    let v: serde_json::Value = serde_json::from_str(&line).expect("a JSON line");
    assert_eq!(v["status"], 200);
    let sent = v["bytes"].as_u64().expect("bytes");
    assert!(
        sent < len,
        "{sent} of {len} bytes logged for a download left after 64 KiB"
    );
}

/// A file that shrinks while it is being served: the connection is closed short of the length
/// the answer promised, and its log line says why. The line looked like a client that left.
#[test]
fn a_file_cut_short_while_served_is_logged_as_such() {
    use std::io::{Read, Write};
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("city.strata");
    std::fs::create_dir(&ds).expect("dataset folder");
    for entry in std::fs::read_dir(super::root().join("city.strata")).expect("dataset") {
        let entry = entry.expect("entry");
        if entry.file_type().expect("type").is_file() {
            std::fs::copy(entry.path(), ds.join(entry.file_name())).expect("copy");
        }
    }
    // Far longer than the sockets' buffers hold: the server is still reading it when it
    // shrinks.
    let octree = ds.join("octree.bin");
    let file = std::fs::OpenOptions::new()
        .write(true)
        .open(&octree)
        .expect("octree.bin");
    file.set_len(256 << 20).expect("grow");
    let (server, log) = logging_server_in(dir.path(), &[]);
    let mut conn = std::net::TcpStream::connect(&server.addr).expect("connect");
    conn.set_read_timeout(Some(Duration::from_secs(10)))
        .expect("timeout");
    conn.write_all(b"GET /city.strata/octree.bin HTTP/1.1\r\nHost: x\r\n\r\n")
        .expect("request");
    let mut buf = vec![0u8; 1 << 16];
    let first = conn.read(&mut buf).expect("the answer starts");
    assert!(first > 0);
    file.set_len(1 << 20).expect("shrink");
    let mut got = first as u64;
    loop {
        match conn.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => got += n as u64,
        }
    }
    assert!(got < 256 << 20, "all {got} bytes came");
    let line = next_line_with(&log, "octree.bin").expect("a log line");
    assert!(
        line.contains(" 200 ") && line.contains("cut short: file shrank while being served"),
        "{line}"
    );
}

/// A file dated before 1970 or after 9999, which no HTTP date states: served whole, with no
/// Last-Modified. Every request for it was a 500 (the date formatter panicked). A file dated
/// within the current second or ahead of it gets no date validator either, so that a range
/// resumed by date cannot splice two versions written within one second: If-Range with its
/// date gives the whole file, while If-Unmodified-Since still holds.
#[test]
fn files_dated_where_no_http_date_holds_them_are_served() {
    let dir = scratch("dates");
    copy_autzen(&dir.path().join("good.strata"), &ALL);
    let meta = dir.path().join("good.strata/metadata.json");
    let len = std::fs::metadata(&meta).expect("metadata.json").len();
    let server = Server::start_in(dir.path(), &["--quiet"]);
    let epoch = std::time::UNIX_EPOCH;
    for (what, seconds, date) in [
        ("before 1970", -1i64, "Wed, 31 Dec 1969 23:59:59 GMT"),
        (
            "in year 10000",
            253_402_300_800,
            "Sat, 01 Jan 10000 00:00:00 GMT",
        ),
        ("in 2100", 4_102_444_800, "Fri, 01 Jan 2100 00:00:00 GMT"),
    ] {
        let when = if seconds < 0 {
            epoch - Duration::from_secs(seconds.unsigned_abs())
        } else {
            epoch + Duration::from_secs(seconds as u64)
        };
        let file = std::fs::File::options()
            .write(true)
            .open(&meta)
            .expect("open");
        file.set_modified(when).expect("set the time");
        let path = "/good.strata/metadata.json";
        let r = get(&server.addr, path, &[]).expect("an answer");
        assert_eq!((r.status, r.body.len() as u64), (200, len), "{what}");
        assert_eq!(r.header("Last-Modified"), None, "{what}");
        assert!(r.header("ETag").is_some(), "{what}");
        let range = [("Range", "bytes=0-9"), ("If-Range", date)];
        let r = get(&server.addr, path, &range).expect("an answer");
        assert_eq!((r.status, r.body.len() as u64), (200, len), "{what}");
        // The conditions still compare with the file's time where there is one.
        let epoch_date = [("If-Unmodified-Since", "Thu, 01 Jan 1970 00:00:00 GMT")];
        let r = get(&server.addr, path, &epoch_date).expect("an answer");
        assert_eq!(r.status, if seconds > 0 { 412 } else { 200 }, "{what}");
    }
}
