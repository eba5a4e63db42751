//! The Strata dataset format: a layered point-cloud octree stored in three files.
//!
//! `SPEC.md` beside this crate is the normative description; this crate is its reference
//! implementation. It encodes and decodes the parts (metadata, hierarchy pages, node payloads)
//! and reads a local dataset, with no caching policy and no threads of its own.

mod attribute;
mod dataset;
mod error;
mod head;
mod hierarchy;
#[cfg(test)]
mod hierarchy_tests;
mod metadata;
mod node_codec;
mod node_key;
mod page_build;
mod side_file;
pub mod v1_0;
mod verify;

pub use attribute::{
    AttrType, Attribute, MAX_ATTRIBUTES, OCT16, RowLayout, TimeBase, oct16_decode, oct16_encode,
    row_position,
};
pub use dataset::{
    DatasetFile, LocalDataset, METADATA_MAX_BYTES, open_regular, read_metadata_file,
};
pub use error::{FormatError, finest_step, number, step_decimals};
pub use head::{
    DatasetId, HIERARCHY_HEAD_SIZE, HIERARCHY_MAGIC, HIERARCHY_MAGIC_1_0, HierarchyHead, Layout,
    OCTREE_HEAD_SIZE, OCTREE_MAGIC, OCTREE_MAGIC_1_0, ROOT_PAGE_OFFSET, check_file_head,
    octree_head,
};
pub use hierarchy::{
    ENTRY_SIZE, EntryKind, HierarchyPage, NodeInfo, PAGE_LEVELS, PAGE_REF_SIZE, PageEntry, PageRef,
    Proxy, decode_page, page_size,
};
pub use metadata::{
    Bounds, Crs, Cube, FORMAT_NAME, FileInfo, Files, GeoTiffKeys, HierarchyInfo, MAX_PAGE_LEVELS,
    Metadata, NormalsInfo, Scanner, VERSION_MAJOR, VERSION_MINOR, plain_file_name,
};
pub use node_codec::{
    NodeColumns, NodeDecodeError, decode_node, encode_node, encode_node_rows, payload_checksum,
};
pub use node_key::NodeKey;
pub use page_build::{BuiltHierarchy, NodeRecord, build_hierarchy};
pub use side_file::{SIDE_FILE_MAX_BYTES, read_side_file};
pub use verify::{Fault, VerifyReport, verify_dataset};

/// Sampling grid cells per node edge: a node's spacing is its edge length / `GRID_CELLS`.
pub const GRID_CELLS_LOG2: u32 = 7;
