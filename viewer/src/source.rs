//! Where dataset bytes come from. The viewer reads through this trait only, so a memory-mapped
//! directory and an HTTP server are interchangeable.

use crate::ViewerError;
use memmap2::Mmap;
use std::path::{Path, PathBuf};
use strata_format::{DatasetFile, FormatError, Metadata, check_file_head};

/// Byte ranges of a dataset's files. Implementations are shared by the loader threads.
pub trait Source: Send + Sync {
    /// A human-readable location (path or URL) for messages.
    fn location(&self) -> String;
    /// Where `file` is, for messages: under the name metadata.json gives it.
    fn file_location(&self, file: DatasetFile) -> String;
    /// The whole `metadata.json`.
    fn metadata_bytes(&self) -> Result<Vec<u8>, ViewerError>;
    /// `len` bytes at `offset` of a binary file.
    fn read(&self, file: DatasetFile, offset: u64, len: u64) -> Result<Vec<u8>, ViewerError>;
}

/// A local dataset directory with `hierarchy.bin` and `octree.bin` memory-mapped.
pub struct MmapSource {
    dir: PathBuf,
    /// The names of hierarchy.bin and octree.bin, as metadata.json gives them.
    names: [String; 2],
    hierarchy: Mmap,
    octree: Mmap,
}

impl MmapSource {
    pub fn open(dir: &Path) -> Result<(MmapSource, Metadata), ViewerError> {
        if !dir.is_dir() {
            return Err(FormatError::corrupt(
                dir,
                "is not a dataset directory (expected a directory holding metadata.json)",
            )
            .into());
        }
        let meta_path = dir.join(DatasetFile::Metadata.name());
        let bytes = strata_format::read_metadata_file(&meta_path)?;
        let metadata = Metadata::from_json(&bytes, &meta_path)?;
        let hierarchy = map_checked(
            &dir.join(&metadata.files.hierarchy.name),
            DatasetFile::Hierarchy,
            &metadata,
        )?;
        let octree = map_checked(
            &dir.join(&metadata.files.octree.name),
            DatasetFile::Octree,
            &metadata,
        )?;
        Ok((
            MmapSource {
                dir: dir.to_path_buf(),
                names: [
                    metadata.files.hierarchy.name.clone(),
                    metadata.files.octree.name.clone(),
                ],
                hierarchy,
                octree,
            },
            metadata,
        ))
    }
}

impl Source for MmapSource {
    fn location(&self) -> String {
        self.dir.display().to_string()
    }

    fn file_location(&self, file: DatasetFile) -> String {
        let name = match file {
            DatasetFile::Metadata => file.name(),
            DatasetFile::Hierarchy => &self.names[0],
            DatasetFile::Octree => &self.names[1],
        };
        self.dir.join(name).display().to_string()
    }

    fn metadata_bytes(&self) -> Result<Vec<u8>, ViewerError> {
        let path = self.dir.join(DatasetFile::Metadata.name());
        Ok(strata_format::read_metadata_file(&path)?)
    }

    fn read(&self, file: DatasetFile, offset: u64, len: u64) -> Result<Vec<u8>, ViewerError> {
        let map = match file {
            DatasetFile::Hierarchy => &self.hierarchy,
            DatasetFile::Octree => &self.octree,
            DatasetFile::Metadata => return self.metadata_bytes(),
        };
        let end = offset.checked_add(len).filter(|&e| e <= map.len() as u64);
        match end {
            Some(end) => Ok(map[offset as usize..end as usize].to_vec()),
            None => Err(FormatError::corrupt(
                self.file_location(file),
                format!(
                    "range of {len} bytes at byte {offset} lies past the end ({} bytes)",
                    map.len()
                ),
            )
            .into()),
        }
    }
}

fn map_checked(path: &Path, file: DatasetFile, meta: &Metadata) -> Result<Mmap, FormatError> {
    // Refused where it is not a regular file: opening a pipe waits for a writer.
    let (f, _) = strata_format::open_regular(path)?;
    // SAFETY: the dataset is read-only by contract (written once, renamed into place); a file
    // truncated under us would fault, which is why sizes are checked against the metadata first.
    let map = unsafe { Mmap::map(&f) }.map_err(|e| FormatError::io(path, e))?;
    check_file_head(path, file, Some(map.len() as u64), &map, meta)?;
    Ok(map)
}
