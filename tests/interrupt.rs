//! An interrupted conversion leaves nothing `verify` accepts, and `--resume` finishes it with
//! exactly the dataset an uninterrupted run makes.

mod common;
use common::*;
use std::time::{Duration, Instant};

#[test]
fn kill_9_then_resume_gives_the_same_dataset() {
    kill_9_then_resume(&[]);
}

/// The normals of the chunks done before the kill, and their share of the metadata's totals
/// (kept in the journal), come back as an uninterrupted run makes them.
#[test]
fn kill_9_then_resume_with_normals_gives_the_same_dataset() {
    kill_9_then_resume(&["--normals"]);
}

fn kill_9_then_resume(extra: &[&str]) {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = dir.path().join("city.las");
    run_ok(&["synth", "--points", "1500000", "-o", s(&las)]);
    let clean = dir.path().join("clean");
    let args = |out: &std::path::Path| small_chunks(&las, out, extra);
    run_ok(&strs(&args(&clean)));

    let out = dir.path().join("ds");
    kill_after_a_chunk(
        &args(&out),
        &dir.path().join("ds.strata-tmp/work/journal.jsonl"),
    );
    assert!(
        !out.exists(),
        "an interrupted run must not leave the dataset in place"
    );
    assert!(!run(&["verify", s(&out)]).status.success());
    assert!(
        !run(&["verify", s(&dir.path().join("ds.strata-tmp"))])
            .status
            .success()
    );

    let stats = dir.path().join("stats.json");
    let mut resume = args(&out);
    resume.extend(["--resume".to_string(), "--stats".into(), s(&stats).into()]);
    run_ok(&strs(&resume));
    let st: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&stats).expect("stats")).expect("json");
    assert!(st["resumed_chunks"].as_u64().unwrap_or(0) >= 1, "{st}");
    run_ok(&["verify", s(&out)]);
    for f in ["octree.bin", "hierarchy.bin", "metadata.json"] {
        assert!(
            std::fs::read(out.join(f)).ok() == std::fs::read(clean.join(f)).ok(),
            "{f} differs from the clean run"
        );
    }
}

/// Runs strata with `args` and kills it (SIGKILL) once `journal` lists a committed chunk.
fn kill_after_a_chunk(args: &[String], journal: &std::path::Path) {
    let mut child = strata().args(args).spawn().expect("spawn");
    let start = Instant::now();
    loop {
        let lines = std::fs::read_to_string(journal)
            .map(|t| t.lines().count())
            .unwrap_or(0);
        if lines >= 1 || start.elapsed() > Duration::from_secs(60) {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().expect("kill -9");
    let status = child.wait().expect("wait");
    assert!(
        !status.success(),
        "the run was meant to be interrupted before it finished"
    );
}

/// `--format potree2` killed in its export (the Strata dataset on the way whole), run again and
/// killed in its conversion: --resume refused, naming the hidden dataset as an existing
/// output, however often it was run.
#[test]
fn a_potree2_conversion_killed_twice_resumes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = dir.path().join("city.las");
    run_ok(&["synth", "--points", "1500000", "-o", s(&las)]);
    let args = |out: &std::path::Path, more: &[&str]| small_chunks(&las, out, more);
    let clean = dir.path().join("clean");
    run_ok(&strs(&args(&clean, &["--format", "potree2"])));
    let out = dir.path().join("pt");
    let hidden = dir.path().join(".pt.strata-for-potree2");
    run_ok(&strs(&args(&hidden, &[])));
    kill_after_a_chunk(
        &args(&out, &["--format", "potree2"]),
        &dir.path()
            .join(".pt.strata-for-potree2.strata-tmp/work/journal.jsonl"),
    );
    run_ok(&strs(&args(&out, &["--format", "potree2", "--resume"])));
    for f in ["octree.bin", "hierarchy.bin"] {
        assert!(
            std::fs::read(out.join(f)).ok() == std::fs::read(clean.join(f)).ok(),
            "{f} differs from the clean run"
        );
    }
    assert!(!hidden.exists());
}

/// A run killed with its work files under --temp-dir, resumed without it: it started over
/// without a word and left the work files behind; it now says where they are, and the resume
/// given the same --temp-dir continues, to the same bytes.
#[test]
fn a_resume_without_the_temp_dir_it_needs_says_where_the_work_is() {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = dir.path().join("city.las");
    run_ok(&["synth", "--points", "1500000", "-o", s(&las)]);
    let temp = dir.path().join("scratch");
    std::fs::create_dir_all(&temp).expect("dir");
    let args = |out: &std::path::Path, more: &[&str]| small_chunks(&las, out, more);
    let clean = dir.path().join("clean");
    run_ok(&strs(&args(&clean, &[])));
    let out = dir.path().join("ds");
    kill_after_a_chunk(
        &args(&out, &["--temp-dir", s(&temp)]),
        &temp.join("ds.strata-work/journal.jsonl"),
    );
    common::refused(
        &strs(&args(&out, &["--resume"])),
        &[
            "the interrupted run kept its work files in",
            "ds.strata-work",
        ],
    );
    let stats = dir.path().join("stats.json");
    run_ok(&strs(&args(
        &out,
        &["--resume", "--temp-dir", s(&temp), "--stats", s(&stats)],
    )));
    let st: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&stats).expect("stats")).expect("json");
    assert!(st["resumed_chunks"].as_u64().unwrap_or(0) >= 1, "{st}");
    assert!(
        std::fs::read(out.join("octree.bin")).ok() == std::fs::read(clean.join("octree.bin")).ok()
    );
    assert!(!temp.join("ds.strata-work").exists());
    // The note of where the work went is not left in the dataset.
    assert_eq!(std::fs::read_dir(&out).expect("dataset").count(), 3);
}

fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

/// `convert LAS -o OUT` in small chunks on one thread (many chunks, each committed on its own),
/// then `more`.
fn small_chunks(las: &std::path::Path, out: &std::path::Path, more: &[&str]) -> Vec<String> {
    let head = ["convert", s(las), "-o", s(out), "--memory-limit", "64MiB"];
    head.iter()
        .chain(&["--threads", "1", "-q"])
        .chain(more)
        .map(|a| a.to_string())
        .collect()
}
