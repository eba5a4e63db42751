//! The bounded pool that runs every file-system call (stat, open, read) off the async workers.
//!
//! A fixed set of `workers` threads (a few per core: more would only trade places on the cores)
//! takes jobs from one queue, back to back. A job whose request gave up while it ran (a hung
//! network mount, a device that stalls) is *abandoned*: it keeps its thread, and a replacement
//! thread starts so that `workers` threads still serve the queue, up to `max_threads` threads in
//! all. An abandoned job that finishes lets one thread go. So a stuck file costs one thread, and
//! only when `max_threads - workers` files are stuck at once do file requests start to wait.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use tokio::sync::oneshot;

const QUEUED: u8 = 0;
const RUNNING: u8 = 1;
const DONE: u8 = 2;
const ABANDONED: u8 = 3;

struct Job {
    state: Arc<AtomicU8>,
    run: Box<dyn FnOnce() + Send>,
}

#[derive(Default)]
struct Queue {
    jobs: VecDeque<Job>,
    threads: usize,
    /// Threads running a job nobody waits for any more.
    abandoned: usize,
}

struct Inner {
    queue: Mutex<Queue>,
    ready: Condvar,
    workers: usize,
    max_threads: usize,
}

#[derive(Clone)]
pub struct BlockingPool {
    inner: Arc<Inner>,
}

impl std::fmt::Debug for BlockingPool {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BlockingPool")
            .field("workers", &self.inner.workers)
            .field("max_threads", &self.inner.max_threads)
            .finish()
    }
}

/// The job panicked or no thread could be started: the request gets a 500, the server goes on.
#[derive(Debug, thiserror::Error)]
#[error("the file-system pool could not run the call")]
pub struct PoolFailed;

fn lock(inner: &Inner) -> MutexGuard<'_, Queue> {
    // A panic inside a job happens outside the lock; the queue itself stays consistent.
    inner.queue.lock().unwrap_or_else(|p| p.into_inner())
}

/// Starts a thread if fewer than `workers` serve the queue and the cap allows; false if none
/// could start.
fn top_up(inner: &Arc<Inner>, q: &mut Queue) -> bool {
    if q.threads - q.abandoned >= inner.workers || q.threads >= inner.max_threads {
        return true;
    }
    let pool = inner.clone();
    let started = std::thread::Builder::new()
        .name("strata-fs".into())
        .spawn(move || work(pool))
        .is_ok();
    if started {
        q.threads += 1;
    }
    started || q.threads > q.abandoned
}

fn work(inner: Arc<Inner>) {
    let mut q = lock(&inner);
    loop {
        let Some(job) = q.jobs.pop_front() else {
            q = inner.ready.wait(q).unwrap_or_else(|p| p.into_inner());
            continue;
        };
        let claimed = job
            .state
            .compare_exchange(QUEUED, RUNNING, Ordering::AcqRel, Ordering::Acquire)
            .is_ok();
        drop(q);
        if claimed {
            // A panicking job drops its sender: its request gets PoolFailed, the thread lives.
            let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(job.run));
        }
        q = lock(&inner);
        if claimed
            && job
                .state
                .compare_exchange(RUNNING, DONE, Ordering::AcqRel, Ordering::Acquire)
                .is_err()
        {
            q.abandoned -= 1;
        }
        // A replacement took this thread's place while it was stuck: one of them goes.
        if q.threads - q.abandoned > inner.workers {
            q.threads -= 1;
            return;
        }
    }
}

/// Abandons the job if its request stops waiting before the answer came.
struct Waiting {
    state: Arc<AtomicU8>,
    inner: Arc<Inner>,
    answered: bool,
}

impl Drop for Waiting {
    fn drop(&mut self) {
        if self.answered {
            return;
        }
        // State changes and the abandoned count move together, under the queue's lock.
        let mut q = lock(&self.inner);
        let swap = |from| {
            self.state
                .compare_exchange(from, ABANDONED, Ordering::AcqRel, Ordering::Acquire)
                .is_ok()
        };
        if !swap(QUEUED) && swap(RUNNING) {
            q.abandoned += 1;
            top_up(&self.inner, &mut q);
        }
    }
}

impl BlockingPool {
    /// `workers` threads serving the queue (no more than `max_threads`), `max_threads` at most
    /// counting stuck ones.
    pub fn new(workers: usize, max_threads: usize) -> BlockingPool {
        let workers = workers.clamp(1, max_threads.max(1));
        BlockingPool {
            inner: Arc::new(Inner {
                queue: Mutex::new(Queue::default()),
                ready: Condvar::new(),
                workers,
                max_threads: max_threads.max(workers),
            }),
        }
    }

    /// Runs `job` on a pool thread. Dropping the returned future (a request timeout) abandons
    /// the job: not started, it never runs; running, it keeps its thread until it ends.
    pub async fn run<T, F>(&self, job: F) -> Result<T, PoolFailed>
    where
        F: FnOnce() -> T + Send + 'static,
        T: Send + 'static,
    {
        let (tx, rx) = oneshot::channel();
        let state = Arc::new(AtomicU8::new(QUEUED));
        let mut waiting = Waiting {
            state: state.clone(),
            inner: self.inner.clone(),
            answered: false,
        };
        {
            let mut q = lock(&self.inner);
            q.jobs.push_back(Job {
                state,
                run: Box::new(move || {
                    let _ = tx.send(job());
                }),
            });
            if !top_up(&self.inner, &mut q) {
                q.jobs.pop_back();
                return Err(PoolFailed);
            }
        }
        self.inner.ready.notify_one();
        let result = rx.await.map_err(|_| PoolFailed);
        waiting.answered = true;
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc;
    use std::time::Duration;

    #[test]
    fn workers_are_no_more_than_the_threads_allowed() {
        assert_eq!(BlockingPool::new(4, 1).inner.workers, 1);
        assert_eq!(BlockingPool::new(4, 64).inner.workers, 4);
        assert_eq!(BlockingPool::new(0, 64).inner.workers, 1);
    }

    fn runtime() -> tokio::runtime::Runtime {
        tokio::runtime::Builder::new_current_thread()
            .enable_time()
            .build()
            .expect("runtime")
    }

    /// The output of `fut` if it finishes within `limit`.
    fn within<F: std::future::Future>(
        rt: &tokio::runtime::Runtime,
        limit: Duration,
        fut: F,
    ) -> Option<F::Output> {
        rt.block_on(async { tokio::time::timeout(limit, fut).await.ok() })
    }

    fn threads(pool: &BlockingPool) -> (usize, usize) {
        let q = lock(&pool.inner);
        (q.threads, q.abandoned)
    }

    #[test]
    fn a_stuck_call_costs_one_thread_and_the_cap_holds() {
        let rt = runtime();
        let pool = BlockingPool::new(2, 4);
        let mut releases = Vec::new();
        // Four calls that never return on their own, each given up by its request.
        for _ in 0..4 {
            let (release, stuck) = mpsc::channel::<()>();
            releases.push(release);
            let call = pool.run(move || stuck.recv().is_ok());
            let gave_up = within(&rt, Duration::from_millis(200), call);
            assert!(gave_up.is_none());
        }
        assert_eq!(threads(&pool), (4, 4), "the cap of 4 threads did not hold");
        // Every thread is stuck: a new call waits, and is not run once abandoned.
        let waits = within(&rt, Duration::from_millis(200), pool.run(|| ()));
        assert!(waits.is_none());
        // One stuck call ends: its thread serves the queue again.
        drop(releases.remove(0));
        let answered = within(&rt, Duration::from_secs(5), pool.run(|| 7));
        assert_eq!(answered.and_then(Result::ok), Some(7));
        releases.clear();
        std::thread::sleep(Duration::from_millis(200));
        // With nothing stuck, the pool shrinks back to its two workers.
        assert_eq!(threads(&pool), (2, 0));
    }

    #[test]
    fn two_stuck_calls_leave_the_workers_serving() {
        let rt = runtime();
        let pool = BlockingPool::new(2, 8);
        let (_release, stuck) = mpsc::channel::<()>();
        let stuck = Arc::new(Mutex::new(stuck));
        for _ in 0..2 {
            let s = stuck.clone();
            let call = pool.run(move || s.lock().map(|r| r.recv().is_ok()).is_ok());
            let _ = within(&rt, Duration::from_millis(100), call);
        }
        for i in 0..100 {
            let r = within(&rt, Duration::from_secs(5), pool.run(move || i));
            assert_eq!(r.and_then(Result::ok), Some(i));
        }
        let (threads, abandoned) = threads(&pool);
        assert!(
            abandoned >= 1 && threads <= 2 + abandoned,
            "{threads} threads, {abandoned} stuck"
        );
    }
}
