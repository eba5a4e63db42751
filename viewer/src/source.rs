//! Where dataset bytes come from. The viewer reads through this trait only, so a local
//! directory and an HTTP server are interchangeable.

use crate::ViewerError;
use std::path::Path;
use strata_format::{DatasetFile, LocalDataset, Metadata};

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

/// A local dataset directory, its binary files read at offsets (`LocalDataset`). They were
/// memory-mapped: a file truncated or rewritten in place while the window was open (a
/// conversion, a copy over it) killed the viewer with SIGBUS and no message when it touched a
/// page past the new end. A read that comes up short is an error naming the file, and the node
/// counts as failed.
pub struct LocalSource {
    ds: LocalDataset,
}

impl LocalSource {
    pub fn open(dir: &Path) -> Result<(LocalSource, Metadata), ViewerError> {
        let ds = LocalDataset::open(dir)?;
        let metadata = ds.metadata().clone();
        Ok((LocalSource { ds }, metadata))
    }
}

impl Source for LocalSource {
    fn location(&self) -> String {
        self.ds.dir().display().to_string()
    }

    fn file_location(&self, file: DatasetFile) -> String {
        self.ds.path_of(file).display().to_string()
    }

    fn metadata_bytes(&self) -> Result<Vec<u8>, ViewerError> {
        let path = self.ds.path_of(DatasetFile::Metadata);
        Ok(strata_format::read_metadata_file(&path)?)
    }

    fn read(&self, file: DatasetFile, offset: u64, len: u64) -> Result<Vec<u8>, ViewerError> {
        match file {
            DatasetFile::Metadata => self.metadata_bytes(),
            _ => Ok(self.ds.read(file, offset, len)?),
        }
    }
}
