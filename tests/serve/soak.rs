//! 256 keep-alive connections asking for random ranges for 20 s: every answer right, and the
//! server's threads, descriptors and memory where they were before.

use super::attacks::process_counts;
use super::{Server, root};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::sync::Arc;
use std::time::{Duration, Instant};

const CONNECTIONS: usize = 256;

/// One keep-alive connection asking for random ranges until `until`: (answers, errors).
fn client(addr: &str, disk: &[u8], seed: u64, until: Instant) -> (u64, u64) {
    let Ok(stream) = TcpStream::connect(addr) else {
        return (0, 1);
    };
    let timeout = Some(Duration::from_secs(10));
    if stream.set_read_timeout(timeout).is_err() || stream.set_write_timeout(timeout).is_err() {
        return (0, 1);
    }
    let Ok(mut writer) = stream.try_clone() else {
        return (0, 1);
    };
    let mut reader = BufReader::new(stream);
    let mut state = seed | 1;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let (mut ok, mut bad) = (0, 0);
    let mut line = String::new();
    while Instant::now() < until {
        let size = 1 + (next() % 65_536) as usize;
        let start = (next() % (disk.len() - size) as u64) as usize;
        let req = format!(
            "GET /city.strata/octree.bin HTTP/1.1\r\nHost: {addr}\r\nRange: bytes={start}-{}\r\n\r\n",
            start + size - 1
        );
        if writer.write_all(req.as_bytes()).is_err() {
            return (ok, bad + 1);
        }
        let (mut status, mut length) = (0u16, None::<usize>);
        loop {
            line.clear();
            if reader.read_line(&mut line).unwrap_or(0) == 0 {
                return (ok, bad + 1);
            }
            let l = line.trim_end();
            if l.is_empty() {
                break;
            }
            if status == 0 {
                status = l
                    .split(' ')
                    .nth(1)
                    .and_then(|c| c.parse().ok())
                    .unwrap_or(1);
            } else if let Some((k, v)) = l.split_once(':')
                && k.eq_ignore_ascii_case("content-length")
            {
                length = v.trim().parse().ok();
            }
        }
        let Some(length) = length else {
            return (ok, bad + 1);
        };
        let mut body = vec![0; length];
        if reader.read_exact(&mut body).is_err() {
            return (ok, bad + 1);
        }
        if status == 206 && body == disk[start..start + size] {
            ok += 1;
        } else {
            bad += 1;
        }
    }
    (ok, bad)
}

/// All connections at once for `time`: (answers, errors).
fn load(addr: &str, disk: &Arc<Vec<u8>>, time: Duration, seed: u64) -> (u64, u64) {
    let until = Instant::now() + time;
    let threads: Vec<_> = (0..CONNECTIONS)
        .map(|i| {
            let (addr, disk) = (addr.to_string(), disk.clone());
            std::thread::spawn(move || client(&addr, &disk, seed + i as u64 * 7919, until))
        })
        .collect();
    threads
        .into_iter()
        .map(|t| t.join().unwrap_or((0, 1)))
        .fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
}

/// The server's counts once its descriptors have come back down (connections close
/// asynchronously), waiting up to 5 s.
fn settled(pid: u32, fds_at_most: usize) -> (u64, usize, u64) {
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let counts = process_counts(pid);
        if counts.1 <= fds_at_most || Instant::now() > deadline {
            return counts;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn soak_256_connections_of_random_ranges_for_20_s() {
    let server = Server::start_in(&super::root(), &["--quiet", "--max-connections", "1024"]);
    let pid = server.child.id();
    let disk = Arc::new(std::fs::read(root().join("city.strata/octree.bin")).expect("read"));
    let (idle_threads, idle_fds, _) = process_counts(pid);
    // Warm up: the same load briefly, so pools and allocator arenas reach their working size.
    let (warm, warm_errors) = load(&server.addr, &disk, Duration::from_secs(2), 1);
    assert!(
        warm > 0 && warm_errors == 0,
        "warm-up: {warm} answers, {warm_errors} errors"
    );
    let (threads_before, fds_before, rss_before) = settled(pid, idle_fds);
    let (answers, errors) = load(&server.addr, &disk, Duration::from_secs(20), 99);
    let (threads, fds, rss) = settled(pid, idle_fds);
    eprintln!(
        "soak: {answers} answers, {errors} errors; threads {idle_threads} idle, {threads_before} \
         after warm-up, {threads} after; fds {idle_fds} / {fds_before} / {fds}; RSS {rss_before} \
         -> {rss} KiB"
    );
    assert_eq!(
        errors,
        0,
        "{errors} failed requests of {}",
        answers + errors
    );
    assert!(answers > CONNECTIONS as u64, "only {answers} answers");
    assert!(
        threads <= threads_before + 2,
        "threads grew from {threads_before} to {threads}"
    );
    assert!(
        fds <= idle_fds,
        "descriptors: {idle_fds} idle, {fds} after the soak"
    );
    assert!(
        rss <= rss_before + 32 * 1024,
        "resident memory grew from {rss_before} to {rss} KiB"
    );
}
