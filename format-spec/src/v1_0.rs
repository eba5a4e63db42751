//! Writing a dataset in format 1.0: for readers that know only 1.0, and for the tests that keep
//! this reader's 1.0 paths honest. The nodes are the same; the files are laid out as the 1.0
//! writer laid them out (8-byte heads, proxies that locate only their page, a one-byte LZ4
//! block for a node without points).

use crate::{
    DatasetFile, DatasetId, FileInfo, FormatError, HierarchyInfo, Layout, LocalDataset, NodeRecord,
    OCTREE_MAGIC_1_0, build_hierarchy,
};
use std::collections::BTreeMap;
use std::path::Path;

/// Rewrites the dataset in `src` (any version this reader reads) as a format 1.0 dataset in
/// the new directory `dst`.
pub fn rewrite_as_1_0(src: &Path, dst: &Path) -> Result<(), FormatError> {
    let ds = LocalDataset::open(src)?;
    let nodes = ds.all_nodes()?;
    let mut octree = OCTREE_MAGIC_1_0.to_vec();
    let mut records: BTreeMap<_, NodeRecord> = BTreeMap::new();
    // Payloads keep their order; nodes without points get the block 1.0 writers stored for
    // them, after the others.
    let mut in_order: Vec<_> = nodes.iter().collect();
    in_order.sort_by_key(|n| (n.point_count == 0, n.offset, n.key));
    for n in in_order {
        let payload = if n.point_count == 0 {
            lz4_flex::block::compress(&[])
        } else {
            ds.read_payload(n)?
        };
        records.insert(
            n.key,
            NodeRecord {
                point_count: n.point_count,
                offset: octree.len() as u64,
                size: payload.len() as u32,
                checksum: crc32fast::hash(&payload),
                child_mask: n.child_mask,
            },
        );
        octree.extend_from_slice(&payload);
    }
    let mut meta = ds.metadata().clone();
    let built = build_hierarchy(&records, meta.hierarchy.page_levels, Layout::V1_0);
    let hierarchy = built.file(DatasetId::default());
    meta.version = [1, 0];
    meta.id = None;
    meta.files.hierarchy = FileInfo {
        name: DatasetFile::Hierarchy.name().into(),
        size: hierarchy.len() as u64,
    };
    meta.files.octree = FileInfo {
        name: DatasetFile::Octree.name().into(),
        size: octree.len() as u64,
    };
    meta.hierarchy = HierarchyInfo {
        root_page_offset: built.root_page_offset,
        root_page_size: built.root_page_size,
        page_levels: built.page_levels,
    };
    std::fs::create_dir_all(dst).map_err(|e| FormatError::io(dst, e))?;
    for (file, bytes) in [
        (DatasetFile::Octree, octree),
        (DatasetFile::Hierarchy, hierarchy),
        (DatasetFile::Metadata, meta.to_json().into_bytes()),
    ] {
        let path = dst.join(file.name());
        std::fs::write(&path, bytes).map_err(|e| FormatError::io(&path, e))?;
    }
    Ok(())
}
