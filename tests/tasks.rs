//! Conversion as independent tasks (`--plan-only`, `--task`, `--finish`), each step its own
//! process as a batch engine runs them: the tasks concurrently and in shuffled order, one of
//! them killed and run again, and the dataset compared byte for byte with a single run's.

mod common;

use common::{refused, run, run_ok, s, strata};
use std::path::{Path, PathBuf};
use std::process::Child;
use std::time::{Duration, Instant};

/// The options every run of a test shares: small chunks, so that there are several.
const SHAPE: [&str; 4] = ["--memory-limit", "64MiB", "--threads", "2"];

fn synth(dir: &Path, name: &str, points: &str, seed: &str) -> PathBuf {
    let path = dir.join(name);
    run_ok(&["synth", "--points", points, "--seed", seed, "-o", s(&path)]);
    path
}

fn args<'a>(head: &[&'a str], inputs: &'a [PathBuf], extra: &[&'a str]) -> Vec<&'a str> {
    let mut v: Vec<&str> = head.to_vec();
    v.extend(inputs.iter().map(|p| s(p)));
    v.extend(SHAPE);
    v.extend(extra);
    v.push("-q");
    v
}

/// Every file of dataset `a` has the same bytes in dataset `b`, and there are no others.
fn assert_same_dataset(a: &Path, b: &Path) {
    let names = |d: &Path| -> Vec<_> {
        let mut v: Vec<_> = std::fs::read_dir(d)
            .expect("dataset dir")
            .map(|e| e.expect("entry").file_name())
            .collect();
        v.sort();
        v
    };
    assert_eq!(names(a), names(b));
    for name in names(a) {
        let (x, y) = (std::fs::read(a.join(&name)), std::fs::read(b.join(&name)));
        assert!(x.expect("read") == y.expect("read"), "{name:?} differs");
    }
}

/// 0..n in an order that changes from run to run (printed, to repeat a failure).
fn shuffled(n: usize) -> Vec<usize> {
    let mut seed = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(1, |d| d.as_nanos() as u64)
        | 1;
    let mut order: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        order.swap(i, (seed % (i as u64 + 1)) as usize);
    }
    println!("task order {order:?}");
    order
}

fn spawn_task(plan: &Path, k: usize) -> Child {
    strata()
        .args(["convert", "--plan", s(plan), "--task", &k.to_string(), "-q"])
        .spawn()
        .expect("spawn task")
}

/// Runs task `k` and kills it (SIGKILL) as soon as `ready` holds (a minute at most), checking
/// that it was still running.
fn kill_task_when(plan: &Path, k: usize, ready: impl Fn() -> bool) {
    let mut child = spawn_task(plan, k);
    let start = Instant::now();
    while !ready() && start.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(1));
    }
    child.kill().expect("kill -9");
    assert!(!child.wait().expect("wait").success(), "killed before done");
}

/// The single run of `inputs` (with `extra`) into `dir/single`.
fn single_run(dir: &Path, inputs: &[PathBuf], extra: &[&str]) -> PathBuf {
    let single = dir.join("single");
    let mut tail = vec!["-o", s(&single)];
    tail.extend(extra);
    run_ok(&args(&["convert"], inputs, &tail));
    single
}

/// `--plan-only` of `inputs` (with `extra`) into `plan`, as `tasks` tasks.
fn plan_only(inputs: &[PathBuf], extra: &[&str], plan: &Path, tasks: usize) {
    let n = tasks.to_string();
    run_ok(&args(
        &["convert", "--plan-only", s(plan), "--tasks", &n],
        inputs,
        extra,
    ));
}

/// `--finish` of `plan` into `out`, which must succeed.
fn finish(plan: &Path, out: &Path) {
    run_ok(&["convert", "--plan", s(plan), "--finish", "-o", s(out), "-q"]);
}

/// Task `k` of `plan` run to success; what it printed.
fn task_says(plan: &Path, k: usize) -> String {
    let o = run_ok(&["convert", "--plan", s(plan), "--task", &k.to_string()]);
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Plans `tasks` tasks, runs them all at once in shuffled order except `skip`, and finishes
/// into `out`.
fn split_run(
    inputs: &[PathBuf],
    extra: &[&str],
    plan: &Path,
    out: &Path,
    tasks: usize,
    skip: &[usize],
) {
    plan_only(inputs, extra, plan, tasks);
    let children: Vec<(usize, Child)> = shuffled(tasks)
        .into_iter()
        .filter(|k| !skip.contains(k))
        .map(|k| (k, spawn_task(plan, k)))
        .collect();
    for (k, mut c) in children {
        assert!(c.wait().expect("wait").success(), "task {k} failed");
    }
    if skip.is_empty() {
        finish(plan, out);
    }
}

#[test]
fn tasks_in_any_order_give_the_single_runs_bytes() {
    let dir = tempfile::tempdir().expect("tempdir");
    // A LAS read in place and a LAZ decoded into the plan's staging rows.
    let inputs = [
        synth(dir.path(), "a.las", "250000", "3"),
        synth(dir.path(), "b.laz", "150000", "4"),
    ];
    let single = single_run(dir.path(), &inputs, &[]);
    let (plan, out) = (dir.path().join("plan"), dir.path().join("split"));
    // Two tasks left out: the finish names them and leaves nothing behind.
    split_run(&inputs, &[], &plan, &out, 6, &[1, 4]);
    let o = run(&["convert", "--plan", s(&plan), "--finish", "-o", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("tasks 1 and 4"), "{err}");
    assert!(err.contains(s(&plan)), "the error names the plan: {err}");
    assert_eq!(err.trim().lines().count(), 1, "one sentence: {err}");
    assert!(!out.exists() && !dir.path().join("split.strata-tmp").exists());
    for k in [4, 1] {
        assert!(spawn_task(&plan, k).wait().expect("wait").success());
    }
    // A finished task run again does nothing.
    assert!(spawn_task(&plan, 0).wait().expect("wait").success());
    finish(&plan, &out);
    run_ok(&["verify", s(&out)]);
    assert_same_dataset(&single, &out);
    assert!(!plan.exists(), "the finish removes the plan");
}

/// With normals, a chunk's halo holds points of other tasks' chunks.
#[test]
fn tasks_with_normals_give_the_single_runs_bytes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let inputs = [synth(dir.path(), "city.las", "300000", "7")];
    let single = single_run(dir.path(), &inputs, &["--normals"]);
    let (plan, out) = (dir.path().join("plan"), dir.path().join("split"));
    split_run(&inputs, &["--normals"], &plan, &out, 3, &[]);
    assert_same_dataset(&single, &out);
}

/// Chunks finish out of order with more workers than cores, and commit while other workers
/// index: the dataset is the one two workers write, where the plan is the same.
#[test]
fn any_number_of_workers_gives_the_same_bytes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = synth(dir.path(), "city.las", "600000", "11");
    let mut outs = Vec::new();
    let mut chunks = Vec::new();
    for threads in ["2", "5"] {
        let out = dir.path().join(format!("threads{threads}"));
        let stats = dir.path().join(format!("stats{threads}.json"));
        run_ok(&[
            "convert",
            s(&las),
            "-o",
            s(&out),
            "--memory-limit",
            "64MiB",
            "--threads",
            threads,
            "--normals",
            "--stats",
            s(&stats),
            "-q",
        ]);
        let text = std::fs::read_to_string(&stats).expect("stats");
        let json: serde_json::Value = serde_json::from_str(&text).expect("stats json");
        chunks.push(json["chunks"].as_u64().unwrap_or(0));
        outs.push(out);
    }
    // The same chunks (the plan divides the memory among workers, but at 64 MiB each chunk
    // is held to the floor), and several for each worker.
    assert_eq!(chunks[0], chunks[1], "the plans differ");
    assert!(chunks[0] >= 10, "{chunks:?}");
    assert_same_dataset(&outs[0], &outs[1]);
}

#[test]
fn a_killed_task_resumes_to_the_same_bytes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let inputs = [synth(dir.path(), "city.las", "1500000", "7")];
    let one = ["--memory-limit", "64MiB", "--threads", "1", "-q"];
    let single = dir.path().join("single");
    let mut a = vec!["convert", s(&inputs[0]), "-o", s(&single)];
    a.extend(one);
    run_ok(&a);
    let plan = dir.path().join("plan");
    let mut a = vec![
        "convert",
        s(&inputs[0]),
        "--plan-only",
        s(&plan),
        "--tasks",
        "2",
    ];
    a.extend(one);
    run_ok(&a);
    let journal = plan.join("tasks/0.strata-tmp/work/journal.jsonl");
    // Killed once at least one chunk has been committed.
    kill_task_when(&plan, 0, || {
        std::fs::read_to_string(&journal).map_or(0, |t| t.lines().count()) >= 1
    });
    assert!(!plan.join("tasks/0").exists());
    let text = task_says(&plan, 0);
    assert!(text.contains("resumed"), "{text}");
    run_ok(&["convert", "--plan", s(&plan), "--task", "1", "-q"]);
    let out = dir.path().join("split");
    finish(&plan, &out);
    assert_same_dataset(&single, &out);
}

/// A task stopped while distributing its share of the points leaves no share behind that a
/// later task would take for whole: the next task to come distributes it again, from the
/// start, and the tasks run one after another give the single run's bytes.
#[test]
fn a_share_cut_short_is_distributed_again() {
    let dir = tempfile::tempdir().expect("tempdir");
    let inputs = [
        synth(dir.path(), "a.las", "2000000", "5"),
        synth(dir.path(), "b.laz", "1000000", "6"),
    ];
    let single = single_run(dir.path(), &inputs, &[]);
    let plan = dir.path().join("plan");
    plan_only(&inputs, &[], &plan, 3);
    let (shares, whole) = (plan.join("shares"), plan.join("shares/1"));
    // Share 1's folder under way (named for the process writing it), once it holds files.
    let cut = || -> Option<PathBuf> {
        std::fs::read_dir(&shares).ok()?.flatten().find_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let busy = name.starts_with("1.") && name.ends_with(".strata-tmp");
            let written = std::fs::read_dir(e.path()).map_or(0, |d| d.count()) > 0;
            (busy && written).then(|| e.path())
        })
    };
    kill_task_when(&plan, 1, || cut().is_some());
    let left = cut().expect("a share cut short");
    assert!(!whole.exists(), "the share was cut short");
    // The next task distributes the three shares, the cut one again; the others find them done.
    let text = task_says(&plan, 2);
    assert!(text.contains("3 of 3 shares distributed here"), "{text}");
    for k in [0, 1] {
        let text = task_says(&plan, k);
        assert!(text.contains("0 of 3 shares distributed here"), "{text}");
    }
    assert!(!left.exists(), "the copy cut short was cleared");
    let out = dir.path().join("split");
    finish(&plan, &out);
    assert_same_dataset(&single, &out);
}

/// A finish that finds a task's result damaged refuses before it removes anything the tasks
/// need, so that running the task again, as it says, mends the plan; and a task whose chunk
/// files lost rows refuses rather than building chunks without them.
#[test]
fn damaged_work_is_refused_and_mended_as_the_message_says() {
    let dir = tempfile::tempdir().expect("tempdir");
    let inputs = [synth(dir.path(), "a.las", "300000", "8")];
    let single = single_run(dir.path(), &inputs, &[]);
    let plan = dir.path().join("plan");
    plan_only(&inputs, &[], &plan, 3);
    for k in [0, 1] {
        assert!(spawn_task(&plan, k).wait().expect("wait").success());
    }
    // One of task 2's chunk files, gone.
    let tp: serde_json::Value =
        serde_json::from_slice(&std::fs::read(plan.join("plan.json")).expect("plan"))
            .expect("json");
    let first = tp["tasks"][2]["start"].as_u64().expect("start");
    let victim = std::fs::read_dir(plan.join("shares/0"))
        .expect("share 0")
        .flatten()
        .map(|e| e.path())
        .find(|p| {
            let name = p
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            name.strip_prefix('c')
                .and_then(|r| r.split('_').next())
                .and_then(|c| c.parse::<u64>().ok())
                .is_some_and(|c| c >= first)
        })
        .expect("a chunk file of task 2");
    let kept = std::fs::read(&victim).expect("read");
    std::fs::remove_file(&victim).expect("remove");
    let o = run(&["convert", "--plan", s(&plan), "--task", "2"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("where the plan counted"),
        "{err}"
    );
    std::fs::write(&victim, kept).expect("restore");
    assert!(spawn_task(&plan, 2).wait().expect("wait").success());
    // Task 1's journal, emptied: the finish names the fix, and the fix works.
    std::fs::write(plan.join("tasks/1/work/journal.jsonl"), b"").expect("empty journal");
    let out = dir.path().join("split");
    let o = run(&["convert", "--plan", s(&plan), "--finish", "-o", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("run the task again after removing"),
        "{err}"
    );
    std::fs::remove_dir_all(plan.join("tasks/1")).expect("remove task 1");
    assert!(spawn_task(&plan, 1).wait().expect("wait").success());
    finish(&plan, &out);
    assert_same_dataset(&single, &out);
}

#[test]
fn contradictory_options_are_refused_in_one_sentence() {
    let dir = tempfile::tempdir().expect("tempdir");
    let las = synth(dir.path(), "a.las", "20000", "1");
    let plan = dir.path().join("plan");
    refused(&["convert", s(&las), "--plan-only", s(&plan)], &["--tasks"]);
    // Without --plan-only, -o is not silently made a plan; absurd counts are refused before
    // anything is allocated or written.
    let out = dir.path().join("x.strata");
    refused(
        &["convert", s(&las), "--tasks", "2", "-o", s(&out)],
        &["--plan-only"],
    );
    assert!(!out.exists());
    refused(
        &[
            "convert",
            s(&las),
            "--plan-only",
            s(&plan),
            "--tasks",
            "100000000000",
        ],
        &["--tasks"],
    );
    refused(
        &["convert", s(&las), "-o", s(&out), "--threads", "100000"],
        &["--threads"],
    );
    assert!(!out.exists() && !plan.exists());
    refused(
        &["convert", "--plan", s(&plan), "--task", "0"],
        &["no conversion plan here"],
    );
    run_ok(&[
        "convert",
        s(&las),
        "--plan-only",
        s(&plan),
        "--tasks",
        "2",
        "-q",
    ]);
    refused(
        &[
            "convert",
            "--plan",
            s(&plan),
            "--task",
            "0",
            "--threads",
            "3",
        ],
        &["--threads"],
    );
    refused(
        &["convert", "--plan", s(&plan), "--task", "0", "--normals"],
        &["--normals"],
    );
    refused(&["convert", "--plan", s(&plan)], &["--task K"]);
    refused(
        &["convert", "--plan", s(&plan), "--task", "0", "--tasks", "5"],
        &["--plan-only"],
    );
    refused(
        &["convert", "--plan", s(&plan), "--task", "2"],
        &["task 2 is not in the plan"],
    );
    refused(
        &["convert", s(&las), "--plan-only", s(&plan), "--tasks", "2"],
        &["already exists"],
    );
    // A damaged plan whose task ranges run past its chunks is refused, not a panic.
    let plan_json = plan.join("plan.json");
    let good = std::fs::read(&plan_json).expect("plan.json");
    let mut v: serde_json::Value = serde_json::from_slice(&good).expect("plan JSON");
    v["tasks"][1]["end"] = serde_json::json!(1_000_000);
    std::fs::write(&plan_json, serde_json::to_vec(&v).expect("JSON")).expect("write");
    refused(
        &["convert", "--plan", s(&plan), "--task", "1"],
        &["do not follow on from chunk"],
    );
    std::fs::write(&plan_json, &good).expect("restore");
    // An input changed since the plan: its chunks would not hold its points. Its modification
    // time put back as it was (`touch -r`) passed, and its points went into chunks that did
    // not hold them.
    let planned = std::fs::metadata(&las)
        .expect("meta")
        .modified()
        .expect("mtime");
    let f = std::fs::File::options()
        .write(true)
        .open(&las)
        .expect("open");
    for time in [
        std::time::SystemTime::now() + Duration::from_secs(10),
        planned,
    ] {
        f.set_modified(time).expect("touch");
        refused(
            &["convert", "--plan", s(&plan), "--task", "1"],
            &["a.las: changed (its size, or the time it was last written or changed) since"],
        );
    }
    assert!(!plan.join("tasks/1").exists());
}

/// A `--plan-only` killed part way left a folder no rerun could replace, with or without
/// `--overwrite` (it held no plan.json, so it was not taken for a plan): a batch engine's
/// retry failed every time. The same command now replaces it.
#[test]
fn a_plan_only_killed_part_way_is_replaced_by_its_retry() {
    let dir = tempfile::tempdir().expect("tempdir");
    let inputs = [synth(dir.path(), "a.las", "1000000", "3")];
    let plan = dir.path().join("plan");
    let cmd = args(
        &["convert", "--plan-only", s(&plan), "--tasks", "2"],
        &inputs,
        &[],
    );
    let mut child = strata().args(&cmd).spawn().expect("spawn");
    let start = Instant::now();
    while !plan.join("plan.unfinished").exists()
        && child.try_wait().ok().flatten().is_none()
        && start.elapsed() < Duration::from_secs(60)
    {
        std::thread::sleep(Duration::from_millis(1));
    }
    child.kill().expect("kill -9");
    let _ = child.wait();
    if !plan.join("plan.json").exists() {
        assert!(plan.join("plan.unfinished").exists());
    }
    run_ok(&cmd);
    assert!(plan.join("plan.json").is_file() && !plan.join("plan.unfinished").exists());
    // A folder of anything else is still refused, --overwrite or not.
    let other = dir.path().join("other");
    std::fs::create_dir_all(other.join("staging")).expect("dir");
    std::fs::write(other.join("notes.txt"), b"mine").expect("write");
    refused(
        &args(
            &["convert", "--plan-only", s(&other), "--tasks", "2"],
            &inputs,
            &["--overwrite"],
        ),
        &["notes.txt"],
    );
}
