//! A plan folder is files on shared storage that anyone may edit or a disk may damage: a
//! changed plan.json, task payload or chunk root is refused in one sentence naming the file,
//! with a non-zero exit, no panic or abort, and no dataset left behind.

mod common;

use common::{refused, run_ok, s};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// A plan of two tasks over 300,000 points in small chunks (several a task).
fn plan(dir: &Path) -> PathBuf {
    let las = dir.join("a.las");
    run_ok(&["synth", "--points", "300000", "--seed", "5", "-o", s(&las)]);
    let plan = dir.join("plan");
    run_ok(&[
        "convert",
        s(&las),
        "--plan-only",
        s(&plan),
        "--tasks",
        "2",
        "--memory-limit",
        "64MiB",
        "--threads",
        "2",
        "-q",
    ]);
    plan
}

fn task(plan: &Path, k: usize) {
    run_ok(&["convert", "--plan", s(plan), "--task", &k.to_string(), "-q"]);
}

/// A plan whose two tasks have both run.
fn plan_run(dir: &Path) -> PathBuf {
    let plan = plan(dir);
    task(&plan, 0);
    task(&plan, 1);
    plan
}

/// `--finish` must fail naming `expect`, and leave neither the dataset nor its work folder.
fn finish_fails(plan: &Path, expect: &[&str]) {
    let out = plan.with_file_name("out.strata");
    refused(
        &["convert", "--plan", s(plan), "--finish", "-o", s(&out)],
        expect,
    );
    assert!(!out.exists(), "no dataset");
    assert!(
        !plan.with_file_name("out.strata.strata-tmp").exists(),
        "no half-written dataset"
    );
}

/// `--finish` of `plan` into `out`, which must succeed and verify.
fn finish_verified(plan: &Path, out: &Path) {
    run_ok(&["convert", "--plan", s(plan), "--finish", "-o", s(out), "-q"]);
    run_ok(&["verify", s(out)]);
}

/// Flips a few bits in the middle of `path`, past its first `skip` bytes.
fn flip(path: &Path, skip: usize) {
    let mut b = std::fs::read(path).expect("read");
    assert!(b.len() > skip + 8, "{} is too short", path.display());
    let at = skip + (b.len() - skip) / 2;
    for (i, m) in [0x01u8, 0x20, 0x80].into_iter().enumerate() {
        b[at + i] ^= m;
    }
    std::fs::write(path, b).expect("write");
}

/// An edit of plan.json.
type Edit = Box<dyn Fn(&mut Value)>;

#[test]
fn an_edited_plan_is_refused_naming_plan_json_and_the_field() {
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = plan(dir.path());
    let plan_json = plan.join("plan.json");
    let good = std::fs::read(&plan_json).expect("plan.json");
    let original: Value = serde_json::from_slice(&good).expect("JSON");
    let total = original["plan"]["points"].as_u64().expect("points");
    let edited = |edit: &dyn Fn(&mut Value)| {
        let mut v = original.clone();
        edit(&mut v);
        std::fs::write(&plan_json, serde_json::to_vec(&v).expect("JSON")).expect("write");
    };
    let not_the_plans = format!("not the plan's {total}");
    let cases: Vec<(Edit, Vec<&str>)> = vec![
        // Was a panic: the counting grid's table indexed past its end.
        (
            Box::new(|v| v["plan"]["chunks"][0]["level"] = json!(200)),
            vec!["chunk 0's level 200 is deeper than the counting grid's"],
        ),
        (
            Box::new(|v| v["plan"]["chunks"][0]["x"] = json!(4_000_000_000u64)),
            vec!["chunk 0's x 4000000000 lies outside its level"],
        ),
        (
            Box::new(|v| v["plan"]["chunks"][1] = v["plan"]["chunks"][0].clone()),
            vec!["chunk 1's cells overlap chunk 0's"],
        ),
        (
            Box::new(|v| v["plan"]["chunks"][0]["points"] = json!(1_000_000_000_000_000u64)),
            vec!["add up to", &not_the_plans],
        ),
        (
            Box::new(|v| v["plan"]["cube"]["bits"] = json!(99)),
            vec!["cube.bits is 99, outside 1 to 32"],
        ),
        (
            Box::new(|v| v["threads"] = json!(1u64 << 40)),
            vec!["\"threads\" is 1099511627776"],
        ),
        // An option that shapes the dataset: was blamed on another version of strata.
        (
            Box::new(|v| v["memory_limit"] = json!(v["memory_limit"].as_u64().expect("limit") / 2)),
            vec!["the plan was edited"],
        ),
        // Attributes cut short, of no size, or of another type: two panics, and rows read as
        // another type without a word.
        (
            Box::new(|v| v["plan"]["attributes"] = json!([v["plan"]["attributes"][0].clone()])),
            vec!["its \"attributes\" are not those its inputs"],
        ),
        (
            Box::new(|v| v["plan"]["attributes"][0]["count"] = json!(0)),
            vec!["its \"attributes\" are not those its inputs"],
        ),
        (
            Box::new(|v| v["plan"]["attributes"][0]["type"] = json!("i16")),
            vec!["its \"attributes\" are not those its inputs"],
        ),
    ];
    for (edit, expect) in &cases {
        edited(edit.as_ref());
        let mut want = vec!["plan.json"];
        want.extend(expect);
        refused(&["convert", "--plan", s(&plan), "--task", "0"], &want);
        assert!(!plan.join("tasks/0").exists(), "{expect:?}: no task result");
    }
    // Points that add up, but more than memory holds: was an abort allocating them.
    edited(&|v| {
        let first = v["plan"]["chunks"][0]["points"].as_u64().expect("points");
        let more = 1_000_000_000_000_000u64;
        v["plan"]["chunks"][0]["points"] = json!(first + more);
        v["plan"]["points"] = json!(total + more);
    });
    refused(
        &["convert", "--plan", s(&plan), "--task", "0"],
        &["plan.json", "chunk 0's 1000000000", "do not fit in memory"],
    );
    assert!(!plan.join("tasks/0").exists());
    // The finish refuses the plan too, whatever its tasks did: the dataset would be invalid.
    std::fs::write(&plan_json, &good).expect("restore");
    task(&plan, 0);
    task(&plan, 1);
    edited(&|v| v["plan"]["cube"]["bits"] = json!(99));
    finish_fails(&plan, &["plan.json", "cube.bits is 99"]);
}

/// Bits flipped in a task's nodes after it ran: was a dataset `strata verify` rejects.
#[test]
fn a_damaged_task_payload_stops_the_finish() {
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = plan_run(dir.path());
    // Past the file head: in a node's payload.
    flip(&plan.join("tasks/0/octree.bin"), 64);
    finish_fails(
        &plan,
        &[
            "tasks/0/octree.bin",
            "does not match the checksum task 0's journal records",
        ],
    );
}

/// Bits flipped in a chunk's root rows after the task ran: was a dataset that verifies but
/// holds other points.
#[test]
fn a_damaged_chunk_root_stops_the_finish() {
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = plan_run(dir.path());
    // One bit of its last byte: lz4 ends a block with literal bytes, so it decodes into other
    // rows without a fault (this very flip passed into the dataset before blocks had
    // checksums).
    let root = plan.join("tasks/0/work/roots/c0.bin");
    let mut b = std::fs::read(&root).expect("read");
    if let Some(last) = b.last_mut() {
        *last ^= 0x01;
    }
    std::fs::write(&root, b).expect("write");
    finish_fails(
        &plan,
        &["tasks/0/work/roots/c0.bin", "does not match its checksum"],
    );
}

/// A task's chunk roots deleted after it ran: the finish said "internal error", then named
/// the loss only once it had removed what running the task again needs. It is found first,
/// and what the message says to do finishes the dataset.
#[test]
fn a_task_whose_work_was_removed_stops_the_finish_before_it_is_too_late() {
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = plan_run(dir.path());
    std::fs::remove_dir_all(plan.join("tasks/0/work/roots")).expect("remove");
    finish_fails(
        &plan,
        &[
            "is missing: task 0's work files are damaged",
            "--task 0 again",
        ],
    );
    std::fs::remove_dir_all(plan.join("tasks/0")).expect("remove");
    task(&plan, 0);
    finish_verified(&plan, &dir.path().join("out.strata"));
}

/// A finish into the plan folder removed the dataset with the plan; two finishes of one plan
/// at once cleared each other's work and one said it had succeeded; a --stats file wrote over
/// the plan. Each is refused before any work, and the plan is left to finish.
#[test]
fn a_finish_that_would_destroy_its_own_work_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = plan_run(dir.path());
    let plan_json = std::fs::read(plan.join("plan.json")).expect("read");
    refused(
        &[
            "convert",
            "--plan",
            s(&plan),
            "--finish",
            "-o",
            s(&plan.join("mine")),
        ],
        &["lies inside the plan folder"],
    );
    refused(
        &[
            "convert",
            "--plan",
            s(&plan),
            "--task",
            "0",
            "--stats",
            s(&plan.join("plan.json")),
        ],
        &["plan.json: the --stats file would be written over the plan folder"],
    );
    // Another process finishing: it holds the plan folder's lock.
    let held = std::fs::File::open(&plan).expect("open");
    held.try_lock().expect("lock");
    finish_fails(&plan, &["is being finished by another process"]);
    drop(held);
    assert_eq!(
        std::fs::read(plan.join("plan.json")).expect("read"),
        plan_json
    );
    finish_verified(&plan, &dir.path().join("out.strata"));
    assert!(!plan.exists());
    // Run again, as a batch engine retries a finish it saw stopped while removing the plan:
    // the dataset is named, and with none, the plan's absence.
    let again = |out: &str, expect: &[&str]| {
        let out = dir.path().join(out);
        refused(
            &["convert", "--plan", s(&plan), "--finish", "-o", s(&out)],
            expect,
        );
    };
    again("out.strata", &["holds a dataset", "strata verify"]);
    again("other.strata", &["no conversion plan here"]);
}

/// A share's class counts edited after it ran: the finish said ok and the dataset stated
/// classes its points do not have.
#[test]
fn class_counts_that_do_not_add_up_stop_the_finish() {
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = plan_run(dir.path());
    let counts = plan.join("shares/0/counts.json");
    let mut v: Value =
        serde_json::from_slice(&std::fs::read(&counts).expect("read")).expect("JSON");
    let first = v["classes"][0].as_u64().expect("count");
    v["classes"][0] = json!(first + 7);
    std::fs::write(&counts, serde_json::to_vec(&v).expect("JSON")).expect("write");
    finish_fails(&plan, &["class counts add up to", "not the plan's 300000"]);
}

#[test]
fn a_plan_copied_without_its_empty_tasks_folder_says_so() {
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = plan(dir.path());
    std::fs::remove_dir(plan.join("tasks")).expect("the plan's tasks folder is empty");
    refused(
        &["convert", "--plan", s(&plan), "--task", "0", "-q"],
        &[
            "tasks",
            "the plan has no tasks folder",
            "empty folders included",
        ],
    );
}
