//! Load on `strata serve` over loopback: C concurrent clients fetch random nodes (byte ranges
//! of octree.bin) for a fixed time. Prints requests/s, MB/s, p50/p99 latency, errors and the
//! server's memory, and, in the same run, the rate of reading the same ranges from the local
//! file (pread on every core) as the ratio.
//!
//! With `--against-nginx`, wrk loads strata and nginx serving the same folder instead, in
//! alternating pairs (strata, then nginx, at each client count, `--rounds` times), with random
//! 1 B to 64 KiB ranges of octree.bin, and prints each pair's ratios.
//!
//! Options: `USAGE` below, or `--help`.

use anyhow::{Context, bail};
use bytes::Bytes;
use http_body_util::{BodyExt, Empty};
use hyper_util::client::legacy::Client;
use hyper_util::rt::TokioExecutor;
use std::io::BufRead;
use std::os::unix::fs::FileExt;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};
use strata_bench::{bench_dir, ensure_city_dataset, parse_count};
use strata_format::LocalDataset;

struct Load {
    requests: u64,
    bytes: u64,
    errors: u64,
    latencies_us: Vec<u64>,
}

fn xorshift(s: &mut u64) -> u64 {
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    *s
}

fn status_kib(pid: u32, key: &str) -> u64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with(key))
                .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
        })
        .unwrap_or(0)
}

async fn http_load(
    url: String,
    nodes: Arc<Vec<(u64, u64)>>,
    clients: usize,
    time: Duration,
) -> Load {
    let client: Client<_, Empty<Bytes>> = Client::builder(TokioExecutor::new())
        .pool_max_idle_per_host(clients)
        .build_http();
    let deadline = Instant::now() + time;
    let tasks: Vec<_> = (0..clients)
        .map(|c| {
            let (client, url, nodes) = (client.clone(), url.clone(), nodes.clone());
            tokio::spawn(async move {
                let mut seed = 0x9e37_79b9_7f4a_7c15 ^ (c as u64 + 1);
                let mut load = Load {
                    requests: 0,
                    bytes: 0,
                    errors: 0,
                    latencies_us: Vec::new(),
                };
                while Instant::now() < deadline {
                    let (offset, size) = nodes[(xorshift(&mut seed) % nodes.len() as u64) as usize];
                    let start = Instant::now();
                    let req = hyper::Request::get(&url)
                        .header("Range", format!("bytes={offset}-{}", offset + size - 1))
                        .body(Empty::new());
                    let ok = match req {
                        Ok(req) => match client.request(req).await {
                            Ok(resp) if resp.status() == 206 => {
                                match resp.into_body().collect().await {
                                    Ok(b) => b.to_bytes().len() as u64 == size,
                                    Err(_) => false,
                                }
                            }
                            _ => false,
                        },
                        Err(_) => false,
                    };
                    load.latencies_us.push(start.elapsed().as_micros() as u64);
                    load.requests += 1;
                    if ok {
                        load.bytes += size;
                    } else {
                        load.errors += 1;
                    }
                }
                load
            })
        })
        .collect();
    let mut total = Load {
        requests: 0,
        bytes: 0,
        errors: 0,
        latencies_us: Vec::new(),
    };
    for t in tasks {
        match t.await {
            Ok(l) => {
                total.requests += l.requests;
                total.bytes += l.bytes;
                total.errors += l.errors;
                total.latencies_us.extend(l.latencies_us);
            }
            Err(_) => total.errors += 1,
        }
    }
    total
}

fn local_load(
    file: &std::path::Path,
    nodes: &[(u64, u64)],
    time: Duration,
) -> anyhow::Result<(u64, u64)> {
    let f = std::fs::File::open(file)?;
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let deadline = Instant::now() + time;
    let results: Vec<(u64, u64)> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                let f = &f;
                s.spawn(move || {
                    let mut seed = 0x1234_5678 ^ (t as u64 + 7);
                    let (mut n, mut bytes) = (0u64, 0u64);
                    let mut buf = Vec::new();
                    while Instant::now() < deadline {
                        let (offset, size) =
                            nodes[(xorshift(&mut seed) % nodes.len() as u64) as usize];
                        buf.resize(size as usize, 0);
                        if f.read_exact_at(&mut buf, offset).is_ok() {
                            n += 1;
                            bytes += size;
                        }
                    }
                    (n, bytes)
                })
            })
            .collect();
        handles.into_iter().filter_map(|h| h.join().ok()).collect()
    });
    Ok(results.iter().fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1)))
}

const USAGE: &str = "cargo run --release -p strata-bench --bin serve-bench -- [--clients 64,256] [--seconds 10]\n    \
       [--points 10M] [--dataset DIR] [--against-nginx [--rounds 3] [--wrk-threads 2]]";

/// The folder a dataset lies in (the one to serve) and its name there.
fn root_and_name(dataset: &std::path::Path) -> anyhow::Result<(&std::path::Path, &str)> {
    let root = dataset
        .parent()
        .context("dataset has no parent directory")?;
    let name = dataset
        .file_name()
        .and_then(|n| n.to_str())
        .context("dataset name")?;
    Ok((root, name))
}

/// wrk against strata and nginx in alternating pairs; prints one row per pair and the medians.
fn against_nginx(
    strata_addr: &str,
    dataset: &std::path::Path,
    clients: &[usize],
    seconds: u64,
    rounds: usize,
    wrk_threads: usize,
) -> anyhow::Result<()> {
    use strata_bench::wrk::{run_wrk, start_nginx};
    let (root, name) = root_and_name(dataset)?;
    let len = std::fs::metadata(dataset.join("octree.bin"))?.len();
    let work = tempfile::tempdir()?;
    let nginx = start_nginx(root, work.path())?;
    println!(
        "\nwrk -t {wrk_threads} -d {seconds}s --latency, random 1 B-64 KiB ranges of {}/octree.bin \
         ({len} bytes), loopback, {} cores; strata --quiet, nginx worker_processes auto, sendfile, \
         access_log off\n",
        dataset.display(),
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    println!(
        "| round | connections | strata req/s | nginx req/s | req/s ratio | strata p99 ms | nginx p99 ms | p99 ratio | errors (strata / nginx) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    let mut ratios: Vec<(usize, f64, f64)> = Vec::new();
    for round in 1..=rounds {
        for &c in clients {
            let s = run_wrk(
                &format!("http://{strata_addr}/{name}/octree.bin"),
                len,
                c,
                wrk_threads,
                seconds,
                work.path(),
            )?;
            let n = run_wrk(
                &format!("http://{}/{name}/octree.bin", nginx.addr),
                len,
                c,
                wrk_threads,
                seconds,
                work.path(),
            )?;
            if s.errors > 0 || n.errors > 0 {
                bail!(
                    "errors under load (strata {}, nginx {}): the comparison would not hold",
                    s.errors,
                    n.errors
                );
            }
            let (rate, p99) = (
                s.requests_per_s / n.requests_per_s.max(1e-9),
                s.p99_ms / n.p99_ms.max(1e-9),
            );
            ratios.push((c, rate, p99));
            println!(
                "| {round} | {c} | {:.0} | {:.0} | {rate:.2} | {:.2} | {:.2} | {p99:.2} | {} / {} |",
                s.requests_per_s, n.requests_per_s, s.p99_ms, n.p99_ms, s.errors, n.errors
            );
        }
    }
    println!("\n| connections | median req/s ratio | median p99 ratio |\n|---|---|---|");
    for &c in clients {
        let median = |pick: fn(&(usize, f64, f64)) -> f64| {
            let mut v: Vec<f64> = ratios.iter().filter(|r| r.0 == c).map(pick).collect();
            v.sort_by(f64::total_cmp);
            v.get(v.len() / 2).copied().unwrap_or(0.0)
        };
        println!("| {c} | {:.2} | {:.2} |", median(|r| r.1), median(|r| r.2));
    }
    Ok(())
}

fn main() -> anyhow::Result<()> {
    if strata_bench::answered_help(USAGE) {
        return Ok(());
    }
    let mut clients = vec![64usize, 256];
    let mut seconds = 10u64;
    let mut points = 10_000_000u64;
    let mut dataset: Option<PathBuf> = None;
    let mut nginx = false;
    let mut rounds = 3usize;
    let mut wrk_threads = 2usize;
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = || it.next().with_context(|| format!("{a} needs a value"));
        match a.as_str() {
            "--clients" => {
                clients = value()?
                    .split(',')
                    .map(|c| c.parse())
                    .collect::<Result<_, _>>()?
            }
            "--seconds" => seconds = value()?.parse()?,
            "--points" => points = parse_count(value()?)?,
            "--dataset" => dataset = Some(PathBuf::from(value()?)),
            "--against-nginx" => nginx = true,
            "--rounds" => rounds = value()?.parse()?,
            "--wrk-threads" => wrk_threads = value()?.parse()?,
            other => bail!("unknown argument {other}"),
        }
    }
    let dataset = match dataset {
        Some(d) => d,
        None => ensure_city_dataset(points, &bench_dir())?,
    };
    let ds = LocalDataset::open(&dataset)?;
    let nodes: Arc<Vec<(u64, u64)>> = Arc::new(
        ds.all_nodes()?
            .iter()
            .filter(|n| n.size > 0)
            .map(|n| (n.offset, n.size as u64))
            .collect(),
    );
    let (root, name) = root_and_name(&dataset)?;
    let strata = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/release/strata");
    if !strata.exists() {
        bail!(
            "{} is missing: run `cargo build --release` first",
            strata.display()
        );
    }
    let mut server = Command::new(&strata)
        .args([
            "serve",
            root.to_str().context("path")?,
            "--bind",
            "127.0.0.1:0",
            "--quiet",
            "--max-connections",
            "1024",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()?;
    let mut banner = String::new();
    std::io::BufReader::new(server.stdout.take().context("stdout")?).read_line(&mut banner)?;
    let addr = banner
        .split("http://")
        .nth(1)
        .and_then(|r| r.split('/').next())
        .context("server address")?
        .to_string();
    if nginx {
        let result = against_nginx(&addr, &dataset, &clients, seconds, rounds, wrk_threads);
        let _ = server.kill();
        let _ = server.wait();
        return result;
    }
    let url = format!("http://{addr}/{name}/octree.bin");
    let time = Duration::from_secs(seconds);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    let avg = nodes.iter().map(|n| n.1).sum::<u64>() / nodes.len().max(1) as u64;
    println!(
        "\n{} nodes of {} (average {} KiB), {} s per run, loopback, {} cores\n",
        nodes.len(),
        dataset.display(),
        avg / 1024,
        seconds,
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    println!(
        "| clients | requests/s | MB/s | p50 ms | p99 ms | errors | server RSS / peak | local pread MB/s | HTTP / local |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for c in clients {
        let mut load = runtime.block_on(http_load(url.clone(), nodes.clone(), c, time));
        let rss = status_kib(server.id(), "VmRSS:");
        let peak = status_kib(server.id(), "VmHWM:");
        let (_, local_bytes) = local_load(&dataset.join("octree.bin"), &nodes, time)?;
        load.latencies_us.sort_unstable();
        let q = |p: f64| {
            load.latencies_us
                .get(((load.latencies_us.len() as f64 - 1.0) * p) as usize)
                .copied()
                .unwrap_or(0) as f64
                / 1e3
        };
        let http_mbs = load.bytes as f64 / 1e6 / seconds as f64;
        let local_mbs = local_bytes as f64 / 1e6 / seconds as f64;
        println!(
            "| {c} | {:.0} | {:.0} | {:.2} | {:.2} | {} | {:.0} / {:.0} MiB | {:.0} | {:.2} |",
            load.requests as f64 / seconds as f64,
            http_mbs,
            q(0.5),
            q(0.99),
            load.errors,
            rss as f64 / 1024.0,
            peak as f64 / 1024.0,
            local_mbs,
            http_mbs / local_mbs.max(1e-9),
        );
    }
    let _ = server.kill();
    let _ = server.wait();
    Ok(())
}
