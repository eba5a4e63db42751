//! The small text files a user names beside a dataset (camera paths, bookmarks, measurements,
//! a server's token), read without trusting them to be small or to end.

use std::fs::File;
use std::io::{self, Read};
use std::os::unix::fs::FileTypeExt;
use std::path::Path;

/// No side file is larger: each holds a few lines per keyframe, bookmark or measurement.
pub const SIDE_FILE_MAX_BYTES: u64 = 64 << 20;

/// The text of a side file. A pipe is read (process substitution, `--token-file <(...)`), up to
/// the same bound; a device or a directory is refused: `/dev/zero` would fill the memory and
/// a terminal would wait for typing. Errors are `io::Error`s, so that a caller can still tell
/// a file that does not exist (`NotFound`) from one that is wrong.
pub fn read_side_file(path: &Path) -> io::Result<String> {
    let stat = std::fs::metadata(path)?;
    let kind = stat.file_type();
    if !(kind.is_file() || kind.is_fifo()) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "not a regular file",
        ));
    }
    // A file's length is known before it is read; a pipe's only as it is read.
    if kind.is_file() && stat.len() > SIDE_FILE_MAX_BYTES {
        return Err(too_long());
    }
    let mut bytes = Vec::new();
    File::open(path)?
        .take(SIDE_FILE_MAX_BYTES + 1)
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > SIDE_FILE_MAX_BYTES {
        return Err(too_long());
    }
    String::from_utf8(bytes)
        .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, format!("not UTF-8 text ({e})")))
}

fn too_long() -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!("longer than {SIDE_FILE_MAX_BYTES} bytes, more than any such file"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_device_is_refused_before_it_is_read() {
        let e = read_side_file(Path::new("/dev/zero")).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput, "{e}");
    }

    #[test]
    fn a_file_longer_than_the_bound_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.json");
        let f = File::create(&path).unwrap();
        f.set_len(SIDE_FILE_MAX_BYTES + 1).unwrap();
        let e = read_side_file(&path).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidData, "{e}");
    }

    #[test]
    fn a_missing_file_stays_not_found_and_text_is_read() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("marks.json");
        let e = read_side_file(&path).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::NotFound);
        std::fs::write(&path, "{}").unwrap();
        assert_eq!(read_side_file(&path).unwrap(), "{}");
    }
}
