//! Sequential round trips over HTTP, counted by a static server that answers in rounds: it
//! holds requests until none has arrived for a moment, then answers them all, so a client's
//! rounds are its sequential round trips. Opening a dataset takes one; the viewer descending to
//! a deep node takes one per level, with no extra round for the pages below proxies (format
//! 1.1), where a 1.0 dataset costs one more per page.

mod common;
use common::*;
use glam::Vec3;
use std::collections::{HashMap, HashSet};
use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};
use strata_format::LocalDataset;
use strata_viewer::camera::Camera;
use strata_viewer::loader::{Done, Job, Loader};
use strata_viewer::lod::{ClipRegion, SelectionParams, Tree, select};
use strata_viewer::{HttpOptions, StreamDataset};

/// One request: its round, the file, the first byte asked for (0 for a whole file).
type Logged = (u32, String, u64);

#[derive(Default)]
struct Gate {
    pending: Vec<u64>,
    released: HashMap<u64, u32>,
    next: u64,
    last: Option<Instant>,
    round: u32,
    log: Vec<Logged>,
}

struct RoundServer {
    addr: String,
    gate: Arc<(Mutex<Gate>, Condvar)>,
}

impl RoundServer {
    /// Serves the files under `root`; a round ends 100 ms after its last request.
    fn start(root: &Path) -> RoundServer {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        let addr = listener.local_addr().expect("addr").to_string();
        let gate = Arc::new((Mutex::new(Gate::default()), Condvar::new()));
        let g = gate.clone();
        std::thread::spawn(move || {
            loop {
                std::thread::sleep(Duration::from_millis(5));
                let (lock, cv) = &*g;
                let mut s = lock.lock().unwrap_or_else(|e| e.into_inner());
                if !s.pending.is_empty() && s.last.is_some_and(|t| t.elapsed().as_millis() > 100) {
                    s.round += 1;
                    let round = s.round;
                    for id in std::mem::take(&mut s.pending) {
                        s.released.insert(id, round);
                    }
                    cv.notify_all();
                }
            }
        });
        let (g, root) = (gate.clone(), root.to_path_buf());
        std::thread::spawn(move || {
            for stream in listener.incoming().flatten() {
                let (g, root) = (g.clone(), root.clone());
                std::thread::spawn(move || serve(stream, &root, &g));
            }
        });
        RoundServer { addr, gate }
    }

    fn log(&self) -> Vec<Logged> {
        let s = self.gate.0.lock().unwrap_or_else(|e| e.into_inner());
        let mut log = s.log.clone();
        log.sort();
        log
    }
}

/// Answers requests on one connection (HTTP/1.1, kept alive) once their round is released.
fn serve(stream: TcpStream, root: &Path, gate: &(Mutex<Gate>, Condvar)) {
    let mut reader = BufReader::new(stream.try_clone().expect("clone"));
    let mut out = stream;
    loop {
        let mut head = Vec::new();
        loop {
            let mut line = String::new();
            if reader.read_line(&mut line).unwrap_or(0) == 0 {
                return;
            }
            if line == "\r\n" {
                break;
            }
            head.push(line);
        }
        let path = head[0].split(' ').nth(1).unwrap_or("/").to_string();
        let range = head.iter().find_map(|l| {
            let (k, v) = l.split_once(':')?;
            let (a, b) = k
                .eq_ignore_ascii_case("range")
                .then_some(v.trim())?
                .strip_prefix("bytes=")?
                .split_once('-')?;
            Some((a.parse::<u64>().ok()?, b.parse::<u64>().ok()?))
        });
        let (lock, cv) = gate;
        let mut s = lock.lock().unwrap_or_else(|e| e.into_inner());
        let id = s.next;
        s.next += 1;
        s.pending.push(id);
        s.last = Some(Instant::now());
        let mut s = cv
            .wait_while(s, |s| !s.released.contains_key(&id))
            .unwrap_or_else(|e| e.into_inner());
        let round = s.released[&id];
        let file = path.rsplit('/').next().unwrap_or("").to_string();
        s.log.push((round, file, range.map_or(0, |r| r.0)));
        drop(s);
        let data = std::fs::read(root.join(path.trim_start_matches('/'))).unwrap_or_default();
        let n = data.len() as u64;
        let (status, body, extra) = match range {
            Some((a, b)) if a < n => {
                let b = b.min(n - 1);
                let cr = format!("Content-Range: bytes {a}-{b}/{n}\r\n");
                ("206 Partial Content", &data[a as usize..=b as usize], cr)
            }
            _ => ("200 OK", &data[..], String::new()),
        };
        let reply = format!(
            "HTTP/1.1 {status}\r\nContent-Length: {}\r\n{extra}\r\n",
            body.len()
        );
        if out.write_all(reply.as_bytes()).is_err() || out.write_all(body).is_err() {
            return;
        }
    }
}

fn scratch(name: &str) -> PathBuf {
    common::fresh_dir(&format!("rounds/{name}"))
}

#[test]
fn opening_over_http_takes_one_round_trip_before_the_root_node() {
    let root = scratch("open");
    let src = deep_dataset("rounds");
    std::os::unix::fs::symlink(&src, root.join("deep")).expect("link");
    let server = RoundServer::start(&root);
    let url = format!("http://{}/deep", server.addr);
    let ds = StreamDataset::open(&url, HttpOptions::default()).expect("opens");
    let log = server.log();
    let first: Vec<&str> = log
        .iter()
        .filter(|r| r.0 == 1)
        .map(|r| r.1.as_str())
        .collect();
    assert_eq!(
        first,
        ["hierarchy.bin", "metadata.json", "octree.bin"],
        "{log:?}"
    );
    // The root node (for the colours) is all that follows, and the viewer reuses it.
    assert_eq!(log.len(), 4, "{log:?}");
    assert_eq!(log[3].0, 2);
    let root = ds.root_hierarchy_page().root_node().expect("root node");
    ds.load_node(
        &root,
        strata_viewer::dataset::ColourWord::Stored,
        &Default::default(),
    )
    .expect("root node");
    assert_eq!(server.log().len(), 4, "the root node is not fetched twice");
}

/// Drives the viewer's selection and loader towards the deep cluster until nothing is missing;
/// returns, per level, the round in which its first node was asked for, and the log.
fn descend(dataset: &Path, prefix_from: &Path) -> (Vec<u32>, Vec<Logged>) {
    let root = scratch(&format!(
        "descend-{}",
        dataset.file_name().and_then(|n| n.to_str()).unwrap_or("x")
    ));
    std::os::unix::fs::symlink(dataset, root.join("ds")).expect("link");
    let server = RoundServer::start(&root);
    // Only the head and the root page come at open, as in a dataset too large for the prefix.
    let local = LocalDataset::open(prefix_from).expect("opens");
    let m = local.metadata();
    let opts = HttpOptions {
        concurrency: 64,
        hierarchy_prefix: m.hierarchy.root_page_offset + m.hierarchy.root_page_size,
        ..HttpOptions::default()
    };
    let ds =
        Arc::new(StreamDataset::open(&format!("http://{}/ds", server.addr), opts).expect("opens"));
    let mut tree = Tree::of(&ds).expect("a sound hierarchy");
    let loader = Loader::new(ds.clone(), 64);
    let anchor = ds.anchor();
    let centre = (glam::DVec3::from_array(DEEP_CENTRE) - anchor).as_vec3();
    let camera = Camera {
        eye: centre + Vec3::splat(2e-4),
        target: centre,
        fov_y: 60f32.to_radians(),
    };
    let clip = ClipRegion {
        keep: vec![(centre - Vec3::splat(1e-5), centre + Vec3::splat(1e-5))],
        hide: Vec::new(),
    };
    let params = SelectionParams {
        budget: 50_000_000,
        width: 256,
        height: 256,
        min_spacing_px: 1.0,
    };
    let mut resident = HashSet::new();
    let none = HashSet::new();
    loop {
        let sel = select(
            &tree,
            &ds,
            &camera,
            &params,
            |k| resident.contains(&k),
            &none,
            &clip,
        );
        if sel.missing_nodes.is_empty() && sel.missing_pages.is_empty() {
            break;
        }
        let mut jobs: Vec<(f32, Job)> = sel
            .missing_pages
            .iter()
            .map(|(p, pr)| (*pr, Job::Page(*p)))
            .collect();
        jobs.extend(sel.missing_nodes.iter().map(|(n, pr)| (*pr, Job::Node(*n))));
        jobs.sort_by(|a, b| b.0.total_cmp(&a.0));
        loader.set_wanted(jobs.into_iter().map(|(_, j)| j));
        let first = loader
            .wait_finished(Duration::from_secs(20))
            .expect("progress");
        for done in std::iter::once(first).chain(loader.finished().collect::<Vec<_>>()) {
            match done {
                Done::Node(n) => {
                    resident.insert(n.key);
                }
                Done::Page(p) => tree.add_page(&p).expect("a sound hierarchy"),
                Done::NodeFailed(k, e) | Done::PageFailed(k, e) => panic!("{k}: {e}"),
            }
        }
    }
    let log = server.log();
    let nodes = LocalDataset::open(dataset)
        .expect("opens")
        .all_nodes()
        .expect("nodes");
    let level_at: HashMap<u64, u8> = nodes
        .iter()
        .filter(|n| n.size > 0)
        .map(|n| (n.offset, n.key.level))
        .collect();
    let mut first_round: Vec<u32> = Vec::new();
    for (round, file, at) in &log {
        if let (true, Some(&level)) = (file == "octree.bin", level_at.get(at)) {
            let level = level as usize;
            if first_round.len() <= level {
                first_round.resize(level + 1, u32::MAX);
            }
            first_round[level] = first_round[level].min(*round);
        }
    }
    (first_round, log)
}

#[test]
fn descending_through_proxies_costs_no_round_for_their_pages() {
    let deep = deep_dataset("rounds");
    let old = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("rounds")
        .join("deep-1.0");
    let _ = std::fs::remove_dir_all(&old);
    strata_format::v1_0::rewrite_as_1_0(&deep, &old).expect("rewrites");
    let (new, new_log) = descend(&deep, &deep);
    let (was, was_log) = descend(&old, &old);
    eprintln!("round of the first node asked for at each level: 1.1 {new:?}, 1.0 {was:?}");
    let deepest = new.len() - 1;
    assert!(deepest >= 9, "the descent went through two pages: {new:?}");
    assert_eq!(was.len(), new.len(), "both reach the same level");
    // Each level one round after its parent (levels whose nodes have no points ask nothing):
    // the root node in round 2, after the round that opened the dataset.
    for (level, &round) in new.iter().enumerate() {
        assert!(
            round == u32::MAX || round <= level as u32 + 2,
            "1.1 level {level} in round {round}: {new_log:?}"
        );
    }
    assert!(
        was[deepest] > new[deepest],
        "1.0 pays a round per page: {was:?} vs {new:?}\n{was_log:?}"
    );
}
