//! The Slurm scripts we ship, run under a real Slurm: a one-node cluster (munged, slurmctld,
//! slurmd from Debian's `slurm-wlm` and `munge`) started in a temporary folder, the conversion
//! submitted with `deploy/slurm/submit.sh`, and its dataset compared byte for byte with a
//! single run's. Skipped, with the reason, where Slurm is not installed or cannot start.

mod common;

use common::{run_ok, s};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The daemons, stopped when the test ends however it ends.
struct Cluster {
    daemons: Vec<Child>,
    dir: PathBuf,
    conf: PathBuf,
}

impl Drop for Cluster {
    fn drop(&mut self) {
        for d in &mut self.daemons {
            let _ = d.kill();
            let _ = d.wait();
        }
    }
}

impl Cluster {
    fn logs(&self) -> String {
        let mut out = String::new();
        for name in ["munged.log", "slurmctld.log", "slurmd.log"] {
            let text = std::fs::read_to_string(self.dir.join(name)).unwrap_or_default();
            let tail: Vec<&str> = text.lines().rev().take(15).collect();
            out.push_str(&format!("--- {name}\n"));
            for l in tail.into_iter().rev() {
                out.push_str(l);
                out.push('\n');
            }
        }
        out
    }

    fn command(&self, program: &str) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", &self.conf);
        c
    }
}

fn found(program: &str) -> bool {
    std::env::var_os("PATH").is_some_and(|paths| {
        std::env::split_paths(&paths)
            .chain([PathBuf::from("/usr/sbin"), PathBuf::from("/sbin")])
            .any(|d| d.join(program).is_file())
    })
}

fn daemon(program: &str, args: &[&str], conf: &Path) -> Result<Child, String> {
    Command::new(program)
        .args(args)
        .env("SLURM_CONF", conf)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| format!("cannot start {program}: {e}"))
}

/// Two consecutive ports nothing listens on, for slurmctld and slurmd: ports of our own, so
/// that a Slurm already on the machine is left alone. They are taken below the kernel's
/// ephemeral range (32768 and up), where the client sockets of earlier tests (the server's
/// soak test opens hundreds) cannot hold them; `dir` varies the start between attempts.
fn free_port_pair(dir: &Path) -> Result<u16, String> {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    (std::process::id(), dir).hash(&mut h);
    let start = 10_000 + (h.finish() % 20_000) as u16;
    let free = |p: u16| std::net::TcpListener::bind(("0.0.0.0", p)).is_ok();
    (0..2_000u16)
        .map(|i| 10_000 + (start - 10_000 + 2 * i) % 20_000)
        .find(|&p| free(p) && free(p + 1))
        .ok_or_else(|| "no two free ports between 10000 and 30000".into())
}

/// A one-node cluster, or why there cannot be one here. A port taken between our check and
/// the daemon's bind is a race, not a missing Slurm: that alone is retried, on other ports.
fn start_cluster(dir: &Path) -> Result<Cluster, String> {
    let mut last = String::new();
    for attempt in 0..3 {
        match start_cluster_once(&dir.join(format!("try{attempt}"))) {
            Err(why) if why.contains("Address already in use") => last = why,
            other => return other,
        }
    }
    Err(last)
}

/// A one-node cluster in `dir`, or why there cannot be one here.
fn start_cluster_once(dir: &Path) -> Result<Cluster, String> {
    let missing: Vec<&str> = [
        "sbatch",
        "squeue",
        "sinfo",
        "slurmctld",
        "slurmd",
        "munged",
        "mungekey",
    ]
    .into_iter()
    .filter(|p| !found(p))
    .collect();
    if !missing.is_empty() {
        return Err(format!(
            "{} not installed (Debian packages slurm-wlm and munge)",
            missing.join(", ")
        ));
    }
    // slurmd starts jobs as their user; a one-node cluster of our own needs root for it.
    let uid = Command::new("id")
        .arg("-u")
        .output()
        .map_err(|e| e.to_string())?;
    if String::from_utf8_lossy(&uid.stdout).trim() != "0" {
        return Err("slurmd needs to run as root".into());
    }
    let host = Command::new("hostname")
        .arg("-s")
        .output()
        .map_err(|e| e.to_string())?;
    let host = String::from_utf8_lossy(&host.stdout).trim().to_string();
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    // munged wants its run folder even when its socket is elsewhere.
    let _ = std::fs::create_dir_all("/run/munge");
    let key = dir.join("munge.key");
    let made = Command::new("mungekey")
        .args(["-c", "-f", "-k", s(&key)])
        .status()
        .map_err(|e| format!("cannot run mungekey: {e}"))?;
    if !made.success() {
        return Err("mungekey could not make a key".into());
    }
    let sock = dir.join("munge.sock");
    let conf = dir.join("slurm.conf");
    let port = free_port_pair(dir)?;
    let d = |name: &str| dir.join(name).display().to_string();
    std::fs::create_dir_all(dir.join("state")).map_err(|e| e.to_string())?;
    std::fs::create_dir_all(dir.join("spool")).map_err(|e| e.to_string())?;
    let text = format!(
        "ClusterName=strata\nSlurmctldHost={host}\nSlurmUser=root\nSlurmdUser=root\n\
         AuthType=auth/munge\nCredType=cred/munge\nAuthInfo=socket={sock}\n\
         SlurmctldPort={port}\nSlurmdPort={}\nStateSaveLocation={}\nSlurmdSpoolDir={}\n\
         SlurmctldPidFile={}\nSlurmdPidFile={}\nSlurmctldLogFile={}\nSlurmdLogFile={}\n\
         ProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\n\
         SelectType=select/cons_tres\nSelectTypeParameters=CR_Core\n\
         JobAcctGatherType=jobacct_gather/none\nAccountingStorageType=accounting_storage/none\n\
         JobCompType=jobcomp/none\nMpiDefault=none\nReturnToService=2\n\
         NodeName={host} CPUs={cpus} State=UNKNOWN\n\
         PartitionName=main Nodes=ALL Default=YES MaxTime=INFINITE State=UP\n",
        port + 1,
        d("state"),
        d("spool"),
        d("slurmctld.pid"),
        d("slurmd.pid"),
        d("slurmctld.log"),
        d("slurmd.log"),
        sock = sock.display(),
    );
    std::fs::write(&conf, text).map_err(|e| e.to_string())?;
    let mut cluster = Cluster {
        daemons: Vec::new(),
        dir: dir.to_path_buf(),
        conf: conf.clone(),
    };
    let munge_args = [
        "-F".to_string(),
        "-f".into(),
        format!("--socket={}", sock.display()),
        format!("--key-file={}", key.display()),
        format!("--log-file={}", d("munged.log")),
        format!("--pid-file={}", d("munged.pid")),
        format!("--seed-file={}", d("munged.seed")),
    ];
    let munge_args: Vec<&str> = munge_args.iter().map(String::as_str).collect();
    cluster.daemons.push(daemon("munged", &munge_args, &conf)?);
    let start = Instant::now();
    while !sock.exists() {
        if start.elapsed() > Duration::from_secs(10) {
            return Err(format!("munged did not start:\n{}", cluster.logs()));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    cluster
        .daemons
        .push(daemon("slurmctld", &["-D", "-i", "-f", s(&conf)], &conf)?);
    cluster
        .daemons
        .push(daemon("slurmd", &["-D", "-f", s(&conf)], &conf)?);
    // Up once the node reports idle.
    let start = Instant::now();
    loop {
        let o = cluster.command("sinfo").args(["-h", "-o", "%T"]).output();
        if o.is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "idle") {
            return Ok(cluster);
        }
        if start.elapsed() > Duration::from_secs(30) {
            return Err(format!("the node did not come up:\n{}", cluster.logs()));
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

#[test]
fn the_shipped_slurm_script_converts_to_the_single_runs_bytes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cluster = match start_cluster(&dir.path().join("slurm")) {
        Ok(c) => c,
        Err(why) => {
            if std::env::var_os("STRATA_REQUIRE_SLURM").is_some() {
                panic!("STRATA_REQUIRE_SLURM is set but Slurm cannot start: {why}");
            }
            eprintln!("skipped: no one-node Slurm cluster here: {why}");
            return;
        }
    };
    let las = dir.path().join("city.las");
    run_ok(&["synth", "--points", "300000", "-o", s(&las)]);
    let opts = ["--memory-limit", "64MiB", "--threads", "2"];
    let single = dir.path().join("single");
    let mut a = vec!["convert", s(&las), "-o", s(&single), "-q"];
    a.extend(opts);
    run_ok(&a);

    let (plan, out) = (dir.path().join("plan"), dir.path().join("slurm.strata"));
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("deploy/slurm/submit.sh");
    let o = cluster
        .command("bash")
        .arg(&script)
        .args([s(&plan), s(&out), "3", s(&las)])
        .env("STRATA", env!("CARGO_BIN_EXE_strata"))
        .env("STRATA_OPTS", opts.join(" "))
        .env("LOG_DIR", dir.path())
        .current_dir(dir.path())
        .output()
        .expect("run submit.sh");
    assert!(
        o.status.success(),
        "submit.sh failed: {}\n{}",
        String::from_utf8_lossy(&o.stderr),
        cluster.logs()
    );
    let ids = String::from_utf8_lossy(&o.stdout).trim().to_string();
    assert_eq!(ids.split_whitespace().count(), 3, "three jobs: {ids}");
    // Done once no job of ours is left in the queue.
    let start = Instant::now();
    loop {
        let q = cluster
            .command("squeue")
            .args(["-h", "-o", "%i %T %r"])
            .output()
            .expect("squeue");
        let queue = String::from_utf8_lossy(&q.stdout).trim().to_string();
        if queue.is_empty() {
            break;
        }
        // A dependency that can never be met means an earlier step failed.
        assert!(
            !queue.contains("DependencyNeverSatisfied")
                && start.elapsed() < Duration::from_secs(300),
            "jobs stuck: {queue}\n{}\n{}",
            job_outputs(dir.path()),
            cluster.logs()
        );
        std::thread::sleep(Duration::from_millis(500));
    }
    assert!(
        out.join("metadata.json").is_file(),
        "no dataset after the jobs:\n{}\n{}",
        job_outputs(dir.path()),
        cluster.logs()
    );
    for f in ["octree.bin", "hierarchy.bin", "metadata.json"] {
        assert!(
            std::fs::read(out.join(f)).ok() == std::fs::read(single.join(f)).ok(),
            "{f} differs from the single run"
        );
    }
    // Every task ran as an element of the array.
    let tasks = std::fs::read_dir(dir.path())
        .expect("dir")
        .filter(|e| {
            e.as_ref()
                .is_ok_and(|e| e.file_name().to_string_lossy().starts_with("strata-task-"))
        })
        .count();
    assert_eq!(tasks, 3, "{}", job_outputs(dir.path()));
}

/// What the jobs printed, for a failure's message.
fn job_outputs(dir: &Path) -> String {
    let mut out = String::new();
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries.flatten() {
            let name = e.file_name().to_string_lossy().to_string();
            if name.starts_with("strata-") && name.ends_with(".out") {
                out.push_str(&format!(
                    "--- {name}\n{}",
                    std::fs::read_to_string(e.path()).unwrap_or_default()
                ));
            }
        }
    }
    out
}
