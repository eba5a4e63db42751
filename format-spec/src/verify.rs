//! Whole-dataset verification: structure, every checksum, every point inside its node.

use crate::{DatasetFile, LocalDataset, NodeInfo, dataset::node_infos, decode_node};
use std::path::Path;

/// One fault, naming the damaged part ("node r0412", "hierarchy page at byte 96", a file).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Fault {
    pub part: String,
    pub what: String,
}

impl std::fmt::Display for Fault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.part, self.what)
    }
}

#[derive(Debug, Clone, Default)]
pub struct VerifyReport {
    pub nodes_checked: u64,
    pub points_checked: u64,
    pub pages_checked: u64,
    pub faults: Vec<Fault>,
}

impl VerifyReport {
    pub fn is_ok(&self) -> bool {
        self.faults.is_empty()
    }
}

/// Checks a dataset directory completely. Never panics on damaged input; every fault found is
/// reported with the part it damaged.
pub fn verify_dataset(dir: &Path) -> VerifyReport {
    let mut report = VerifyReport::default();
    let ds = match LocalDataset::open(dir) {
        Ok(ds) => ds,
        Err(e) => {
            report.faults.push(Fault {
                part: "dataset".into(),
                what: e.to_string(),
            });
            return report;
        }
    };
    let meta = ds.metadata().clone();
    let octree_len = meta.files.octree.size;
    let mut nodes: Vec<NodeInfo> = Vec::new();
    let mut pages = vec![ds.root_page()];
    while let Some(p) = pages.pop() {
        match ds.load_page(&p) {
            Ok(page) => {
                report.pages_checked += 1;
                pages.extend(page.child_pages());
                nodes.extend(node_infos(&page));
            }
            Err(e) => report.faults.push(Fault {
                part: format!(
                    "hierarchy page at byte {} (nodes under {})",
                    p.offset, p.root
                ),
                what: e.to_string(),
            }),
        }
    }
    nodes.sort_by_key(|n| n.offset);
    let mut last_end = crate::OCTREE_MAGIC.len() as u64;
    let mut max_level = 0u32;
    let octree_path = ds.path_of(DatasetFile::Octree);
    for n in &nodes {
        max_level = max_level.max(n.key.level as u32);
        report.points_checked += n.point_count as u64;
        if n.point_count == 0 {
            continue;
        }
        let part = format!("node {}", n.key);
        if n.offset < last_end || n.offset + n.size as u64 > octree_len {
            report.faults.push(Fault {
                part,
                what: format!(
                    "payload range {}..{} overlaps another node or lies outside {}",
                    n.offset,
                    n.offset + n.size as u64,
                    octree_path.display()
                ),
            });
            continue;
        }
        last_end = n.offset + n.size as u64;
        let decoded = ds
            .read_payload(n)
            .map_err(|e| e.to_string())
            .and_then(|payload| {
                decode_node(&payload, n.point_count as usize, n.checksum, ds.layout())
                    .map_err(|e| e.to_string())
            });
        match decoded {
            Ok(cols) => {
                report.nodes_checked += 1;
                let (min, edge) = n.key.int_bounds(meta.cube.min, meta.cube.bits);
                let outside = (0..cols.count).find(|&i| {
                    let p = cols.position(i);
                    (0..3).any(|a| {
                        let v = p[a] as i64;
                        v < min[a] || v >= min[a] + edge
                    })
                });
                if let Some(i) = outside {
                    report.faults.push(Fault {
                        part,
                        what: format!("point {i} lies outside the node's cube"),
                    });
                }
            }
            Err(what) => report.faults.push(Fault { part, what }),
        }
    }
    let all_pages_read = report
        .faults
        .iter()
        .all(|f| !f.part.starts_with("hierarchy"));
    if all_pages_read {
        if report.points_checked != meta.points {
            report.faults.push(Fault {
                part: "metadata.json".into(),
                what: format!(
                    "says {} points but the hierarchy holds {}",
                    meta.points, report.points_checked
                ),
            });
        }
        if nodes.len() as u64 != meta.nodes {
            report.faults.push(Fault {
                part: "metadata.json".into(),
                what: format!(
                    "says {} nodes but the hierarchy holds {}",
                    meta.nodes,
                    nodes.len()
                ),
            });
        }
        if max_level != meta.depth {
            report.faults.push(Fault {
                part: "metadata.json".into(),
                what: format!(
                    "says depth {} but the deepest node is at level {max_level}",
                    meta.depth
                ),
            });
        }
    }
    report
}
