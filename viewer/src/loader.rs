//! Loader threads: fetch, verify, decompress and convert nodes and hierarchy pages off the render
//! thread. The render thread replaces the wanted list every frame; what the camera has left
//! behind is dropped before a thread takes it.

use crate::ViewerError;
use crate::dataset::{ColourWord, GpuNode, StreamDataset};
use crate::marks::Marks;
use crossbeam_channel::{Receiver, Sender, unbounded};
use std::collections::HashSet;
use std::panic::AssertUnwindSafe;
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::thread::JoinHandle;
use strata_format::{HierarchyPage, NodeInfo, NodeKey, PageRef};

#[derive(Debug, Clone, Copy)]
pub enum Job {
    Node(NodeInfo),
    Page(PageRef),
}

/// Identifies a job independently of its payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum JobKey {
    Node(NodeKey),
    Page(NodeKey),
}

impl Job {
    pub fn key(&self) -> JobKey {
        match self {
            Job::Node(n) => JobKey::Node(n.key),
            Job::Page(p) => JobKey::Page(p.root),
        }
    }
}

pub enum Done {
    Node(GpuNode),
    NodeFailed(NodeKey, ViewerError),
    Page(HierarchyPage),
    PageFailed(NodeKey, ViewerError),
}

#[derive(Default)]
struct Queue {
    /// Lowest priority first, so `pop` takes the most important.
    pending: Vec<Job>,
    in_flight: HashSet<JobKey>,
    shutdown: bool,
}

struct Shared {
    queue: Mutex<Queue>,
    wake: Condvar,
    /// What nodes are loaded with: their colour word (normals as colours, or the stored
    /// ones) and the attribute ranges their points are marked by.
    form: Mutex<(ColourWord, Marks)>,
}

pub struct Loader {
    shared: Arc<Shared>,
    results: Receiver<Done>,
    threads: Vec<JoinHandle<()>>,
}

impl Loader {
    pub fn new(dataset: Arc<StreamDataset>, threads: usize) -> Loader {
        let shared = Arc::new(Shared {
            queue: Mutex::new(Queue::default()),
            wake: Condvar::new(),
            form: Mutex::new((ColourWord::Stored, Marks::default())),
        });
        let (tx, rx) = unbounded();
        let threads = (0..threads.max(1))
            .map(|_| {
                let shared = shared.clone();
                let tx = tx.clone();
                let ds = dataset.clone();
                std::thread::spawn(move || worker(&shared, &ds, &tx))
            })
            .collect();
        Loader {
            shared,
            results: rx,
            threads,
        }
    }

    /// Replaces the wanted jobs (most important first). Jobs already in flight are not
    /// repeated; jobs no longer wanted are dropped unless a thread has taken them.
    pub fn set_wanted(&self, jobs: impl IntoIterator<Item = Job>) {
        let mut q = self
            .shared
            .queue
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let mut pending: Vec<Job> = jobs
            .into_iter()
            .filter(|j| !q.in_flight.contains(&j.key()))
            .collect();
        pending.reverse();
        q.pending = pending;
        drop(q);
        self.shared.wake.notify_all();
    }

    /// What nodes loaded from now on hold: the colour word and the marked ranges; nodes
    /// already in flight keep what they were started with (`GpuNode::colours`, `marks`).
    pub fn set_form(&self, colours: ColourWord, marks: Marks) {
        *self
            .shared
            .form
            .lock()
            .unwrap_or_else(PoisonError::into_inner) = (colours, marks);
    }

    pub fn form(&self) -> (ColourWord, Marks) {
        form(&self.shared)
    }

    pub fn is_busy(&self, key: JobKey) -> bool {
        let q = self
            .shared
            .queue
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        q.in_flight.contains(&key) || q.pending.iter().any(|j| j.key() == key)
    }

    /// Jobs queued and in flight.
    pub fn counts(&self) -> (usize, usize) {
        let q = self
            .shared
            .queue
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        (q.pending.len(), q.in_flight.len())
    }

    /// Finished jobs, without waiting.
    pub fn finished(&self) -> impl Iterator<Item = Done> + '_ {
        self.results.try_iter()
    }

    /// Waits up to `timeout` for one finished job.
    pub fn wait_finished(&self, timeout: std::time::Duration) -> Option<Done> {
        self.results.recv_timeout(timeout).ok()
    }
}

impl Drop for Loader {
    fn drop(&mut self) {
        self.shared
            .queue
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .shutdown = true;
        self.shared.wake.notify_all();
        for t in self.threads.drain(..) {
            // A loader thread that panicked has nothing left to clean up.
            let _ = t.join();
        }
    }
}

fn worker(shared: &Shared, ds: &StreamDataset, tx: &Sender<Done>) {
    loop {
        let job = {
            let mut q = shared.queue.lock().unwrap_or_else(PoisonError::into_inner);
            loop {
                if q.shutdown {
                    return;
                }
                if let Some(job) = q.pending.pop() {
                    q.in_flight.insert(job.key());
                    break job;
                }
                q = shared.wake.wait(q).unwrap_or_else(PoisonError::into_inner);
            }
        };
        // A panic is a fault of ours, but it must fail its node, not leave it in flight for
        // ever: the view would then be taken for complete without it.
        let done = std::panic::catch_unwind(AssertUnwindSafe(|| run(shared, ds, &job)))
            .unwrap_or_else(|panic| {
                let what = panic
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| panic.downcast_ref::<String>().cloned())
                    .unwrap_or_default();
                let e = ViewerError::source(
                    ds.location(),
                    format!(
                        "loading {} failed unexpectedly ({what})",
                        match &job {
                            Job::Node(info) => format!("node {}", info.key),
                            Job::Page(page) => format!("the hierarchy page of node {}", page.root),
                        }
                    ),
                );
                match &job {
                    Job::Node(info) => Done::NodeFailed(info.key, e),
                    Job::Page(page) => Done::PageFailed(page.root, e),
                }
            });
        let receiver_gone = tx.send(done).is_err();
        shared
            .queue
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .in_flight
            .remove(&job.key());
        if receiver_gone {
            return;
        }
    }
}

fn run(shared: &Shared, ds: &StreamDataset, job: &Job) -> Done {
    match job {
        Job::Node(info) => match load(shared, ds, info) {
            Ok(node) => Done::Node(node),
            Err(e) => Done::NodeFailed(info.key, e),
        },
        Job::Page(page) => match ds.load_page(page) {
            Ok(p) => Done::Page(p),
            Err(e) => Done::PageFailed(page.root, e),
        },
    }
}

fn load(shared: &Shared, ds: &StreamDataset, info: &NodeInfo) -> Result<GpuNode, ViewerError> {
    let (colours, marks) = form(shared);
    ds.load_node(info, colours, &marks)
}

fn form(shared: &Shared) -> (ColourWord, Marks) {
    shared
        .form
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .clone()
}
