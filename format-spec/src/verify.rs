//! Whole-dataset verification: heads, structure, every checksum, every point inside its node.

use crate::{
    DatasetFile, DatasetId, FormatError, Layout, LocalDataset, NodeInfo, NodeKey, PageRef,
    decode_node,
};
use std::collections::{BTreeMap, HashMap};
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
    /// The format version `metadata.json` states, once it has been read.
    pub version: Option<[u32; 2]>,
    /// The dataset id (format 1.1), checked against both files' heads.
    pub id: Option<DatasetId>,
    /// Every node of the hierarchy, each once, nodes without points included: what
    /// `metadata.json`'s `nodes` counts.
    pub nodes_checked: u64,
    /// Of those, the nodes without points.
    pub empty_nodes: u64,
    pub points_checked: u64,
    pub pages_checked: u64,
    /// Proxies followed to their pages (in 1.1 each also compared with its page's root entry).
    pub proxies_checked: u64,
    pub faults: Vec<Fault>,
}

impl VerifyReport {
    pub fn is_ok(&self) -> bool {
        self.faults.is_empty()
    }

    fn fault(&mut self, part: impl Into<String>, what: impl Into<String>) {
        self.faults.push(Fault {
            part: part.into(),
            what: what.into(),
        });
    }
}

fn page_part(p: &PageRef) -> String {
    format!(
        "hierarchy page at byte {} (nodes under {})",
        p.offset, p.root
    )
}

/// Checks a dataset directory completely. Never panics on damaged input; every fault found is
/// reported with the part it damaged.
pub fn verify_dataset(dir: &Path) -> VerifyReport {
    let mut report = VerifyReport::default();
    let ds = match LocalDataset::open(dir) {
        Ok(ds) => ds,
        Err(e) => {
            report.fault("dataset", e.to_string());
            return report;
        }
    };
    let meta = ds.metadata().clone();
    report.version = Some(meta.version);
    report.id = meta.id;
    // The root's spacing follows from the cube (SPEC.md); a reader sizes points by it.
    let spacing = meta.scale[0] * 2f64.powi(meta.cube.bits as i32) / 128.0;
    if !meta.spacing.is_finite() || (meta.spacing - spacing).abs() > 1e-9 * spacing.abs() {
        report.fault(
            "metadata.json",
            format!(
                "gives spacing {} where its cube's (scale[0] * 2^{} / 128) is {spacing}",
                meta.spacing, meta.cube.bits
            ),
        );
    }
    let (nodes, pages_ok) = check_pages(&ds, &mut report);
    let seen = check_nodes(&ds, &nodes, &mut report);
    let (max_level, extent) = (seen.max_level, seen.extent);
    report.nodes_checked = nodes.len() as u64;
    // Counted from every point only where every node decoded: one that failed would show
    // as a count or a bound off, beside its own fault.
    if pages_ok && seen.complete && !meta.classes.is_empty() && meta.classes != seen.classes {
        report.fault(
            "metadata.json",
            format!(
                "counts the points by class as {:?}, but they are {:?}",
                meta.classes, seen.classes
            ),
        );
    }
    if pages_ok {
        if report.points_checked != meta.points {
            report.fault(
                "metadata.json",
                format!(
                    "says {} points but the hierarchy holds {}",
                    meta.points, report.points_checked
                ),
            );
        }
        if nodes.len() as u64 != meta.nodes {
            report.fault(
                "metadata.json",
                format!(
                    "says {} nodes but the hierarchy holds {}",
                    meta.nodes,
                    nodes.len()
                ),
            );
        }
        // The bounds are the stored points' own (a reader frames and culls by them).
        if let Some((lo, hi)) = extent.filter(|_| seen.complete) {
            let real = |a: usize, v: i32| meta.offset[a] + meta.scale[a] * v as f64;
            // A point whose coordinate is not a finite number (a scale that overflows them)
            // is off any bounds.
            let off = |stated: f64, a: usize, v: i32| {
                let want = real(a, v);
                !want.is_finite()
                    || (stated - want).abs() > 0.5 * meta.scale[a].abs() + 1e-9 * want.abs()
            };
            if (0..3)
                .any(|a| off(meta.bounds.min[a], a, lo[a]) || off(meta.bounds.max[a], a, hi[a]))
            {
                report.fault(
                    "metadata.json",
                    format!(
                        "gives bounds {:?} to {:?}, but the points span {:?} to {:?}",
                        meta.bounds.min,
                        meta.bounds.max,
                        [0, 1, 2].map(|a| real(a, lo[a])),
                        [0, 1, 2].map(|a| real(a, hi[a])),
                    ),
                );
            }
        }
        if max_level != meta.depth {
            report.fault(
                "metadata.json",
                format!(
                    "says depth {} but the deepest node is at level {max_level}",
                    meta.depth
                ),
            );
        }
    }
    report
}

/// Reads every page from the root: checksums and shapes (in `load_page`), each page read once,
/// proxies equal to the roots of their pages (1.1), and the pages' places in the file. Returns
/// every node once, and whether every page could be read.
fn check_pages(ds: &LocalDataset, report: &mut VerifyReport) -> (Vec<NodeInfo>, bool) {
    let layout = ds.metadata().layout();
    let mut nodes = Vec::new();
    let mut all_read = true;
    // Page offset to its size, for the placement check; a page reached twice is a fault.
    let mut extents: BTreeMap<u64, u64> = BTreeMap::new();
    // 1.1: the node each proxy describes, to compare with the root entry of its page.
    let mut proxied: HashMap<NodeKey, NodeInfo> = HashMap::new();
    let mut pages = vec![ds.root_page()];
    while let Some(p) = pages.pop() {
        if extents.insert(p.offset, p.size).is_some() {
            report.fault(page_part(&p), "is referenced by more than one proxy");
            all_read = false;
            continue;
        }
        let page = match ds.load_page(&p) {
            Ok(page) => page,
            Err(e) => {
                // The file and the page once each: a decoding fault names the page already.
                match e {
                    FormatError::Corrupt { path, what } => {
                        let file = path.file_name().map_or_else(
                            || path.display().to_string(),
                            |n| n.to_string_lossy().into_owned(),
                        );
                        let what = match what.starts_with("hierarchy page at byte") {
                            true => what,
                            false => format!("{}: {what}", page_part(&p)),
                        };
                        report.fault(file, what)
                    }
                    e => report.fault(page_part(&p), e.to_string()),
                }
                all_read = false;
                continue;
            }
        };
        report.pages_checked += 1;
        if let (Some(proxy), Some(root)) = (proxied.remove(&p.root), page.root_node())
            && proxy != root
        {
            report.fault(
                page_part(&p),
                format!(
                    "its root entry ({} points, payload {} bytes at {}, mask {:#04x}) differs from the proxy that points to it ({} points, payload {} bytes at {}, mask {:#04x})",
                    root.point_count,
                    root.size,
                    root.offset,
                    root.child_mask,
                    proxy.point_count,
                    proxy.size,
                    proxy.offset,
                    proxy.child_mask
                ),
            );
        }
        for proxy in page.proxies() {
            report.proxies_checked += 1;
            if let Some(node) = proxy.node {
                proxied.insert(proxy.key, node);
            }
        }
        pages.extend(page.child_pages());
        nodes.extend(page.own_nodes());
    }
    if all_read {
        check_page_places(ds, layout, &extents, report);
    }
    (nodes, all_read)
}

/// Pages must not overlap; in 1.1 they also fill the file from the head to the end.
fn check_page_places(
    ds: &LocalDataset,
    layout: Layout,
    extents: &BTreeMap<u64, u64>,
    report: &mut VerifyReport,
) {
    let part = ds.path_of(DatasetFile::Hierarchy).display().to_string();
    let mut end = layout.head_size(DatasetFile::Hierarchy);
    for (&offset, &size) in extents {
        if offset < end {
            report.fault(
                &part,
                format!("the page at byte {offset} overlaps the head or the page before it"),
            );
        } else if offset > end && layout == Layout::V1_1 {
            report.fault(&part, format!("bytes {end}..{offset} belong to no page"));
        }
        end = end.max(offset.saturating_add(size));
    }
    let len = ds.metadata().files.hierarchy.size;
    if end < len && layout == Layout::V1_1 {
        report.fault(&part, format!("bytes {end}..{len} belong to no page"));
    }
}

/// Every node's payload: its place in `octree.bin`, checksum, decompression and points inside
/// the node's cube; in 1.1 a node without points has offset, size and checksum 0 (checked when
/// its page was decoded). Returns the deepest level.
/// The smallest and largest integer position per axis.
type Extent = ([i32; 3], [i32; 3]);

/// Checks every node's payload; returns the deepest level and the integer extent of the
/// points that decoded.
/// What the nodes' points add up to.
struct NodesSeen {
    max_level: u32,
    extent: Option<Extent>,
    /// Points per classification code, as `metadata.json` keys them.
    classes: BTreeMap<String, u64>,
    /// Whether every node with points decoded: the extent and the classes are then whole.
    complete: bool,
}

fn check_nodes(ds: &LocalDataset, nodes: &[NodeInfo], report: &mut VerifyReport) -> NodesSeen {
    let meta = ds.metadata();
    let layout = meta.layout();
    let class = ds
        .layout()
        .index_of("classification")
        .map(|i| (i, ds.layout().attributes[i].ty));
    let mut class_counts: BTreeMap<u64, u64> = BTreeMap::new();
    let mut complete = true;
    let octree_len = meta.files.octree.size;
    let octree_path = ds.path_of(DatasetFile::Octree);
    let mut by_offset: Vec<&NodeInfo> = nodes.iter().collect();
    by_offset.sort_by_key(|n| n.offset);
    let mut last_end = layout.head_size(DatasetFile::Octree);
    let mut max_level = 0u32;
    let mut extent: Option<Extent> = None;
    for n in by_offset {
        max_level = max_level.max(n.key.level as u32);
        report.points_checked += n.point_count as u64;
        let part = format!("node {}", n.key);
        if n.key.level as u32 > meta.cube.bits {
            complete = false;
            report.fault(
                part,
                format!(
                    "lies at level {} but the cube of 2^{} units splits to level {} at most",
                    n.key.level, meta.cube.bits, meta.cube.bits
                ),
            );
            continue;
        }
        if n.point_count == 0 {
            // 1.0 writers stored a one-byte block for such a node; 1.0 readers never read it.
            report.empty_nodes += 1;
            continue;
        }
        let end = n.offset.saturating_add(n.size as u64);
        if n.offset < last_end || end > octree_len {
            complete = false;
            report.fault(
                part,
                format!(
                    "payload range {}..{end} overlaps another node or lies outside {}",
                    n.offset,
                    octree_path.display()
                ),
            );
            continue;
        }
        last_end = end;
        let decoded = ds
            .read_payload(n)
            .map_err(|e| e.to_string())
            .and_then(|payload| {
                decode_node(&payload, n.point_count as usize, n.checksum, ds.layout())
                    .map_err(|e| e.to_string())
            });
        match decoded {
            Ok(cols) => {
                for i in 0..cols.count {
                    let p = cols.position(i);
                    let (lo, hi) = extent.get_or_insert((p, p));
                    for a in 0..3 {
                        lo[a] = lo[a].min(p[a]);
                        hi[a] = hi[a].max(p[a]);
                    }
                }
                if let Some((i, ty)) = class {
                    let col = cols.attribute(ds.layout(), i);
                    for v in col.chunks_exact(ty.size()).take(cols.count) {
                        *class_counts.entry(ty.read_f64(v) as u64).or_default() += 1;
                    }
                }
                if let Some(i) = cols.first_outside(n.key, meta.cube.min, meta.cube.bits) {
                    report.fault(part, format!("point {i} lies outside the node's cube"));
                }
            }
            Err(what) => {
                complete = false;
                report.fault(part, what);
            }
        }
    }
    NodesSeen {
        max_level,
        extent,
        classes: class_counts
            .into_iter()
            .map(|(c, n)| (c.to_string(), n))
            .collect(),
        complete,
    }
}
