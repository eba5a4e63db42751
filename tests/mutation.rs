//! The structure-aware mutation test: seeded mutations of real inputs across every class of
//! fault (header fields at their boundaries, VLR and extra-bytes nonsense, laszip VLR and chunk
//! table damage, bit flips in records and compressed bodies, PLY header and body faults, odd but
//! valid clouds, E57 damage behind repaired page checksums). For each: no panic, no abort, no hang, and either a clean one-sentence refusal
//! with no dataset left, or an exact conversion. `STRATA_MUTATION_CASES` raises the count (300 by
//! default) and `STRATA_MUTATION_SEED` changes the seed.

#[path = "mutation/bytes.rs"]
mod bytes;
#[path = "mutation/cases.rs"]
mod cases;
mod common;
#[path = "mutation/e57.rs"]
mod e57_cases;
#[path = "e57/write.rs"]
mod e57_write;

use cases::{Case, Expect, Rng, Seeds};
use common::*;
use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

/// A conversion that takes longer is a hang (the largest case converts in well under a second).
const DEADLINE: Duration = Duration::from_secs(30);

#[derive(Debug, PartialEq)]
enum Outcome {
    Refused,
    Converted,
}

fn env_u64(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Converts one case in a child process under a deadline and checks the rule; returns the
/// outcome or what broke it.
fn check(case: &Case, dir: &Path, index: usize) -> Result<Outcome, String> {
    let input = dir.join(format!("case{index}.{}", case.ext));
    std::fs::write(&input, &case.bytes).map_err(|e| e.to_string())?;
    let out = dir.join(format!("ds{index}"));
    let mut child = strata()
        .args([
            "convert",
            s(&input),
            "-o",
            s(&out),
            "--quiet",
            "--threads",
            "2",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("cannot run strata: {e}"))?;
    let start = Instant::now();
    let status = loop {
        if let Some(st) = child.try_wait().map_err(|e| e.to_string())? {
            break st;
        }
        if start.elapsed() > DEADLINE {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("hang: no result after {DEADLINE:?}"));
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let mut err = String::new();
    if let Some(mut e) = child.stderr.take() {
        use std::io::Read;
        let _ = e.read_to_string(&mut err);
    }
    let Some(code) = status.code() else {
        return Err(format!("abort: killed by a signal ({status}): {err}"));
    };
    if err.contains("panicked") || code == 101 {
        return Err(format!("panic: {err}"));
    }
    let result = if code == 0 {
        check_converted(case, &input, &out, &err).map(|_| Outcome::Converted)
    } else {
        check_refusal(&input, &out, &err).map(|_| Outcome::Refused)
    };
    let _ = std::fs::remove_dir_all(&out);
    let _ = std::fs::remove_file(&input);
    result
}

fn check_refusal(input: &Path, out: &Path, err: &str) -> Result<(), String> {
    let name = input.file_name().and_then(|n| n.to_str()).unwrap_or("?");
    let text = err.trim_end_matches('\n');
    let problems = [
        (text.lines().count() != 1, "not one line"),
        (!text.starts_with("error: "), "not an error line"),
        (!text.contains(name), "does not name the file"),
        (
            text.chars().any(|c| c.is_control() && c != '\t'),
            "echoes control characters",
        ),
        (
            ["{ ", "Some(", "Error(", "Err(", "kind: "]
                .iter()
                .any(|d| text.contains(d)),
            "holds Rust debug text",
        ),
        (
            text.matches("os error").count() > 1 || text.contains("buffer: failed"),
            "says an error twice",
        ),
        (out.exists(), "left a dataset"),
        (
            out.with_extension("strata-tmp").exists(),
            "left a work directory",
        ),
    ];
    match problems.iter().find(|(bad, _)| *bad) {
        Some((_, why)) => Err(format!("refusal {why}: {text}")),
        None => Ok(()),
    }
}

fn check_converted(case: &Case, input: &Path, out: &Path, err: &str) -> Result<(), String> {
    let v = run(&["verify", s(out)]);
    if !v.status.success() {
        return Err(format!(
            "converted, but the dataset fails verify: {}",
            String::from_utf8_lossy(&v.stderr)
        ));
    }
    if case.ext == "ply" {
        return Ok(());
    }
    if case.ext == "e57" {
        return check_e57(input, out, err);
    }
    // The points must be the las crate's reading of the file, every field of every point.
    let expected = std::panic::catch_unwind(|| las_multiset(input));
    let Ok(expected) = expected else {
        return Err(format!(
            "converted a file the las crate cannot read (warnings: {err})"
        ));
    };
    let exported = out.with_extension("export.las");
    let e = run(&["export", s(out), "-o", s(&exported)]);
    if !e.status.success() {
        return Err("converted, but export fails".into());
    }
    let got = las_multiset(&exported);
    let _ = std::fs::remove_file(&exported);
    if got != expected {
        let moved = got.iter().zip(&expected).filter(|(a, b)| a != b).count();
        return Err(format!(
            "silent corruption: {} points read, {} converted, {moved} differ (warnings: {})",
            expected.len(),
            got.len(),
            err.trim()
        ));
    }
    Ok(())
}

/// A converted E57 case holds as many points as the `e57` crate reads valid ones from it.
fn check_e57(input: &Path, out: &Path, err: &str) -> Result<(), String> {
    let expected = std::panic::catch_unwind(|| e57_write::crate_points(input).len());
    let Ok(expected) = expected else {
        return Err(format!(
            "converted a file the e57 crate cannot read (warnings: {err})"
        ));
    };
    let meta = std::fs::read(out.join("metadata.json")).map_err(|e| e.to_string())?;
    let meta: serde_json::Value = serde_json::from_slice(&meta).map_err(|e| e.to_string())?;
    match meta["points"].as_u64() {
        Some(n) if n == expected as u64 => Ok(()),
        n => Err(format!(
            "silent corruption: the e57 crate reads {expected} valid points, {n:?} converted"
        )),
    }
}

#[test]
fn mutated_inputs_are_refused_cleanly_or_converted_exactly() {
    let count = env_u64("STRATA_MUTATION_CASES", 300) as usize;
    let seed = env_u64("STRATA_MUTATION_SEED", 24);
    let seeds = Seeds::read(&data(""));
    let generators: [fn(&Seeds, &mut Rng) -> Case; 6] = [
        cases::las_header,
        cases::extra_bytes,
        cases::laszip,
        cases::records,
        cases::ply,
        cases::odd_valid,
    ];
    let mut rng = Rng::new(seed);
    let mut all: Vec<Case> = (0..count)
        .map(|i| generators[i % generators.len()](&seeds, &mut rng))
        .collect();
    // E57 cases draw from their own generator, so the others stay what each seed made them.
    let e57_seeds = e57_cases::E57Seeds::read(&data(""));
    let mut e57_rng = Rng::new(seed ^ 0xE57);
    all.extend((0..count / generators.len()).map(|_| e57_cases::e57(&e57_seeds, &mut e57_rng)));
    let dir = tempfile::tempdir().expect("tempdir");
    let threads = 2;
    let results: Vec<(usize, Result<Outcome, String>)> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|t| {
                let (all, dir) = (&all, dir.path());
                scope.spawn(move || {
                    (t..all.len())
                        .step_by(threads)
                        .map(|i| (i, check(&all[i], dir, i)))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().expect("worker"))
            .collect()
    });
    let mut failures = Vec::new();
    let (mut refused, mut converted) = (0, 0);
    for (i, r) in results {
        let case = &all[i];
        let r = r.and_then(|o| match (case.expect, &o) {
            (Expect::Refuse, Outcome::Converted) => Err("accepted although invalid".into()),
            (Expect::Exact, Outcome::Refused) => Err("a valid input was refused".into()),
            _ => Ok(o),
        });
        match r {
            Ok(Outcome::Refused) => refused += 1,
            Ok(Outcome::Converted) => converted += 1,
            Err(why) => failures.push(format!("case {i} ({}): {why}", case.name)),
        }
    }
    eprintln!(
        "{count} cases (seed {seed}): {refused} refused cleanly, {converted} converted exactly, {} failed",
        failures.len()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
