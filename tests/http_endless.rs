//! A server whose answers never end: the client reads what it asked for, no more, and fails
//! with an error naming the file instead of filling the memory.

use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
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
