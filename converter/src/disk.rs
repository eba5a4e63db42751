//! Disk a conversion takes: the check before it starts that it fits, and the peak it reached
//! (work files and output together), sampled while it runs: a sample lists the folders, so it
//! can miss a peak shorter than the pause between samples (20 ms or more).

use crate::error::{ConvertError, Result};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Work files (chunk parts, staging rows, bands, chunk roots) per byte of uncompressed rows, at
/// most: lz4 on byte-grouped rows measured 0.39 on the synthetic city (20 M points), with chunk
/// roots another 0.2 on small clouds; random attributes compress less.
pub const WORK_PER_ROW_BYTE: f64 = 0.6;

/// Dataset bytes per byte of uncompressed rows, at most: measured 0.55 (lz4 nodes plus the
/// inner levels' copies).
pub const OUTPUT_PER_ROW_BYTE: f64 = 0.7;

/// Bytes free to an unprivileged writer on the file system holding `path` (or the nearest
/// folder above it that exists), and that file system's device.
pub fn free_space(path: &Path) -> Option<(u64, u64)> {
    // A bare file name's parent is "", which does not exist: it is the working folder (the
    // check was skipped for `-o big.laz`).
    fn here(p: &Path) -> &Path {
        if p.as_os_str().is_empty() {
            Path::new(".")
        } else {
            p
        }
    }
    let mut at = here(path);
    while !at.exists() {
        at = here(at.parent()?);
    }
    let dev = std::fs::metadata(at).ok()?.dev();
    let c = std::ffi::CString::new(at.as_os_str().as_encoded_bytes()).ok()?;
    // SAFETY: statvfs fills the struct it is given from a NUL-terminated path; it is zeroed
    // first and read only when the call succeeds.
    let mut s: libc::statvfs = unsafe { std::mem::zeroed() };
    if unsafe { libc::statvfs(c.as_ptr(), &mut s) } != 0 {
        return None;
    }
    Some((s.f_bavail as u64 * s.f_frsize as u64, dev))
}

/// Refuses, before any work, when `needs` (bytes wanted under each folder) do not fit in the
/// free space of their file systems (folders on one file system add up).
pub fn check_space(needs: &[(&Path, u64)]) -> Result<()> {
    let mut by_dev: Vec<(u64, u64, u64, PathBuf)> = Vec::new();
    for &(path, bytes) in needs {
        let Some((free, dev)) = free_space(path) else {
            continue;
        };
        match by_dev.iter_mut().find(|d| d.0 == dev) {
            Some(d) => d.1 += bytes,
            None => by_dev.push((dev, bytes, free, path.to_path_buf())),
        }
    }
    match by_dev.into_iter().find(|d| d.1 > d.2) {
        Some((_, needed, free, path)) => Err(ConvertError::NoSpace { path, needed, free }),
        None => Ok(()),
    }
}

/// Bytes per byte of uncompressed rows that work and output take together beyond the larger
/// of the two: chunk roots kept until the top levels are merged, and the blocks and chunks in
/// flight while one stage hands over to the next.
pub const OVERLAP_PER_ROW_BYTE: f64 = 0.2;

/// How the work files and the output of a conversion share the disk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiskUse {
    /// One run: the stages hand the disk over rather than adding up (staging rows are freed
    /// block by block as they are distributed into chunk files, and each chunk file is
    /// deleted once its chunk is built), so on one file system the peak is the larger of work
    /// and output plus the overlap (measured 0.58x to 0.63x the rows from 5 M to 10^9 points,
    /// against 0.9x asked here).
    HandOver,
    /// A plan's tasks: the chunk files stay until every task is done (each task reads its
    /// neighbours'), beside the tasks' nodes, so work and output add up.
    Together,
}

/// Refuses a conversion of `points` rows of `stride` bytes that would not fit at its peak.
/// With the work on another file system (`--temp-dir`), each side needs its own share.
pub fn check_conversion(
    work: &Path,
    root: &Path,
    points: u64,
    stride: usize,
    disk: DiskUse,
) -> Result<()> {
    let (work_bytes, output) = disk_estimate(points, stride);
    let same_disk = matches!(
        (free_space(work), free_space(root)),
        (Some((_, a)), Some((_, b))) if a == b
    );
    match (same_disk, disk) {
        (true, DiskUse::HandOver) => check_space(&[(root, work_bytes.max(output))]),
        (true, DiskUse::Together) => check_space(&[(root, work_bytes + output)]),
        (false, _) => check_space(&[(work, work_bytes), (root, output)]),
    }
}

/// The most disk the work files and the output of a conversion of `points` rows of `stride`
/// bytes take, each with the overlap of the stages.
pub fn disk_estimate(points: u64, stride: usize) -> (u64, u64) {
    let rows = points as f64 * stride as f64;
    let work = rows * (WORK_PER_ROW_BYTE + OVERLAP_PER_ROW_BYTE);
    let output = rows * (OUTPUT_PER_ROW_BYTE + OVERLAP_PER_ROW_BYTE);
    (work as u64, output as u64)
}

/// Bytes the files under `dir` take on disk, all levels.
pub fn tree_bytes(dir: &Path) -> u64 {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    entries
        .flatten()
        .map(|e| match e.metadata() {
            Ok(m) if m.is_dir() => tree_bytes(&e.path()),
            // What the file takes on disk: a staging file with freed blocks takes less.
            Ok(m) => m.blocks() * 512,
            Err(_) => 0,
        })
        .sum()
}

/// Samples the bytes under some folders every few milliseconds, keeping the largest sum.
pub struct PeakWatch {
    stop: Arc<AtomicBool>,
    peak: Arc<AtomicU64>,
    thread: Option<JoinHandle<()>>,
    dirs: Vec<PathBuf>,
}

impl PeakWatch {
    pub fn start(dirs: Vec<PathBuf>) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let peak = Arc::new(AtomicU64::new(0));
        let (s, p, d) = (stop.clone(), peak.clone(), dirs.clone());
        let thread = std::thread::Builder::new()
            .name("disk-watch".into())
            .spawn(move || {
                while !s.load(Ordering::Relaxed) {
                    let t = Instant::now();
                    p.fetch_max(d.iter().map(|x| tree_bytes(x)).sum(), Ordering::Relaxed);
                    // At most a tenth of a core, however many files there are.
                    let pause = (t.elapsed() * 9).max(Duration::from_millis(20));
                    std::thread::sleep(pause);
                }
            })
            .ok();
        PeakWatch {
            stop,
            peak,
            thread,
            dirs,
        }
    }

    /// Samples once more and returns the peak.
    pub fn sample(&self) -> u64 {
        let now = self.dirs.iter().map(|x| tree_bytes(x)).sum();
        self.peak.fetch_max(now, Ordering::Relaxed).max(now)
    }
}

impl Drop for PeakWatch {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
