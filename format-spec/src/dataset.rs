//! Reading a dataset from a local directory with positioned reads.

use crate::{
    FormatError, HierarchyPage, Metadata, NodeColumns, NodeInfo, PageRef, RowLayout,
    check_file_head, decode_node, decode_page,
};
use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

/// The files of a dataset directory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DatasetFile {
    Metadata,
    Hierarchy,
    Octree,
}

impl DatasetFile {
    pub fn name(self) -> &'static str {
        match self {
            DatasetFile::Metadata => "metadata.json",
            DatasetFile::Hierarchy => "hierarchy.bin",
            DatasetFile::Octree => "octree.bin",
        }
    }
}

/// An open dataset on the local file system.
#[derive(Debug)]
pub struct LocalDataset {
    dir: PathBuf,
    metadata: Metadata,
    layout: RowLayout,
    hierarchy: File,
    octree: File,
}

impl LocalDataset {
    /// Opens a dataset directory: reads `metadata.json` and checks both binary files' heads
    /// against it (magic, dataset id, size). Reads no hierarchy page yet.
    pub fn open(dir: &Path) -> Result<LocalDataset, FormatError> {
        if !dir.is_dir() {
            return Err(FormatError::corrupt(
                dir,
                "is not a dataset directory (expected a directory holding metadata.json)",
            ));
        }
        let meta_path = dir.join(DatasetFile::Metadata.name());
        let bytes = read_metadata_file(&meta_path)?;
        let metadata = Metadata::from_json(&bytes, &meta_path)?;
        let hierarchy = open_checked(
            &dir.join(&metadata.files.hierarchy.name),
            DatasetFile::Hierarchy,
            &metadata,
        )?;
        let octree = open_checked(
            &dir.join(&metadata.files.octree.name),
            DatasetFile::Octree,
            &metadata,
        )?;
        Ok(LocalDataset {
            dir: dir.to_path_buf(),
            layout: metadata.row_layout(),
            metadata,
            hierarchy,
            octree,
        })
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    pub fn metadata(&self) -> &Metadata {
        &self.metadata
    }

    pub fn layout(&self) -> &RowLayout {
        &self.layout
    }

    pub fn path_of(&self, file: DatasetFile) -> PathBuf {
        match file {
            DatasetFile::Metadata => self.dir.join(file.name()),
            DatasetFile::Hierarchy => self.dir.join(&self.metadata.files.hierarchy.name),
            DatasetFile::Octree => self.dir.join(&self.metadata.files.octree.name),
        }
    }

    pub fn root_page(&self) -> PageRef {
        self.metadata.root_page()
    }

    /// Reads and decodes one hierarchy page.
    pub fn load_page(&self, page: &PageRef) -> Result<HierarchyPage, FormatError> {
        let path = self.path_of(DatasetFile::Hierarchy);
        let bytes = self.read(DatasetFile::Hierarchy, page.offset, page.size)?;
        let levels = self.metadata.hierarchy.page_levels;
        decode_page(&bytes, page, levels, self.metadata.layout()).map_err(|e| {
            FormatError::corrupt(
                &path,
                format!(
                    "hierarchy page at byte {} (nodes under {}): {e}",
                    page.offset, page.root
                ),
            )
        })
    }

    /// Every node once, loading every page, in key order. For whole-dataset work (export,
    /// verify, info).
    pub fn all_nodes(&self) -> Result<Vec<NodeInfo>, FormatError> {
        let mut nodes = Vec::new();
        let mut pages = vec![self.root_page()];
        let mut seen = std::collections::HashSet::new();
        while let Some(p) = pages.pop() {
            if !seen.insert(p.offset) {
                return Err(FormatError::corrupt(
                    self.path_of(DatasetFile::Hierarchy),
                    format!(
                        "hierarchy page at byte {} is referenced by more than one proxy",
                        p.offset
                    ),
                ));
            }
            let page = self.load_page(&p)?;
            pages.extend(page.child_pages());
            nodes.extend(page.own_nodes());
        }
        nodes.sort_by_key(|n| n.key);
        Ok(nodes)
    }

    /// Reads, verifies and decompresses one node.
    pub fn read_node(&self, node: &NodeInfo) -> Result<NodeColumns, FormatError> {
        let path = self.path_of(DatasetFile::Octree);
        let payload = self.read_payload(node)?;
        decode_node(
            &payload,
            node.point_count as usize,
            node.checksum,
            &self.layout,
        )
        .map_err(|e| FormatError::corrupt(&path, format!("node {}: {e}", node.key)))
    }
}

impl LocalDataset {
    /// The stored (compressed) bytes of one node, unchecked.
    pub fn read_payload(&self, node: &NodeInfo) -> Result<Vec<u8>, FormatError> {
        self.read(DatasetFile::Octree, node.offset, node.size as u64)
    }

    /// `len` bytes at `offset` of a binary file, refused before allocating when the range
    /// lies past the file's end (sizes were checked against the metadata at open).
    pub fn read(&self, file: DatasetFile, offset: u64, len: u64) -> Result<Vec<u8>, FormatError> {
        let path = self.path_of(file);
        let (f, size) = match file {
            DatasetFile::Hierarchy => (&self.hierarchy, self.metadata.files.hierarchy.size),
            _ => (&self.octree, self.metadata.files.octree.size),
        };
        if offset.checked_add(len).is_none_or(|end| end > size) {
            return Err(FormatError::corrupt(
                &path,
                format!("range of {len} bytes at byte {offset} lies past the end ({size} bytes)"),
            ));
        }
        read_range(f, &path, offset, len)
    }
}

/// No `metadata.json` is larger: a few kilobytes, plus a line per input and scanner.
pub const METADATA_MAX_BYTES: u64 = 16 << 20;

/// The bytes of a `metadata.json`, refused where it is not a regular file (a pipe or a
/// device would block or never end) or is larger than any real one.
pub fn read_metadata_file(path: &Path) -> Result<Vec<u8>, FormatError> {
    const MAX: u64 = METADATA_MAX_BYTES;
    let (file, stat) = open_regular(path)?;
    if stat.len() > MAX {
        return Err(FormatError::corrupt(
            path,
            format!(
                "is {} bytes long, more than any metadata ({MAX} at most)",
                stat.len()
            ),
        ));
    }
    read_range(&file, path, 0, stat.len())
}

/// A dataset file opened for reading, refused where it is not a regular file: a pipe or a
/// device would block or never end.
pub fn open_regular(path: &Path) -> Result<(File, std::fs::Metadata), FormatError> {
    // Looked at before it is opened: opening a pipe waits for a writer.
    if !std::fs::metadata(path)
        .map_err(|e| FormatError::io(path, e))?
        .is_file()
    {
        return Err(FormatError::corrupt(path, "is not a regular file"));
    }
    let file = File::open(path).map_err(|e| FormatError::io(path, e))?;
    let stat = file.metadata().map_err(|e| FormatError::io(path, e))?;
    // Looked at again on what was opened: the name may have been replaced in between.
    if !stat.is_file() {
        return Err(FormatError::corrupt(path, "is not a regular file"));
    }
    Ok((file, stat))
}

fn open_checked(path: &Path, file: DatasetFile, meta: &Metadata) -> Result<File, FormatError> {
    let (f, stat) = open_regular(path)?;
    let len = stat.len();
    let head = read_range(&f, path, 0, meta.layout().head_size(file).min(len))?;
    check_file_head(path, file, Some(len), &head, meta)?;
    Ok(f)
}

fn read_range(file: &File, path: &Path, offset: u64, len: u64) -> Result<Vec<u8>, FormatError> {
    let mut buf = vec![0u8; len as usize];
    file.read_exact_at(&mut buf, offset).map_err(|e| {
        FormatError::corrupt(
            path,
            format!("cannot read {len} bytes at byte {offset} ({e})"),
        )
    })?;
    Ok(buf)
}
