//! A server whose answers never end: the client reads what it asked for, no more, and fails
//! with an error naming the file instead of filling the memory. A server that ignores Range
//! and sends whole files still serves: the client reads each up to the range's end. A server
//! that falls silent fails a render within the render's --timeout.

mod common;
use common::*;

use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};
use strata_viewer::{HttpOptions, StreamDataset};

/// Answers every request with a chunked body of spaces that goes on until the client hangs up.
fn endless_server() -> String {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = listener.local_addr().expect("addr").to_string();
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            std::thread::spawn(move || answer_endlessly(stream));
        }
    });
    addr
}

fn answer_endlessly(stream: TcpStream) {
    let mut reader = BufReader::new(stream.try_clone().expect("clone"));
    let mut line = String::new();
    while reader.read_line(&mut line).unwrap_or(0) > 0 && line != "\r\n" {
        line.clear();
    }
    let mut out = stream;
    let chunk = vec![b' '; 1 << 16];
    let mut message = b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n".to_vec();
    loop {
        message.extend_from_slice(format!("{:x}\r\n", chunk.len()).as_bytes());
        message.extend_from_slice(&chunk);
        message.extend_from_slice(b"\r\n");
        if out.write_all(&message).is_err() {
            return;
        }
        message.clear();
    }
}

#[test]
fn an_answer_that_never_ends_is_an_error_not_a_full_memory() {
    let addr = endless_server();
    let url = format!("http://{addr}/ds");
    let start = Instant::now();
    let err = match StreamDataset::open(&url, HttpOptions::default()) {
        Ok(_) => panic!("a dataset opened from a server that sends only spaces"),
        Err(e) => e.to_string(),
    };
    // Without a bound the client reads until its timeout and retries, gigabytes later.
    assert!(start.elapsed() < Duration::from_secs(8), "{err}");
    assert!(err.contains(&url), "{err}");
    assert!(err.contains("more than the"), "{err}");
}

/// Answers every request with the whole file under `root`, status 200, whatever its Range.
fn range_ignoring_server(root: PathBuf) -> String {
    silent_after_server(root, usize::MAX)
}

/// As `range_ignoring_server` for its first `answers` requests; then it reads requests and
/// answers none, as a server that hangs.
fn silent_after_server(root: PathBuf, answers: usize) -> String {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = listener.local_addr().expect("addr").to_string();
    let left = Arc::new(AtomicUsize::new(answers));
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            let root = root.clone();
            let left = left.clone();
            std::thread::spawn(move || answer_whole_files(stream, &root, &left));
        }
    });
    addr
}

fn answer_whole_files(stream: TcpStream, root: &Path, left: &AtomicUsize) {
    let mut reader = BufReader::new(stream.try_clone().expect("clone"));
    let mut out = stream;
    loop {
        let mut first = String::new();
        if reader.read_line(&mut first).unwrap_or(0) == 0 {
            return;
        }
        let mut line = String::new();
        while reader.read_line(&mut line).unwrap_or(0) > 0 && line != "\r\n" {
            line.clear();
        }
        let answer = left.fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| n.checked_sub(1));
        if answer.is_err() {
            // Hold the connection open and say nothing until the client hangs up.
            while reader.read_line(&mut line).unwrap_or(0) > 0 {}
            return;
        }
        let path = first.split(' ').nth(1).unwrap_or("/").to_string();
        let data = std::fs::read(root.join(path.trim_start_matches('/'))).unwrap_or_default();
        let head = format!("HTTP/1.1 200 OK\r\nContent-Length: {}\r\n\r\n", data.len());
        if out.write_all(head.as_bytes()).is_err() || out.write_all(&data).is_err() {
            return;
        }
    }
}

#[test]
fn a_server_that_ignores_range_still_serves_the_nodes() {
    let ds = converted("range-ignoring", "autzen_trim.las", "ds");
    let root = ds.parent().expect("parent").to_path_buf();
    let addr = range_ignoring_server(root);
    let url = format!("http://{addr}/ds.strata");
    let remote = StreamDataset::open(&url, HttpOptions::default()).expect("opens");
    let local = StreamDataset::open_path(&ds).expect("opens locally");
    let colours = strata_viewer::dataset::ColourWord::Stored;
    // Every node of the root page, the root (read while opening) and those after it.
    let nodes: Vec<_> = remote.root_hierarchy_page().nodes().take(4).collect();
    assert!(nodes.len() > 1, "a root page with several nodes");
    for node in &nodes {
        let got = remote
            .load_node(node, colours, &Default::default())
            .expect("node over HTTP");
        let want = local
            .load_node(node, colours, &Default::default())
            .expect("node locally");
        assert_eq!(got.points, want.points, "node {}", node.key);
        assert_eq!(got.attributes, want.attributes, "node {}", node.key);
    }
}

#[test]
fn a_server_that_falls_silent_fails_a_render_within_its_timeout() {
    let ds = converted("falls-silent", "autzen_trim.las", "ds");
    let root = ds.parent().expect("parent").to_path_buf();
    let dir = fresh_dir("falls-silent-out");
    let image = dir.join("view.png");
    for (answers, what) in [(0, "metadata.json"), (3, "octree.bin")] {
        // 0: silent from the start; 3: the opening's three reads answered, no node's.
        let url = format!(
            "http://{}/ds.strata",
            silent_after_server(root.clone(), answers)
        );
        let start = Instant::now();
        let out = gpu_run(&["render", &url, "-o", s(&image), "--timeout", "2"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{err}");
        // The read that gave up, or (the render's own wait ending at the same moment) the
        // image that had nothing to show.
        let read = err.contains(&format!("{url}/{what}")) && err.contains("no answer");
        let nothing = what == "octree.bin" && err.contains("nothing was drawn");
        assert!(read || nothing, "{err}");
        // Each read's four attempts once waited 10 s each: 40 s.
        assert!(start.elapsed() < Duration::from_secs(20), "{err}");
        assert!(!image.exists(), "no image is kept");
    }
}
