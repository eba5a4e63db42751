//! The heads of the two binary files, the dataset id that ties the three files together, and
//! the binary layout a format version uses.

use crate::{DatasetFile, FormatError, Metadata};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::path::Path;

/// The first 8 bytes of a 1.1 `hierarchy.bin` (1.0: `STRATAHY`).
pub const HIERARCHY_MAGIC: &[u8; 8] = b"STRHY1.1";
/// The first 8 bytes of a 1.1 `octree.bin` (1.0: `STRATAOC`).
pub const OCTREE_MAGIC: &[u8; 8] = b"STROC1.1";
pub const HIERARCHY_MAGIC_1_0: &[u8; 8] = b"STRATAHY";
pub const OCTREE_MAGIC_1_0: &[u8; 8] = b"STRATAOC";
/// Bytes of a 1.1 `hierarchy.bin` head: magic, id, root page size (u32), page levels (u32).
pub const HIERARCHY_HEAD_SIZE: u64 = 32;
/// Bytes of a 1.1 `octree.bin` head: magic, id.
pub const OCTREE_HEAD_SIZE: u64 = 24;
/// Where the root page of a 1.1 `hierarchy.bin` begins: right after the head, always, so a
/// client can fetch it before it has read `metadata.json`.
pub const ROOT_PAGE_OFFSET: u64 = HIERARCHY_HEAD_SIZE;

/// The binary layout of a dataset's files, decided by its format version.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Layout {
    /// Format 1.0: 8-byte heads (magic only), proxies locate only their page.
    V1_0,
    /// Format 1.1: heads with the dataset id, the root page right after the head, proxies
    /// that locate both their node's payload and their page.
    V1_1,
}

impl Layout {
    /// The layout of format version `[1, minor]` (a minor version this reader knows).
    pub fn of_minor(minor: u32) -> Layout {
        if minor == 0 {
            Layout::V1_0
        } else {
            Layout::V1_1
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Layout::V1_0 => "1.0",
            Layout::V1_1 => "1.1",
        }
    }

    pub fn magic(self, file: DatasetFile) -> &'static [u8; 8] {
        match (self, file) {
            (Layout::V1_0, DatasetFile::Hierarchy) => HIERARCHY_MAGIC_1_0,
            (Layout::V1_0, _) => OCTREE_MAGIC_1_0,
            (Layout::V1_1, DatasetFile::Hierarchy) => HIERARCHY_MAGIC,
            (Layout::V1_1, _) => OCTREE_MAGIC,
        }
    }

    /// Bytes before the first page or payload of a binary file.
    pub fn head_size(self, file: DatasetFile) -> u64 {
        match (self, file) {
            (Layout::V1_0, _) => 8,
            (Layout::V1_1, DatasetFile::Hierarchy) => HIERARCHY_HEAD_SIZE,
            (Layout::V1_1, _) => OCTREE_HEAD_SIZE,
        }
    }
}

/// 16 bytes made once per dataset and stored in all three files; written as 32 lowercase hex
/// digits in `metadata.json`.
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct DatasetId(pub [u8; 16]);

impl DatasetId {
    /// FNV-1a (128-bit) of `parts` in order: the same content always gives the same id, so
    /// a conversion is reproducible byte for byte, and different content gives different ids.
    pub fn of_content<'a>(parts: impl IntoIterator<Item = &'a [u8]>) -> DatasetId {
        const BASIS: u128 = 0x6c62_272e_07bb_0142_62b8_2175_6295_c58d;
        const PRIME: u128 = 0x0000_0000_0100_0000_0000_0000_0000_013b;
        let mut h = BASIS;
        for part in parts {
            // The length first, so that moving bytes between parts changes the id.
            for &b in (part.len() as u64).to_le_bytes().iter().chain(part) {
                h ^= b as u128;
                h = h.wrapping_mul(PRIME);
            }
        }
        DatasetId(h.to_le_bytes())
    }

    pub fn parse_hex(s: &str) -> Option<DatasetId> {
        if s.len() != 32 || !s.is_ascii() {
            return None;
        }
        let mut id = [0u8; 16];
        for (i, b) in id.iter_mut().enumerate() {
            *b = u8::from_str_radix(&s[2 * i..2 * i + 2], 16).ok()?;
        }
        Some(DatasetId(id))
    }
}

impl std::fmt::Display for DatasetId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for b in self.0 {
            write!(f, "{b:02x}")?;
        }
        Ok(())
    }
}

impl std::fmt::Debug for DatasetId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "DatasetId({self})")
    }
}

impl Serialize for DatasetId {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.to_string())
    }
}

impl<'de> Deserialize<'de> for DatasetId {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        DatasetId::parse_hex(&s).ok_or_else(|| {
            serde::de::Error::custom(format!("id \"{s}\" is not 32 hexadecimal digits"))
        })
    }
}

/// The head of a 1.1 `hierarchy.bin`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HierarchyHead {
    pub id: DatasetId,
    pub root_page_size: u32,
    pub page_levels: u32,
}

impl HierarchyHead {
    pub fn encode(&self) -> Vec<u8> {
        let mut out = HIERARCHY_MAGIC.to_vec();
        out.extend_from_slice(&self.id.0);
        out.extend_from_slice(&self.root_page_size.to_le_bytes());
        out.extend_from_slice(&self.page_levels.to_le_bytes());
        out
    }

    /// Reads a head whose magic has been checked; `None` when `b` is shorter than a head.
    pub fn decode(b: &[u8]) -> Option<HierarchyHead> {
        let b = b.get(..HIERARCHY_HEAD_SIZE as usize)?;
        let u32_at = |i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        Some(HierarchyHead {
            id: id_at(b)?,
            root_page_size: u32_at(24),
            page_levels: u32_at(28),
        })
    }
}

/// The head of a 1.1 `octree.bin`.
pub fn octree_head(id: DatasetId) -> Vec<u8> {
    let mut out = OCTREE_MAGIC.to_vec();
    out.extend_from_slice(&id.0);
    out
}

fn id_at(b: &[u8]) -> Option<DatasetId> {
    let mut id = [0u8; 16];
    id.copy_from_slice(b.get(8..24)?);
    Some(DatasetId(id))
}

/// Checks a binary dataset file against `metadata.json`: its magic (the layout of the
/// metadata's version), then (1.1) that it belongs to the same dataset, then its length, then
/// (1.1 `hierarchy.bin`) the root page size and page levels its head states. `path` names the
/// file (or URL) in the message; `len` is the file's length where known (an HTTP server may
/// not say); `head` is its first bytes (at least the head's size, unless the file is shorter).
/// Every reader (local, mmap, HTTP) applies this one check.
pub fn check_file_head(
    path: impl AsRef<Path>,
    file: DatasetFile,
    len: Option<u64>,
    head: &[u8],
    meta: &Metadata,
) -> Result<(), FormatError> {
    let path = path.as_ref();
    let layout = meta.layout();
    let expected = match file {
        DatasetFile::Hierarchy => meta.files.hierarchy.size,
        _ => meta.files.octree.size,
    };
    let fault = |what: String| Err(FormatError::corrupt(path, what));
    let size_fault = |len: u64| {
        fault(format!(
            "file is {len} bytes but metadata.json says {expected} (truncated or replaced)"
        ))
    };
    // A file cut inside its head, the metadata's size edited to match, is not "N bytes but
    // metadata.json says N".
    let short_head = || {
        fault(format!(
            "is {} bytes long, too short for the head of a format {} file (cut short)",
            len.unwrap_or(head.len() as u64),
            layout.name()
        ))
    };
    let magic = layout.magic(file);
    if head.get(..8) != Some(&magic[..]) {
        let other = [Layout::V1_0, Layout::V1_1]
            .into_iter()
            .find(|l| head.get(..8) == Some(&l.magic(file)[..]));
        return match (other, len) {
            (Some(l), _) => fault(format!(
                "is a format {} file but metadata.json says format {} (files of two datasets mixed)",
                l.name(),
                layout.name()
            )),
            (None, Some(len)) if len < 8 => size_fault(len),
            (None, _) => fault(format!(
                "does not start with the {:?} magic of format {}",
                String::from_utf8_lossy(magic),
                layout.name()
            )),
        };
    }
    if layout == Layout::V1_1 {
        let found = id_at(head);
        if found != meta.id {
            return match (found, meta.id) {
                (Some(found), Some(said)) => fault(format!(
                    "belongs to another dataset (id {found}, metadata.json says {said})"
                )),
                _ => short_head(),
            };
        }
    }
    if let Some(len) = len.filter(|&l| l != expected) {
        return size_fault(len);
    }
    if layout == Layout::V1_1 && file == DatasetFile::Hierarchy {
        let Some(h) = HierarchyHead::decode(head) else {
            return short_head();
        };
        let (size, levels) = (meta.hierarchy.root_page_size, meta.hierarchy.page_levels);
        if h.root_page_size as u64 != size || h.page_levels != levels {
            return fault(format!(
                "head says the root page is {} bytes in pages of {} levels but metadata.json says {size} bytes and {levels} levels",
                h.root_page_size, h.page_levels
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_print_and_parse_as_hex_and_follow_content() {
        let a = DatasetId::of_content([&b"abc"[..], b"def"]);
        let b = DatasetId::of_content([&b"abcd"[..], b"ef"]);
        assert_ne!(a, b, "the part boundaries count");
        assert_eq!(a, DatasetId::of_content([&b"abc"[..], b"def"]));
        let hex = a.to_string();
        assert_eq!(hex.len(), 32);
        assert_eq!(DatasetId::parse_hex(&hex), Some(a));
        assert_eq!(DatasetId::parse_hex("xyz"), None);
        assert_eq!(DatasetId::parse_hex(&"é".repeat(16)), None);
    }

    #[test]
    fn a_hierarchy_head_round_trips() {
        let h = HierarchyHead {
            id: DatasetId([7; 16]),
            root_page_size: 1234,
            page_levels: 5,
        };
        let b = h.encode();
        assert_eq!(b.len() as u64, HIERARCHY_HEAD_SIZE);
        assert_eq!(&b[..8], HIERARCHY_MAGIC);
        assert_eq!(HierarchyHead::decode(&b), Some(h));
        assert_eq!(HierarchyHead::decode(&b[..31]), None);
        assert_eq!(octree_head(h.id).len() as u64, OCTREE_HEAD_SIZE);
    }
}
