//! A server whose answers never end: the client reads what it asked for, no more, and fails
//! with an error naming the file instead of filling the memory. A server that ignores Range
//! and sends whole files still serves: the client reads each up to the range's end. A server
//! that falls silent fails a render within the render's --timeout. A node claimed beyond its
//! file's end is refused without a read; files named otherwise, and a URL's query (a
//! presigned URL's signature), are asked for as the dataset and the URL name them. With no
//! server at the address, the error says the connection was refused; a server that refuses
//! access is asked once, and again later.

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
    serve_whole_files(root, answers, None)
}

/// As `silent_after_server`; a request whose target lacks `?query` (where one is given) gets
/// 403, as object storage answers a URL without its signature.
fn serve_whole_files(root: PathBuf, answers: usize, query: Option<&'static str>) -> String {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = listener.local_addr().expect("addr").to_string();
    let left = Arc::new(AtomicUsize::new(answers));
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            let root = root.clone();
            let left = left.clone();
            std::thread::spawn(move || answer_whole_files(stream, &root, &left, query));
        }
    });
    addr
}

fn answer_whole_files(stream: TcpStream, root: &Path, left: &AtomicUsize, query: Option<&str>) {
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
        let target = first.split(' ').nth(1).unwrap_or("/").to_string();
        let (path, asked) = target.split_once('?').unwrap_or((&target, ""));
        if query.is_some_and(|q| q != asked) {
            let _ = out.write_all(b"HTTP/1.1 403 Forbidden\r\nContent-Length: 0\r\n\r\n");
            continue;
        }
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

/// A hierarchy entry whose range lies beyond octree.bin (its page's checksum can be right):
/// refused, naming the range and the file's size, before anything is asked. Over a server
/// that ignores Range the range's end once overflowed and panicked a loader thread, and the
/// render went on without the node, exit 0.
#[test]
fn a_node_claimed_past_the_files_end_is_refused_not_read() {
    let ds = converted("past-the-end", "autzen_trim.las", "ds");
    let root = ds.parent().expect("parent").to_path_buf();
    let url = format!("http://{}/ds.strata", range_ignoring_server(root));
    let remote = StreamDataset::open(&url, HttpOptions::default()).expect("opens");
    let node = remote
        .root_hierarchy_page()
        .nodes()
        .nth(1)
        .expect("a second node");
    let size = std::fs::metadata(ds.join("octree.bin"))
        .expect("octree")
        .len();
    for (offset, len) in [(u64::MAX - 255, 4096), (size, 1), (24, u32::MAX - 15)] {
        let hostile = strata_format::NodeInfo {
            offset,
            size: len,
            ..node
        };
        let err = match remote.load_node(
            &hostile,
            strata_viewer::dataset::ColourWord::Stored,
            &Default::default(),
        ) {
            Ok(_) => panic!("a node at byte {offset} loaded"),
            Err(e) => e.to_string(),
        };
        assert!(
            err.contains(&format!(
                "range of {len} bytes at byte {offset} lies past the end ({size} bytes)"
            )),
            "{err}"
        );
    }
}

/// Files named otherwise than hierarchy.bin and octree.bin (SPEC.md section 2), served where
/// every request must carry the URL's query: both are kept, and a fragment is not sent.
#[test]
fn files_named_otherwise_and_a_query_are_asked_for_as_named() {
    let ds = converted("named-otherwise", "autzen_trim.las", "ds");
    let dir = fresh_dir("named-otherwise-served");
    let renamed = dir.join("ren.strata");
    std::fs::create_dir_all(&renamed).expect("dir");
    std::fs::copy(ds.join("hierarchy.bin"), renamed.join("h.bin")).expect("copy");
    std::fs::copy(ds.join("octree.bin"), renamed.join("o.bin")).expect("copy");
    let text = std::fs::read_to_string(ds.join("metadata.json")).expect("metadata");
    let mut meta: serde_json::Value = serde_json::from_str(&text).expect("json");
    meta["files"]["hierarchy"]["name"] = "h.bin".into();
    meta["files"]["octree"]["name"] = "o.bin".into();
    std::fs::write(renamed.join("metadata.json"), meta.to_string()).expect("write");
    let addr = serve_whole_files(dir.clone(), usize::MAX, Some("sig=abc"));
    let url = format!("http://{addr}/ren.strata?sig=abc#view");
    let remote = StreamDataset::open(&url, HttpOptions::default()).expect("opens");
    let local = StreamDataset::open_path(&ds).expect("opens locally");
    let colours = strata_viewer::dataset::ColourWord::Stored;
    for node in remote.root_hierarchy_page().nodes().take(3) {
        let got = remote
            .load_node(&node, colours, &Default::default())
            .expect("over HTTP");
        let want = local
            .load_node(&node, colours, &Default::default())
            .expect("locally");
        assert_eq!(got.points, want.points, "node {}", node.key);
    }
    // The signature stays out of what is shown: the location, and an error naming a file.
    assert!(!remote.location().contains("sig"), "{}", remote.location());
    let node = remote
        .root_hierarchy_page()
        .nodes()
        .nth(1)
        .expect("a second node");
    let past = strata_format::NodeInfo {
        offset: u64::MAX - 255,
        ..node
    };
    let err = match remote.load_node(&past, colours, &Default::default()) {
        Ok(_) => panic!("a node past the end loaded"),
        Err(e) => e.to_string(),
    };
    assert!(
        err.contains("/ren.strata/o.bin") && !err.contains("sig"),
        "{err}"
    );
    // Without the query every file is refused.
    let bare = format!("http://{addr}/ren.strata");
    assert!(StreamDataset::open(&bare, HttpOptions::default()).is_err());
}

/// A user name and password in the URL would be neither sent nor kept out of messages and
/// stats: refused, and not repeated.
#[test]
fn credentials_in_the_url_are_refused_and_not_repeated() {
    let err = match StreamDataset::open(
        "http://surveyor:s3cret@127.0.0.1:9/ds.strata",
        HttpOptions::default(),
    ) {
        Ok(_) => panic!("opened"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains("user name or password"), "{err}");
    assert!(
        !err.contains("s3cret") && !err.contains("surveyor"),
        "{err}"
    );
}

/// A server that sends files compressed (object storage does, for files uploaded with a
/// Content-Encoding): bytes of the compressed body are not the file's, and the error says
/// why, where it said "not valid JSON" or named a length.
#[test]
fn a_compressed_answer_is_refused_naming_its_encoding() {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = listener.local_addr().expect("addr").to_string();
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            let mut reader = BufReader::new(stream.try_clone().expect("clone"));
            let mut line = String::new();
            while reader.read_line(&mut line).unwrap_or(0) > 0 && line != "\r\n" {
                line.clear();
            }
            let mut out = stream;
            let _ = out.write_all(
                b"HTTP/1.1 200 OK\r\nContent-Encoding: gzip\r\nContent-Length: 4\r\n\r\n\x1f\x8b\x08\x00",
            );
        }
    });
    let url = format!("http://{addr}/ds.strata");
    let err = match StreamDataset::open(&url, HttpOptions::default()) {
        Ok(_) => panic!("a compressed dataset opened"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains("Content-Encoding gzip"), "{err}");
}

/// No server at the address: the error says the connection was refused, where it said
/// "request failed (client error (Connect))".
#[test]
fn no_server_at_the_address_is_named_as_a_refused_connection() {
    // A port just bound and let go: nothing listens there.
    let addr = TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port");
    let err = match StreamDataset::open(&format!("http://{addr}/ds.strata"), HttpOptions::default())
    {
        Ok(_) => panic!("opened"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains("cannot connect"), "{err}");
    assert!(err.to_lowercase().contains("refused"), "{err}");
    assert!(err.contains("metadata.json"), "{err}");
}

/// A server that refuses access (401): asked once, not again at once, and the failure is one a
/// later request may get past (a token rotated, the server restarted with the one given), so
/// the window asks again and shows why. It failed the nodes for good, holes for the session.
#[test]
fn refused_access_is_asked_once_and_may_pass_later() {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = listener.local_addr().expect("addr").to_string();
    let asked = Arc::new(std::sync::Mutex::new(Vec::new()));
    let counted = asked.clone();
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            let mut reader = BufReader::new(stream.try_clone().expect("clone"));
            let mut line = String::new();
            while reader.read_line(&mut line).unwrap_or(0) > 0 && line != "\r\n" {
                if line.starts_with("GET ") {
                    counted
                        .lock()
                        .unwrap_or_else(std::sync::PoisonError::into_inner)
                        .push(line.clone());
                }
                line.clear();
            }
            let mut out = stream;
            let _ = out.write_all(b"HTTP/1.1 401 Unauthorized\r\nContent-Length: 0\r\n\r\n");
        }
    });
    let err = match StreamDataset::open(&format!("http://{addr}/ds.strata"), HttpOptions::default())
    {
        Ok(_) => panic!("opened"),
        Err(e) => e,
    };
    assert!(err.to_string().contains("refused access"), "{err}");
    assert!(err.is_transient(), "{err:?}");
    let mut asked = asked
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .clone();
    let n = asked.len();
    asked.sort();
    asked.dedup();
    assert_eq!(asked.len(), n, "a file asked for again at once: {asked:?}");
}
