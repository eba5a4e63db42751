//! The temporary file an output is written under (`NAME.part` beside it) until it is complete
//! and renamed into place.
//!
//! Two runs writing the same output once opened the same `NAME.part` and wrote into one
//! another's file: the one that finished first moved a mixture of both into place and exited 0.
//! A link at `NAME.part` was followed, so a run overwrote whatever it pointed at. The part is
//! now created new, never through a link, and locked for as long as its writer has it open:
//! a second writer finds it locked and is refused; a part left by a run that was killed is
//! unlocked, and is replaced.

use crate::error::{ConvertError, Result};
use std::fs::{File, OpenOptions, TryLockError};
use std::path::{Path, PathBuf};

/// Where an output is written before it is renamed into place: `NAME.part` beside it.
pub(crate) fn part_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".part");
    path.with_file_name(name)
}

/// Creates `path`'s part for reading and writing, locked until the file is closed; a stale
/// part (no writer holds its lock) is replaced first.
pub(crate) fn create_part(path: &Path) -> Result<(PathBuf, File)> {
    let part = part_path(path);
    remove_stale(path, &part)?;
    // Made under a name of this process's own and locked there, then linked to the part's
    // name, which fails where that exists: the part is never seen unlocked while its writer
    // lives, so no other run takes it for stale.
    let mut own = part.clone().into_os_string();
    own.push(format!(".{}", std::process::id()));
    let own = PathBuf::from(own);
    let _ = std::fs::remove_file(&own);
    let file = OpenOptions::new()
        .read(true)
        .write(true)
        .create_new(true)
        .open(&own)
        .map_err(|e| ConvertError::io(&own, "cannot create", e))?;
    let made = lock(&own, &file).and_then(|()| {
        std::fs::hard_link(&own, &part).map_err(|e| match e.kind() {
            std::io::ErrorKind::AlreadyExists => busy(path, &part),
            _ => ConvertError::io(&part, "cannot create", e),
        })
    });
    let _ = std::fs::remove_file(&own);
    made.map(|()| (part, file))
}

fn lock(part: &Path, file: &File) -> Result<()> {
    file.try_lock().map_err(|e| match e {
        TryLockError::WouldBlock => ConvertError::output(part, "is locked by another process"),
        TryLockError::Error(e) => ConvertError::io(part, "cannot lock", e),
    })
}

fn busy(path: &Path, part: &Path) -> ConvertError {
    ConvertError::output(
        path,
        format!(
            "another strata is writing it ({} is in use); wait for it to finish",
            part.display()
        ),
    )
}

/// Removes a part that no writer holds; refuses one a writer holds, and anything at its name
/// that is not a plain file (a link is never written through, nor removed).
fn remove_stale(path: &Path, part: &Path) -> Result<()> {
    let meta = match std::fs::symlink_metadata(part) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(ConvertError::io(part, "cannot inspect", e)),
    };
    if !meta.file_type().is_file() {
        return Err(ConvertError::output(
            part,
            "is in the way of the output's temporary file and is not one strata left (a link or \
             a folder); move it away",
        ));
    }
    let stale = open_no_follow(part).map_err(|e| ConvertError::io(part, "cannot open", e))?;
    match stale.try_lock() {
        Ok(()) => {}
        Err(TryLockError::WouldBlock) => return Err(busy(path, part)),
        Err(TryLockError::Error(e)) => return Err(ConvertError::io(part, "cannot lock", e)),
    }
    // Removed only while it is still the file just locked: another run may have replaced it.
    if same_file(&stale, part) {
        std::fs::remove_file(part).map_err(|e| ConvertError::io(part, "cannot remove", e))?;
    }
    Ok(())
}

#[cfg(unix)]
fn open_no_follow(path: &Path) -> std::io::Result<File> {
    use std::os::unix::fs::OpenOptionsExt;
    OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NOFOLLOW)
        .open(path)
}

#[cfg(not(unix))]
fn open_no_follow(path: &Path) -> std::io::Result<File> {
    OpenOptions::new().read(true).open(path)
}

#[cfg(unix)]
fn same_file(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), std::fs::symlink_metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(_: &File, path: &Path) -> bool {
    path.is_file()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_writer_is_refused_while_the_first_holds_the_part() {
        let dir = tempfile::tempdir().expect("tempdir");
        let out = dir.path().join("a.las");
        let (part, first) = create_part(&out).expect("the first writer");
        assert_eq!(part, dir.path().join("a.las.part"));
        let err = create_part(&out).expect_err("a second writer").to_string();
        assert!(err.contains("another strata is writing it"), "{err}");
        assert!(part.exists(), "the first writer's part is left alone");
        // Closed (the first writer killed), the part is stale and replaced.
        drop(first);
        let (again, _) = create_part(&out).expect("after the first is gone");
        assert_eq!(again, part);
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .expect("list")
            .map(|e| e.expect("entry").file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("a.las.part")]);
    }

    #[cfg(unix)]
    #[test]
    fn a_link_at_the_parts_name_is_neither_followed_nor_removed() {
        let dir = tempfile::tempdir().expect("tempdir");
        let precious = dir.path().join("precious.txt");
        std::fs::write(&precious, "keep me").expect("write");
        let out = dir.path().join("b.las");
        std::os::unix::fs::symlink(&precious, part_path(&out)).expect("link");
        let err = create_part(&out).expect_err("refused").to_string();
        assert!(err.contains("a link or a folder"), "{err}");
        assert_eq!(std::fs::read_to_string(&precious).expect("read"), "keep me");
        assert!(part_path(&out).is_symlink());
    }
}
