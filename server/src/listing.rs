//! The JSON list of datasets in the served directory.

use serde::Serialize;
use std::path::Path;
use strata_format::Metadata;

#[derive(Debug, Serialize)]
pub struct DatasetEntry {
    pub name: String,
    pub points: u64,
    pub nodes: u64,
    pub depth: u32,
    pub bounds: strata_format::Bounds,
    pub bytes: u64,
}

/// Every directory directly under `root` that holds a readable `metadata.json`.
pub fn list(root: &Path) -> Vec<DatasetEntry> {
    let Ok(dir) = std::fs::read_dir(root) else {
        return Vec::new();
    };
    let mut out: Vec<DatasetEntry> = dir
        .filter_map(Result::ok)
        .filter_map(|e| {
            let name = e.file_name().to_str()?.to_string();
            if name.starts_with('.') {
                return None;
            }
            let meta_path = e.path().join("metadata.json");
            let bytes = std::fs::read(&meta_path).ok()?;
            let m = Metadata::from_json(&bytes, &meta_path).ok()?;
            Some(DatasetEntry {
                name,
                points: m.points,
                nodes: m.nodes,
                depth: m.depth,
                bounds: m.bounds,
                bytes: bytes.len() as u64 + m.files.hierarchy.size + m.files.octree.size,
            })
        })
        .collect();
    out.sort_by(|a, b| a.name.cmp(&b.name));
    out
}
