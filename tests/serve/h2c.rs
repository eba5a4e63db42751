//! HTTP/2 without TLS (h2c, prior knowledge) on the same port as HTTP/1.1: a client that
//! multiplexes gets the same bytes.

use super::{Server, root};
use bytes::Bytes;
use http_body_util::{BodyExt, Empty};
use hyper_util::client::legacy::Client;
use hyper_util::rt::TokioExecutor;
use std::time::Duration;

/// A server of the fixtures, the city's octree file as on disk, its URL, and a runtime for
/// the client.
fn octree_server() -> (Server, Vec<u8>, String, tokio::runtime::Runtime) {
    let server = Server::start_in(&super::root(), &["--quiet"]);
    let disk = std::fs::read(root().join("city.strata/octree.bin")).expect("read");
    let url = format!("http://{}/city.strata/octree.bin", server.addr);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    (server, disk, url, runtime)
}

#[test]
fn an_h2c_client_gets_ranges_over_one_connection() {
    let (_server, disk, url, runtime) = octree_server();
    let client: Client<_, Empty<Bytes>> = Client::builder(TokioExecutor::new())
        .http2_only(true)
        .build_http();
    let ranges: Vec<(usize, usize)> = (0..32)
        .map(|i| {
            let start = (i * 7919 * 131) % (disk.len() - 70_000);
            (start, start + 1 + (i * 2111) % 65_536)
        })
        .collect();
    let answers = runtime.block_on(async {
        let fetches = ranges.iter().map(|&(a, b)| {
            let req = hyper::Request::get(&url)
                .header("Range", format!("bytes={a}-{}", b - 1))
                .body(Empty::new())
                .expect("request");
            let client = client.clone();
            async move {
                let resp = client.request(req).await.expect("an h2c answer");
                let (parts, body) = resp.into_parts();
                let bytes = body.collect().await.expect("body").to_bytes();
                (parts.status, parts.version, bytes)
            }
        });
        let all = futures_join(fetches.collect());
        tokio::time::timeout(Duration::from_secs(20), all)
            .await
            .expect("h2c answers within 20 s")
    });
    for ((status, version, bytes), (a, b)) in answers.into_iter().zip(ranges) {
        assert_eq!(status, 206);
        assert_eq!(version, hyper::Version::HTTP_2);
        assert_eq!(bytes[..], disk[a..b], "bytes {a}..{b} differ over h2c");
    }
}

/// Runs `futures` concurrently (on one connection, as h2 streams) and returns their outputs in
/// order.
async fn futures_join<F: std::future::Future + Send + 'static>(futures: Vec<F>) -> Vec<F::Output>
where
    F::Output: Send + 'static,
{
    let handles: Vec<_> = futures.into_iter().map(tokio::spawn).collect();
    let mut out = Vec::with_capacity(handles.len());
    for h in handles {
        out.push(h.await.expect("task"));
    }
    out
}

/// An h2c connection that sends only PINGs makes no progress: it is closed at the idle limit.
/// Each PING counted as progress, so a PING a minute held a connection (and the answers
/// buffered on it) for good.
#[test]
fn pings_alone_do_not_hold_an_h2c_connection() {
    use std::io::{Read, Write};
    let server = Server::start_in(&root(), &["--quiet", "--idle-timeout", "2"]);
    let mut conn = std::net::TcpStream::connect(&server.addr).expect("connect");
    conn.set_read_timeout(Some(Duration::from_millis(300)))
        .expect("timeout");
    let mut opening = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n".to_vec();
    opening.extend_from_slice(&[0, 0, 0, 4, 0, 0, 0, 0, 0]); // SETTINGS, empty
    conn.write_all(&opening).expect("preface");
    let ping = [0, 0, 8, 6, 0, 0, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8];
    let start = std::time::Instant::now();
    let mut buf = [0u8; 4096];
    let closed = loop {
        if start.elapsed() > Duration::from_secs(10) {
            break false;
        }
        if conn.write_all(&ping).is_err() {
            break true;
        }
        match conn.read(&mut buf) {
            Ok(0) => break true,
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(_) => break true,
        }
    };
    assert!(closed, "a connection sending PINGs was held for 10 s");
    assert!(
        start.elapsed() < Duration::from_secs(6),
        "held {:?} with an idle limit of 2 s",
        start.elapsed()
    );
}

/// Sends a GET of `path` as a new stream every 300 ms on an h2c connection whose streams'
/// windows are shut (SETTINGS_INITIAL_WINDOW_SIZE 0: no answer's body can go out) for up to
/// `hold`; whether the server closed it, and when.
fn shut_window_requests(server: &Server, path: &str, hold: Duration) -> Option<Duration> {
    use std::io::{Read, Write};
    let mut conn = std::net::TcpStream::connect(&server.addr).expect("connect");
    conn.set_read_timeout(Some(Duration::from_millis(50)))
        .expect("timeout");
    let mut opening = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n".to_vec();
    // SETTINGS: INITIAL_WINDOW_SIZE (4) = 0.
    opening.extend_from_slice(&[0, 0, 6, 4, 0, 0, 0, 0, 0, 0, 4, 0, 0, 0, 0]);
    conn.write_all(&opening).expect("preface");
    // :method GET, :scheme http (indexed); :path and :authority literal, not indexed.
    let mut block = vec![0x82, 0x86, 0x04, path.len() as u8];
    block.extend_from_slice(path.as_bytes());
    block.extend_from_slice(&[0x01, 9]);
    block.extend_from_slice(b"localhost");
    let start = std::time::Instant::now();
    let mut buf = [0u8; 65536];
    let mut stream = 1u32;
    while start.elapsed() < hold {
        let len = (block.len() as u32).to_be_bytes();
        // HEADERS, END_STREAM | END_HEADERS.
        let mut headers = vec![len[1], len[2], len[3], 1, 5];
        headers.extend_from_slice(&stream.to_be_bytes());
        headers.extend_from_slice(&block);
        stream += 2;
        if conn.write_all(&headers).is_err() {
            return Some(start.elapsed());
        }
        // One request a period, answered or not: h2 sends GOAWAY to a client whose requests
        // it keeps refusing faster.
        std::thread::sleep(Duration::from_millis(250));
        match conn.read(&mut buf) {
            Ok(0) => return Some(start.elapsed()),
            Ok(_) => {}
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(_) => return Some(start.elapsed()),
        }
    }
    None
}

/// Requests alone make no progress on a connection whose answers cannot go out: it is closed
/// at the idle limit. Each request counted as progress (answered with headers, or refused once
/// the connection's streams were all taken), so a client sending one every so often with its
/// windows shut held the connection, and the answers buffered on it, for good.
#[test]
fn requests_with_their_windows_shut_do_not_hold_an_h2c_connection() {
    let path = "/city.strata/octree.bin";
    // Within a long limit the connection stands: the requests are well formed, and nothing
    // else closes it.
    let patient = Server::start_in(&root(), &["--quiet", "--idle-timeout", "60"]);
    assert_eq!(
        shut_window_requests(&patient, path, Duration::from_secs(4)),
        None,
        "closed within 4 s with an idle limit of 60 s"
    );
    let server = Server::start_in(&root(), &["--quiet", "--idle-timeout", "2"]);
    let closed = shut_window_requests(&server, path, Duration::from_secs(10));
    assert!(
        closed.is_some_and(|t| t < Duration::from_secs(6)),
        "a connection sending requests with its windows shut was held {closed:?} with an \
         idle limit of 2 s"
    );
}

/// h2c connections that each ask for the whole octree file on 32 streams and never read: the
/// answers' chunks stay in the server's memory until the windows let them out, within the
/// server's budget (128 MiB shared, 256 KiB each connection's own). Each connection held 32
/// chunks of 256 KiB, 8.6 MB; 64 of them held 550 MB, 500 held 4.3 GB. A new client is still
/// answered, from its own reserve, while they hold the whole pool.
#[test]
fn stalled_h2c_streams_hold_a_bounded_share_of_memory() {
    use std::io::Write;
    let server = Server::start_in(&root(), &["--quiet"]);
    let pid = server.child.id();
    let path = "/city.strata/octree.bin";
    // Warmed up: the first answers' allocations are not the stalled streams'.
    assert_eq!(
        super::http::request(&server.addr, "GET", path, &[]).status,
        200
    );
    let (_, _, before_kib) = super::attacks::process_counts(pid);
    let mut block = vec![0x82, 0x86, 0x04, path.len() as u8];
    block.extend_from_slice(path.as_bytes());
    block.extend_from_slice(&[0x01, 9]);
    block.extend_from_slice(b"localhost");
    let len = (block.len() as u32).to_be_bytes();
    let connections: Vec<_> = (0..64)
        .map(|_| {
            let mut conn = std::net::TcpStream::connect(&server.addr).expect("connect");
            // The preface and empty SETTINGS: the default windows of 64 KiB, never opened
            // further, as nothing is read.
            let mut out = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n".to_vec();
            out.extend_from_slice(&[0, 0, 0, 4, 0, 0, 0, 0, 0]);
            for stream in (1u32..64).step_by(2) {
                // HEADERS, END_STREAM | END_HEADERS.
                out.extend_from_slice(&[len[1], len[2], len[3], 1, 5]);
                out.extend_from_slice(&stream.to_be_bytes());
                out.extend_from_slice(&block);
            }
            conn.write_all(&out).expect("requests");
            conn
        })
        .collect();
    // The server reads its chunks as their streams ask: let it read what it will.
    let mut grown_mib = 0;
    for _ in 0..10 {
        std::thread::sleep(Duration::from_millis(300));
        let (_, _, kib) = super::attacks::process_counts(pid);
        grown_mib = grown_mib.max(kib.saturating_sub(before_kib) / 1024);
    }
    assert!(
        grown_mib < 250,
        "64 stalled connections grew the server by {grown_mib} MiB"
    );
    // A new client is answered meanwhile, a large file too.
    let start = std::time::Instant::now();
    let reply = super::http::request(&server.addr, "GET", path, &[]);
    assert_eq!(reply.status, 200);
    assert!(
        start.elapsed() < Duration::from_secs(5),
        "{:?}",
        start.elapsed()
    );
    drop(connections);
}

/// An h2c client that asks for 32 large ranges at once and reads them one after the other,
/// with windows of 64 KiB a stream: the streams it does not read yet each keep a chunk in the
/// server, and the one it reads still finds room for its next. With room for 8 chunks a
/// connection, the 9th download waited until the idle limit closed the connection.
#[test]
fn an_h2c_client_reading_its_streams_in_turn_gets_them_all() {
    let (_server, disk, url, runtime) = octree_server();
    let client: Client<_, Empty<Bytes>> = Client::builder(TokioExecutor::new())
        .http2_only(true)
        .http2_initial_stream_window_size(65_535)
        .http2_initial_connection_window_size(64 << 20)
        .http2_adaptive_window(false)
        .build_http();
    let part = 1 << 20;
    let ranges: Vec<(usize, usize)> = (0..32)
        .map(|i| {
            let start = (i * 211_111) % (disk.len() - part);
            (start, start + part)
        })
        .collect();
    let bodies = runtime.block_on(async {
        let mut pending = Vec::new();
        for &(a, b) in &ranges {
            let req = hyper::Request::get(&url)
                .header("Range", format!("bytes={a}-{}", b - 1))
                .body(Empty::new())
                .expect("request");
            pending.push(tokio::spawn(client.request(req)));
        }
        let mut answers = Vec::new();
        for p in pending {
            let resp = p.await.expect("task").expect("an h2c answer");
            answers.push(resp.into_body());
        }
        // One at a time, in order.
        let in_turn = async {
            let mut bodies = Vec::new();
            for body in answers {
                bodies.push(body.collect().await.expect("body").to_bytes());
            }
            bodies
        };
        tokio::time::timeout(Duration::from_secs(30), in_turn)
            .await
            .expect("every download within 30 s")
    });
    for (bytes, (a, b)) in bodies.into_iter().zip(ranges) {
        assert_eq!(bytes[..], disk[a..b], "bytes {a}..{b} differ");
    }
}
