//! Blocking file-system steps, run only on the blocking pool: confining a path to the served
//! directory, opening regular files without ever waiting on a FIFO or device, and reading a
//! byte range in one call into a reused buffer.

use bytes::Bytes;
use std::fs::{File, Metadata};
use std::os::unix::fs::{FileExt, FileTypeExt, OpenOptionsExt};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// `path` (whose parent is already inside `root`) if it stays inside `root`, following a final
/// symlink, with its `lstat`, or of its target when it is a link.
pub fn confined(root: &Path, path: &Path) -> Option<(PathBuf, Metadata)> {
    let meta = std::fs::symlink_metadata(path).ok()?;
    if !meta.file_type().is_symlink() {
        return Some((path.to_path_buf(), meta));
    }
    let target = std::fs::canonicalize(path).ok()?;
    if !target.starts_with(root) {
        return None;
    }
    let meta = std::fs::symlink_metadata(&target).ok()?;
    Some((target, meta))
}

/// Opens `path` for reading if it is a regular file. `O_NONBLOCK` makes opening a FIFO or a
/// device return at once instead of waiting for a writer; `O_NOFOLLOW` refuses a symlink swapped
/// in since `confined` looked; `fstat` on the open file decides.
pub fn open_regular(path: &Path) -> Option<(File, Metadata)> {
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK | libc::O_NOFOLLOW | libc::O_CLOEXEC)
        .open(path)
        .ok()?;
    let meta = file.metadata().ok()?;
    if !meta.file_type().is_file() || meta.file_type().is_fifo() {
        return None;
    }
    Some((file, meta))
}

/// Buffers kept for reuse: a range is read into memory that earlier requests already touched,
/// so neither the allocator nor zero-filling runs per request.
static POOL: Mutex<Vec<Vec<u8>>> = Mutex::new(Vec::new());
const POOL_BUFFERS: usize = 256;
/// Larger buffers go back to the allocator rather than into the pool.
const POOL_BUFFER_MAX: usize = 1 << 20;

struct PooledBuf {
    buf: Vec<u8>,
    used: usize,
}

impl AsRef<[u8]> for PooledBuf {
    fn as_ref(&self) -> &[u8] {
        &self.buf[..self.used]
    }
}

impl Drop for PooledBuf {
    fn drop(&mut self) {
        if self.buf.len() > POOL_BUFFER_MAX {
            return;
        }
        if let Ok(mut pool) = POOL.lock()
            && pool.len() < POOL_BUFFERS
        {
            pool.push(std::mem::take(&mut self.buf));
        }
    }
}

/// Exactly `len` bytes at `offset`, read with as few `pread` calls as the kernel allows.
pub fn read_range(file: &File, offset: u64, len: usize) -> std::io::Result<Bytes> {
    let mut buf = POOL
        .lock()
        .ok()
        .and_then(|mut p| p.pop())
        .unwrap_or_default();
    // A reused buffer keeps its length, so only growth is zero-filled.
    if buf.len() < len {
        buf.resize(len, 0);
    }
    let mut pooled = PooledBuf { buf, used: 0 };
    file.read_exact_at(&mut pooled.buf[..len], offset)
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::UnexpectedEof => std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                "file shrank while being served",
            ),
            _ => e,
        })?;
    pooled.used = len;
    Ok(Bytes::from_owner(pooled))
}
