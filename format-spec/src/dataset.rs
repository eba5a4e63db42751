//! Reading a dataset from a local directory with positioned reads.

use crate::{
    EntryKind, FormatError, HIERARCHY_MAGIC, HierarchyPage, Metadata, NodeColumns, NodeKey,
    OCTREE_MAGIC, PageRef, RowLayout, decode_node, decode_page,
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

/// A node as the hierarchy describes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeInfo {
    pub key: NodeKey,
    pub point_count: u32,
    pub offset: u64,
    pub size: u32,
    pub checksum: u32,
    pub child_mask: u8,
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
    /// Opens a dataset directory: reads `metadata.json` and checks both binary files' magic and
    /// size. Reads no hierarchy page yet.
    pub fn open(dir: &Path) -> Result<LocalDataset, FormatError> {
        if !dir.is_dir() {
            return Err(FormatError::corrupt(
                dir,
                "is not a dataset directory (expected a directory holding metadata.json)",
            ));
        }
        let meta_path = dir.join(DatasetFile::Metadata.name());
        let bytes = std::fs::read(&meta_path).map_err(|e| FormatError::io(&meta_path, e))?;
        let metadata = Metadata::from_json(&bytes, &meta_path)?;
        let hierarchy = open_checked(
            &dir.join(&metadata.files.hierarchy.name),
            HIERARCHY_MAGIC,
            metadata.files.hierarchy.size,
        )?;
        let octree = open_checked(
            &dir.join(&metadata.files.octree.name),
            OCTREE_MAGIC,
            metadata.files.octree.size,
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
        let bytes = read_range(&self.hierarchy, &path, page.offset, page.size)?;
        decode_page(&bytes, page, self.metadata.hierarchy.page_levels).map_err(|e| {
            FormatError::corrupt(
                &path,
                format!(
                    "hierarchy page at byte {} (nodes under {}): {e}",
                    page.offset, page.root
                ),
            )
        })
    }

    /// Every node, loading every page. For whole-dataset work (export, verify, info).
    pub fn all_nodes(&self) -> Result<Vec<NodeInfo>, FormatError> {
        let mut nodes = Vec::new();
        let mut pages = vec![self.root_page()];
        while let Some(p) = pages.pop() {
            let page = self.load_page(&p)?;
            pages.extend(page.child_pages());
            nodes.extend(node_infos(&page));
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
        let path = self.path_of(DatasetFile::Octree);
        read_range(&self.octree, &path, node.offset, node.size as u64)
    }
}

/// The nodes a page describes in full (proxies are described by their own page).
pub fn node_infos(page: &HierarchyPage) -> impl Iterator<Item = NodeInfo> + '_ {
    page.entries
        .iter()
        .filter(|(_, e)| e.kind == EntryKind::Node)
        .map(|(k, e)| NodeInfo {
            key: *k,
            point_count: e.point_count,
            offset: e.offset,
            size: e.size,
            checksum: e.checksum,
            child_mask: e.child_mask,
        })
}

fn open_checked(path: &Path, magic: &[u8; 8], expected_size: u64) -> Result<File, FormatError> {
    let file = File::open(path).map_err(|e| FormatError::io(path, e))?;
    let len = file.metadata().map_err(|e| FormatError::io(path, e))?.len();
    let head = if len >= 8 {
        read_range(&file, path, 0, 8)?
    } else {
        Vec::new()
    };
    check_file_head(path, len, &head, magic, expected_size)?;
    Ok(file)
}

/// Checks a binary dataset file's length against `metadata.json` and its first bytes against
/// its magic. `path` names the file (or URL) in the message. Every reader (local, mmap, HTTP)
/// applies the same check.
pub fn check_file_head(
    path: impl AsRef<Path>,
    len: u64,
    head: &[u8],
    magic: &[u8; 8],
    expected_size: u64,
) -> Result<(), FormatError> {
    let path = path.as_ref();
    if len != expected_size {
        return Err(FormatError::corrupt(
            path,
            format!(
                "file is {len} bytes but metadata.json says {expected_size} (truncated or replaced)"
            ),
        ));
    }
    if head.get(..8) != Some(&magic[..]) {
        return Err(FormatError::corrupt(
            path,
            format!(
                "does not start with the {:?} magic",
                String::from_utf8_lossy(magic)
            ),
        ));
    }
    Ok(())
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
