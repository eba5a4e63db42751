//! The Strata dataset format: a layered point-cloud octree stored in three files.
//!
//! `SPEC.md` beside this crate is the normative description; this crate is its reference
//! implementation. It encodes and decodes the parts (metadata, hierarchy pages, node payloads)
//! and reads a local dataset, with no caching policy and no threads of its own.

mod attribute;
mod dataset;
mod error;
mod hierarchy;
mod metadata;
mod node_codec;
mod node_key;
mod verify;

pub use attribute::{
    AttrType, Attribute, OCT16, RowLayout, oct16_decode, oct16_encode, row_position,
};
pub use dataset::{DatasetFile, LocalDataset, NodeInfo, check_file_head, node_infos};
pub use error::FormatError;
pub use hierarchy::{
    ENTRY_SIZE, EntryKind, HIERARCHY_MAGIC, HierarchyPage, NodeRecord, PAGE_LEVELS, PageEntry,
    PageRef, build_hierarchy, decode_page,
};
pub use metadata::{
    Bounds, Cube, FORMAT_NAME, FileInfo, Files, HierarchyInfo, Metadata, NormalsInfo, Scanner,
    VERSION_MAJOR, VERSION_MINOR,
};
pub use node_codec::{
    NodeColumns, NodeDecodeError, OCTREE_MAGIC, decode_node, encode_node, encode_node_rows,
};
pub use node_key::NodeKey;
pub use verify::{Fault, VerifyReport, verify_dataset};

/// Sampling grid cells per node edge: a node's spacing is its edge length / `GRID_CELLS`.
pub const GRID_CELLS_LOG2: u32 = 7;
