//! The known part of the hierarchy, and the per-frame choice of nodes under the point budget.

use crate::camera::{Camera, Frustum};
use crate::dataset::StreamDataset;
use crate::error::ViewerError;
use glam::Vec3;
use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap, HashSet};
use strata_format::{HierarchyPage, NodeInfo, NodeKey, PageRef};

/// Nodes described by the hierarchy pages loaded so far, and the pages not yet loaded.
#[derive(Default)]
pub struct Tree {
    nodes: HashMap<NodeKey, NodeInfo>,
    /// The spacing each node's points were measured at when it was loaded
    /// (`dataset::sampling`), where they told one.
    sampling: HashMap<NodeKey, f32>,
    /// Pages known from a loaded page but not loaded themselves, by their root (a proxy).
    unloaded_pages: HashMap<NodeKey, PageRef>,
    loaded_pages: HashSet<NodeKey>,
    /// Whose page lies at each byte of the hierarchy file that a known page refers to.
    page_owners: HashMap<u64, NodeKey>,
}

impl Tree {
    /// The tree of `ds` as its root page describes it; an error where that page refers to
    /// itself.
    pub fn of(ds: &StreamDataset) -> Result<Tree, ViewerError> {
        Tree::with_root(ds.root_hierarchy_page(), ds.root_page())
            .map_err(|what| ViewerError::source(ds.location(), what))
    }

    /// The tree of a root page `page`, which lies at `at`.
    fn with_root(page: &HierarchyPage, at: PageRef) -> Result<Tree, String> {
        let mut tree = Tree::default();
        tree.page_owners.insert(at.offset, at.root);
        tree.add_page(page)?;
        Ok(tree)
    }

    /// Takes in a page's nodes (in 1.1 its proxies too, whose payloads it locates) and the
    /// pages below it. A page that another node's proxy already refers to is left out, and
    /// is the error: read again under this proxy, the same nodes would come twice, or without
    /// end where a page refers to itself (a damaged or forged hierarchy).
    pub fn add_page(&mut self, page: &HierarchyPage) -> Result<(), String> {
        self.loaded_pages.insert(page.root);
        self.unloaded_pages.remove(&page.root);
        for info in page.nodes() {
            self.nodes.insert(info.key, info);
        }
        let mut fault = Ok(());
        for child in page.child_pages() {
            let owner = *self.page_owners.entry(child.offset).or_insert(child.root);
            if owner != child.root {
                fault = Err(format!(
                    "the hierarchy page at byte {} is referred to by the proxies of nodes {owner} and {}",
                    child.offset, child.root
                ));
            } else if !self.loaded_pages.contains(&child.root) {
                self.unloaded_pages.insert(child.root, child);
            }
        }
        fault
    }

    /// A page that failed to load: its subtree is left out for the rest of the session.
    pub fn drop_page(&mut self, root: NodeKey) {
        self.unloaded_pages.remove(&root);
    }

    pub fn node(&self, key: NodeKey) -> Option<&NodeInfo> {
        self.nodes.get(&key)
    }

    /// Keeps what a loaded node's points measured (`GpuNode::sampling`).
    pub fn measured(&mut self, key: NodeKey, spacing: Option<f32>) {
        if let Some(s) = spacing {
            self.sampling.insert(key, s);
        }
    }

    /// The spacing node `key`'s points were measured at, once it has been loaded.
    pub fn sampling(&self, key: NodeKey) -> Option<f32> {
        self.sampling.get(&key).copied()
    }

    /// The page rooted at `key` that is known but not loaded: in 1.1 the one holding a
    /// proxy's children, in 1.0 the one holding the proxy `key` itself.
    pub fn unloaded_page(&self, key: NodeKey) -> Option<PageRef> {
        self.unloaded_pages.get(&key).copied()
    }

    pub fn known_nodes(&self) -> usize {
        self.nodes.len()
    }
}

/// What the view asks for.
#[derive(Debug, Clone, Copy)]
pub struct SelectionParams {
    pub budget: u64,
    pub width: u32,
    pub height: u32,
    /// Stop refining where a node's point spacing projects below this many pixels.
    pub min_spacing_px: f32,
}

/// The clip boxes of the frame relative to the anchor: a node that can hold no point they keep
/// is neither drawn nor loaded.
#[derive(Debug, Clone, Default)]
pub struct ClipRegion {
    /// Boxes that keep their inside.
    pub keep: Vec<(Vec3, Vec3)>,
    /// Boxes that hide their inside.
    pub hide: Vec<(Vec3, Vec3)>,
}

impl ClipRegion {
    /// Whether a node cube from `min` to `max` may hold a point the boxes keep.
    pub fn admits(&self, min: Vec3, max: Vec3) -> bool {
        let meets = |(lo, hi): &(Vec3, Vec3)| min.cmple(*hi).all() && max.cmpge(*lo).all();
        let within = |(lo, hi): &(Vec3, Vec3)| min.cmpge(*lo).all() && max.cmple(*hi).all();
        (self.keep.is_empty() || self.keep.iter().any(meets)) && !self.hide.iter().any(within)
    }
}

/// The outcome of one selection: what to draw and what to fetch, most important first.
#[derive(Debug, Default)]
pub struct Selection {
    /// Resident nodes to draw.
    pub draw: Vec<NodeKey>,
    /// Points in `draw`.
    pub draw_points: u64,
    /// Nodes the view wants that are not resident, with their priority.
    pub missing_nodes: Vec<(NodeInfo, f32)>,
    /// Hierarchy pages the view wants, with their priority.
    pub missing_pages: Vec<(PageRef, f32)>,
    /// Points of every node chosen under the budget, resident or not.
    pub chosen_points: u64,
}

#[derive(PartialEq)]
struct Candidate {
    priority: f32,
    key: NodeKey,
}

impl Eq for Candidate {}

impl Ord for Candidate {
    fn cmp(&self, other: &Self) -> Ordering {
        self.priority
            .total_cmp(&other.priority)
            .then_with(|| other.key.cmp(&self.key))
    }
}

impl PartialOrd for Candidate {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// Chooses nodes by projected size until the budget is reached. Children are visited only
/// below resident nodes, so detail arrives coarse to fine, and only where the parent's point
/// spacing is still coarser than `min_spacing_px` on screen.
pub fn select(
    tree: &Tree,
    ds: &StreamDataset,
    camera: &Camera,
    params: &SelectionParams,
    resident: impl Fn(NodeKey) -> bool,
    failed: &HashSet<NodeKey>,
    clip: &ClipRegion,
) -> Selection {
    let aspect = params.width as f32 / params.height.max(1) as f32;
    let (near, far) = clip_range(ds, camera, aspect);
    let frustum = Frustum::of_view(camera, aspect, near, far);
    let focal = camera.focal_px(params.height);
    let mut out = Selection::default();
    let mut heap = BinaryHeap::new();
    let (root_min, root_edge) = ds.node_cube(NodeKey::ROOT);
    let root_max = root_min + Vec3::splat(root_edge);
    if tree.node(NodeKey::ROOT).is_some()
        && frustum.intersects_box(root_min, root_max)
        && clip.admits(root_min, root_max)
    {
        heap.push(Candidate {
            priority: f32::MAX,
            key: NodeKey::ROOT,
        });
    }
    while let Some(Candidate { priority, key }) = heap.pop() {
        let Some(info) = tree.node(key) else { continue };
        let count = info.point_count as u64;
        if out.chosen_points + count > params.budget {
            break;
        }
        out.chosen_points += count;
        let (min, edge) = ds.node_cube(key);
        let distance = box_distance(camera.eye, min, min + Vec3::splat(edge)).max(near);
        let refines = ds.node_spacing(key) / distance * focal >= params.min_spacing_px;
        // 1.1: a proxy whose page is not loaded. Its page holds its children's entries.
        let page_below = tree.unloaded_pages.get(&key);
        let is_failed = failed.contains(&key);
        if !is_failed && !resident(key) {
            out.missing_nodes.push((*info, priority));
            // The proxy locates both its payload and its page: ask for the page now, beside
            // the node, so the children are known when the node arrives.
            if let Some(page) = page_below.filter(|_| refines) {
                out.missing_pages.push((*page, priority));
            }
            continue;
        }
        if !is_failed {
            out.draw.push(key);
            out.draw_points += count;
        }
        if !refines {
            continue;
        }
        let mut want_page_below: Option<f32> = None;
        for octant in 0..8u8 {
            if info.child_mask & (1 << octant) == 0 {
                continue;
            }
            let child = key.child(octant);
            let (cmin, cedge) = ds.node_cube(child);
            let cmax = cmin + Vec3::splat(cedge);
            if !frustum.intersects_box(cmin, cmax) || !clip.admits(cmin, cmax) {
                continue;
            }
            let priority = node_priority(camera.eye, cmin, cedge, focal);
            if tree.node(child).is_some() {
                heap.push(Candidate {
                    priority,
                    key: child,
                });
            } else if let Some(page) = tree.unloaded_pages.get(&child) {
                // 1.0: the child is a proxy, known only from its page.
                out.missing_pages.push((*page, priority));
            } else if page_below.is_some() {
                want_page_below = Some(want_page_below.map_or(priority, |p| p.max(priority)));
            }
        }
        if let (Some(page), Some(priority)) = (page_below, want_page_below) {
            out.missing_pages.push((*page, priority));
        }
    }
    out
}

/// Projected size in pixels; the node holding the camera comes before everything else.
fn node_priority(eye: Vec3, min: Vec3, edge: f32, focal: f32) -> f32 {
    let max = min + Vec3::splat(edge);
    if eye.cmpge(min).all() && eye.cmple(max).all() {
        return f32::MAX / 2.0;
    }
    let centre = min + Vec3::splat(edge * 0.5);
    let radius = edge * 0.866;
    let distance = (centre - eye).length().max(radius * 0.5);
    radius / distance * focal
}

fn box_distance(p: Vec3, min: Vec3, max: Vec3) -> f32 {
    (p.clamp(min, max) - p).length()
}

/// Automatic near and far planes that enclose the dataset's bounds as seen from the eye, in a
/// view of `aspect` (width / height). The near plane lies in front of every point of the
/// bounds that the view can show: no nearer along the view axis than the box's nearest corner,
/// nor than its nearest point seen at the view's widest angle (a point off the axis is nearer
/// along it than its distance).
pub fn clip_range(ds: &StreamDataset, camera: &Camera, aspect: f32) -> (f32, f32) {
    let (min, max) = ds.bounds();
    let radius = ((max - min) * 0.5).length().max(1e-3);
    let centre = (min + max) * 0.5;
    let to_centre = (centre - camera.eye).length();
    let far = (to_centre + radius) * 1.01;
    let forward = (camera.target - camera.eye).normalize_or(Vec3::Y);
    let nearest_depth = crate::camera::box_corners(min, max)
        .into_iter()
        .map(|corner| (corner - camera.eye).dot(forward))
        .fold(f32::INFINITY, f32::min);
    // The widest angle from the axis a view shows: towards a corner of the image.
    let half_diagonal = (camera.fov_y * 0.5).tan() * (1.0 + aspect * aspect).sqrt();
    let widest_cos = 1.0 / (1.0 + half_diagonal * half_diagonal).sqrt();
    let nearest = box_distance(camera.eye, min, max) * widest_cos;
    // Inside the bounds the nearest surface can be close (a wall a hand's width away in a scan
    // kilometres deep): the clip tests compare linear depths (`Frame::near`), exact at any
    // ratio, so the floor is only the f32 positions' own resolution at that distance.
    let near = (nearest.max(nearest_depth) * 0.9).max(far * 1e-7);
    (near, far)
}

/// The metric spacing of the points drawn, for the pyramid pipeline's default s0: the median,
/// over the finest drawn node at each place, of the spacing of the points that cover it (its
/// own, plus a quarter of its parent's per level up, since a surface crossing a cube takes
/// about a quarter of its parent's area). A node's own points are taken at the spacing they
/// were measured at (`Tree::sampling`); before it is measured, at its edge over the root of
/// their count, as if the surface crossing it covered its face once. `None` when nothing is
/// drawn.
pub fn drawn_spacing(tree: &Tree, ds: &StreamDataset, draw: &[NodeKey]) -> Option<f32> {
    let drawn: HashSet<NodeKey> = draw.iter().copied().collect();
    let has_drawn_child: HashSet<NodeKey> = draw.iter().filter_map(|k| k.parent()).collect();
    let mut spacings: Vec<f32> = draw
        .iter()
        .filter(|k| !has_drawn_child.contains(k))
        .filter_map(|&key| {
            let mut cover = 0.0f64;
            let mut share = 1.0f64;
            let mut at = Some(key);
            while let Some(k) = at {
                if drawn.contains(&k) {
                    cover += tree.node(k).map_or(0.0, |n| n.point_count as f64) * share;
                }
                share *= 0.25;
                at = k.parent();
            }
            // The area the points cover: each point takes a square of the spacing.
            let own = tree.node(key).map_or(0, |n| n.point_count) as f64;
            let area = match tree.sampling(key) {
                Some(s) if own > 0.0 => own * (s as f64).powi(2),
                _ => (ds.node_cube(key).1 as f64).powi(2),
            };
            (cover >= 1.0).then(|| (area / cover).sqrt() as f32)
        })
        .collect();
    if spacings.is_empty() {
        return None;
    }
    let mid = spacings.len() / 2;
    let (_, median, _) = spacings.select_nth_unstable_by(mid, f32::total_cmp);
    Some(*median)
}

#[cfg(test)]
mod tests {
    use super::*;
    use strata_format::{EntryKind, Layout, PageEntry};

    /// A page at `root` whose two proxies, children 0 and 1 of the root, lead to the pages
    /// at `offsets`.
    fn page(root: NodeKey, offsets: [u64; 2]) -> HierarchyPage {
        let entry = |kind, child_mask| PageEntry {
            kind,
            child_mask,
            point_count: 1,
            offset: 0,
            size: 1,
            checksum: 0,
        };
        let children = [0u8, 1].map(|o| root.child(o));
        HierarchyPage {
            root,
            layout: Layout::V1_1,
            entries: vec![
                (root, entry(EntryKind::Node, 0b11)),
                (children[0], entry(EntryKind::Proxy, 1)),
                (children[1], entry(EntryKind::Proxy, 1)),
            ],
            children: (0..2)
                .map(|i| PageRef {
                    root: children[i],
                    offset: offsets[i],
                    size: 64,
                    checksum: Some(0),
                })
                .collect(),
        }
    }

    /// Two proxies leading to one page would read its nodes twice, under two keys; a page
    /// that leads back to one already known (its own: every proxy of a forged root page did)
    /// without end. Either is an error, and only the first proxy's page is taken.
    #[test]
    fn a_page_two_proxies_lead_to_is_refused() {
        let mut tree = Tree::default();
        let err = tree.add_page(&page(NodeKey::ROOT, [100, 100]));
        assert!(
            err.is_err_and(|e| e.contains("byte 100")),
            "two proxies, one page"
        );
        let first = NodeKey::ROOT.child(0);
        assert!(tree.unloaded_page(first).is_some());
        assert!(tree.unloaded_page(NodeKey::ROOT.child(1)).is_none());
        // The first proxy's page, whose own proxies lead to the root page's byte again.
        tree.page_owners.insert(32, NodeKey::ROOT);
        assert!(
            tree.add_page(&page(first, [32, 200])).is_err(),
            "a page leading back"
        );
        // A root page whose proxies lead back to it (every one of a forged root page did).
        let at = |offset| PageRef {
            root: NodeKey::ROOT,
            offset,
            size: 64,
            checksum: None,
        };
        let looping = page(NodeKey::ROOT, [100, 32]);
        assert!(Tree::with_root(&looping, at(32)).is_err_and(|e| e.contains("byte 32")));
        assert!(Tree::with_root(&looping, at(500)).is_ok());
        assert!(tree.unloaded_page(first.child(1)).is_some());
        let sound = page(first.child(1), [300, 400]);
        assert_eq!(tree.add_page(&sound), Ok(()));
    }
}
