//! Conversion throughput against the raw decode of the same file, measured in the same run.
//!
//! Options: `USAGE` below, or `--help`.
//!
//! Each conversion runs in a child process, so its peak memory (VmHWM) is its own. Every run
//! starts after `sync`, so no earlier run's dirty pages are written back during it, and the
//! table shows the median of the runs (all of them are listed).

use anyhow::{Context, bail};
use std::path::{Path, PathBuf};
use std::time::Instant;
use strata_bench::{convert_quietly, convert_with_normals, parse_count};
use strata_converter::input::open_source;
use strata_converter::synth::{Scene, synth};
use strata_converter::sys::{format_bytes, parse_size};

fn decode_only(path: &Path) -> anyhow::Result<(u64, f64)> {
    let start = Instant::now();
    let mut src = open_source(path)?;
    let (mut xyz, mut rows) = (Vec::new(), Vec::new());
    let mut n = 0u64;
    loop {
        xyz.clear();
        rows.clear();
        let got = src.read(1 << 18, &mut xyz, &mut rows)?;
        if got == 0 {
            break;
        }
        n += got as u64;
    }
    Ok((n, start.elapsed().as_secs_f64()))
}

/// Flushes dirty pages so that writeback from earlier work does not land inside a timed run.
fn settle() {
    let _ = std::process::Command::new("sync").status();
}

fn child(args: &[String]) -> anyhow::Result<()> {
    let [input, output, limit, step] = args else {
        bail!("child needs IN OUT LIMIT STEP")
    };
    let limit = parse_size(limit).map_err(anyhow::Error::msg)?;
    let summary = match step.as_str() {
        "normals" => convert_with_normals(Path::new(input), Path::new(output), limit)?,
        _ => convert_quietly(Path::new(input), Path::new(output), limit)?,
    };
    println!("{}", serde_json::to_string(&summary)?);
    Ok(())
}

const USAGE: &str = "cargo run --release -p strata-bench --bin convert-bench -- [--points 10M,100M]\n    \
       [--formats las,laz] [--memory-limit 512MiB] [--dir DIR] [--runs 3] [--normals]\n\n\
       --normals: also convert with `--normals` (k = 16) in the same run, and give the ratio.";

fn main() -> anyhow::Result<()> {
    if strata_bench::answered_help(USAGE) {
        return Ok(());
    }
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("child") {
        return child(&args[1..]);
    }
    let mut points = vec![10_000_000u64];
    let mut formats = vec!["las".to_string(), "laz".to_string()];
    let mut limit = "2GiB".to_string();
    let mut dir = PathBuf::from("target/bench-data");
    let mut runs = 3usize;
    let mut steps = vec!["plain"];
    let mut it = args.iter();
    while let Some(a) = it.next() {
        if a == "--normals" {
            steps.push("normals");
            continue;
        }
        let v = it.next().with_context(|| format!("{a} needs a value"))?;
        match a.as_str() {
            "--points" => {
                points = v
                    .split(',')
                    .map(parse_count)
                    .collect::<anyhow::Result<_>>()?
            }
            "--formats" => formats = v.split(',').map(String::from).collect(),
            "--memory-limit" => limit = v.clone(),
            "--dir" => dir = PathBuf::from(v),
            "--runs" => runs = v.parse::<usize>().context("--runs needs a count")?.max(1),
            _ => bail!("unknown option {a}"),
        }
    }
    std::fs::create_dir_all(&dir)?;
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!(
        "conditions: {threads} threads, memory limit {limit}, synth city scene, poisson sampling"
    );
    println!(
        "| points | input | step | decode Mpts/s | convert Mpts/s (median) | convert/decode time | peak memory | nodes |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for &n in &points {
        for f in &formats {
            let input = dir.join(format!("city_{n}.{f}"));
            if !input.exists() {
                synth(&input, n, Scene::City, 1, 0.0, false)?;
            }
            settle();
            let (decoded, decode_s) = decode_only(&input)?;
            let out = dir.join(format!("city_{n}_{f}.strata"));
            let mut plain_secs = None;
            for step in &steps {
                let mut results: Vec<serde_json::Value> = Vec::new();
                for _ in 0..runs {
                    settle();
                    let o = std::process::Command::new(std::env::current_exe()?)
                        .args([
                            "child",
                            &input.to_string_lossy(),
                            &out.to_string_lossy(),
                            &limit,
                            step,
                        ])
                        .output()?;
                    if !o.status.success() {
                        bail!("conversion failed: {}", String::from_utf8_lossy(&o.stderr));
                    }
                    results.push(serde_json::from_slice(&o.stdout)?);
                }
                let secs_of = |v: &serde_json::Value| v["seconds"].as_f64().unwrap_or(f64::NAN);
                results.sort_by(|a, b| secs_of(a).total_cmp(&secs_of(b)));
                let all: Vec<String> = results
                    .iter()
                    .map(|r| format!("{:.2}", n as f64 / secs_of(r) / 1e6))
                    .collect();
                let s = &results[results.len() / 2];
                let secs = secs_of(s);
                println!(
                    "| {n} | {f} | {step} | {:.2} | {:.2} (runs: {}) | {:.2}x | {} | {} |",
                    decoded as f64 / decode_s / 1e6,
                    n as f64 / secs / 1e6,
                    all.join(", "),
                    secs / decode_s,
                    s["peak_memory_bytes"]
                        .as_u64()
                        .map_or("?".into(), format_bytes),
                    s["nodes"],
                );
                let phases: Vec<String> = s["phases"]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .map(|p| {
                        format!(
                            "{} {:.2}s",
                            p["name"].as_str().unwrap_or("?"),
                            p["seconds"].as_f64().unwrap_or(0.0)
                        )
                    })
                    .collect();
                println!("|  | phases: {} | | | | | | |", phases.join(", "));
                match plain_secs {
                    None => plain_secs = Some(secs),
                    Some(plain) => println!(
                        "|  | {step} takes {:.2}x the time of the plain conversion, same run | | | | | | |",
                        secs / plain
                    ),
                }
                let _ = std::fs::remove_dir_all(&out);
            }
        }
    }
    Ok(())
}
