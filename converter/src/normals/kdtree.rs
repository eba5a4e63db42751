//! k nearest neighbours in a chunk and its halo: a balanced k-d tree over the points,
//! reordered so that every subtree is one contiguous range (queries in that order touch
//! memory that is already cached).
//!
//! Positions are whole quantization steps from the chunk's corner and a distance is taken
//! from their exact difference, so it depends on the two points alone, not on the chunk: the
//! same cloud cut into other chunks finds the same neighbours, bit for bit. Ties are distances
//! equal as computed (scaled to real units and rounded): two offsets of equal length in steps
//! may round apart where the scale is not a power of two, and then the nearer as rounded wins.

/// Points per leaf: about twice k, so that the query's own leaf gives a tight first bound.
pub(super) const LEAF: usize = 32;
const _: () = assert!(LEAF.is_power_of_two());

pub struct KdTree {
    /// Positions in quantization steps from the chunk's corner (whole numbers), in tree order.
    pub points: Vec<[f64; 3]>,
    /// The same positions axis by axis, for distance loops that vectorise.
    axes: [Vec<f64>; 3],
    /// Each point's index in the input order.
    pub order: Vec<u32>,
    /// Real units per step, per axis.
    pub scale: [f64; 3],
    /// Per inner node (implicit heap numbering from 1): split axis and value.
    splits: Vec<(u8, f64)>,
}

impl KdTree {
    /// Builds the tree over `points` (whole steps of `scale`, spanning less than 2^32 steps
    /// per axis, as positions read from 32-bit integers do).
    pub fn build(points: Vec<[f64; 3]>, scale: [f64; 3]) -> Self {
        let n = points.len();
        let mut min = [f64::INFINITY; 3];
        for p in &points {
            for a in 0..3 {
                min[a] = min[a].min(p[a]);
            }
        }
        // Partitioned as 16-byte items with integer keys rather than the f64 positions: the
        // median selections move half the bytes and compare integers, and the build takes
        // half the time.
        debug_assert!(
            points
                .iter()
                .all(|p| (0..3).all(|a| p[a] - min[a] <= f64::from(u32::MAX)))
        );
        let mut items: Vec<([u32; 3], u32)> = points
            .iter()
            .enumerate()
            .map(|(i, p)| ([0, 1, 2].map(|a| (p[a] - min[a]) as u32), i as u32))
            .collect();
        let mut splits = vec![(0u8, 0.0); inner_nodes(n)];
        build_node(&mut items, 1, &mut splits, scale, min);
        // Into the input's own memory, reordered: the peak is the same as with a new vector,
        // and its pages are already mapped.
        let mut points = points;
        for (p, (key, _)) in points.iter_mut().zip(&items) {
            *p = [0, 1, 2].map(|a| f64::from(key[a]) + min[a]);
        }
        let order: Vec<u32> = items.iter().map(|&(_, i)| i).collect();
        drop(items);
        // Axis by axis once the items are gone, so that the peak holds two copies, not three.
        let axes = std::array::from_fn(|a| points.iter().map(|p| p[a]).collect());
        KdTree {
            points,
            order,
            axes,
            scale,
            splits,
        }
    }

    /// The offset from point `from` to point `to` in whole steps (exact: both are whole
    /// numbers).
    #[inline]
    pub fn steps(&self, from: usize, to: usize) -> [f64; 3] {
        let (a, b) = (self.points[from], self.points[to]);
        [b[0] - a[0], b[1] - a[1], b[2] - a[2]]
    }

    /// The real offset from point `from` to point `to`, exact for the two points alone.
    #[inline]
    pub fn offset(&self, from: usize, to: usize) -> [f64; 3] {
        let (a, b) = (self.points[from], self.points[to]);
        [0, 1, 2].map(|i| (b[i] - a[i]) * self.scale[i])
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// The `k` points nearest to tree point `at` (itself included) within distance `within`,
    /// into `out`: fewer where fewer are that near.
    pub fn nearest(
        &self,
        at: usize,
        k: usize,
        within: f64,
        out: &mut Found,
        stack: &mut Vec<Pending>,
    ) {
        self.nearest_of(at, k, within, out, stack, false);
    }

    /// As `nearest`, but each position counts once: of points repeated at one position, one
    /// is taken. However many repeats lie near, the search finds the `k` nearest distinct
    /// positions (repeats share a distance, so the search meets them together).
    pub fn nearest_distinct(
        &self,
        at: usize,
        k: usize,
        within: f64,
        out: &mut Found,
        stack: &mut Vec<Pending>,
    ) {
        self.nearest_of(at, k, within, out, stack, true);
    }

    fn nearest_of(
        &self,
        at: usize,
        k: usize,
        within: f64,
        out: &mut Found,
        stack: &mut Vec<Pending>,
        distinct: bool,
    ) {
        let q = self.points[at];
        let mut best = Best::new(self, k, out, within * within);
        best.distinct = distinct;
        self.search(q, at, &mut best, stack);
    }

    /// Inner node `node`'s split: axis and value.
    pub(super) fn split(&self, node: usize) -> (usize, f64) {
        let (axis, value) = self.splits[node];
        (axis as usize, value)
    }

    /// The squared real distance from `q` to tree point `j`.
    #[inline]
    pub(super) fn distance2(&self, q: [f64; 3], j: usize) -> f64 {
        let (p, s) = (self.points[j], self.scale);
        let d = [
            (p[0] - q[0]) * s[0],
            (p[1] - q[1]) * s[1],
            (p[2] - q[2]) * s[2],
        ];
        squared_length(d)
    }

    /// Whether tree point `a` comes before `b` in position order (for ties of distance, so
    /// that they do not depend on the order points came in).
    #[inline]
    fn position_before(&self, a: u32, b: u32) -> bool {
        self.points[a as usize] < self.points[b as usize]
    }

    /// Offers `best` every leaf that may hold a point within its bound of `q` (tree point
    /// `at`), its own leaf first.
    fn search(&self, q: [f64; 3], at: usize, best: &mut Best, stack: &mut Vec<Pending>) {
        stack.clear();
        let s = self.scale;
        // Down to the leaf holding `at` by index, leaving the other sides for later with a
        // lower bound of their distance: the per-axis distances to the planes that bound them
        // (nanoflann's incremental distance), summed.
        let (mut node, mut lo, mut hi) = (1usize, 0usize, self.points.len());
        let off = [0.0f64; 3];
        while hi - lo > LEAF {
            let (axis, split) = self.splits[node];
            let a = axis as usize;
            let mid = lo + (hi - lo) / 2;
            let d = (q[a] - split) * s[a];
            let mut far_off = off;
            far_off[a] = d.abs();
            let far = if at < mid {
                (2 * node + 1, mid, hi)
            } else {
                (2 * node, lo, mid)
            };
            stack.push(Pending {
                node: far.0,
                lo: far.1,
                hi: far.2,
                off: far_off,
                plane: plane_distance2(far_off),
            });
            (node, lo, hi) = if at < mid {
                (2 * node, lo, mid)
            } else {
                (2 * node + 1, mid, hi)
            };
        }
        best.scan(q, lo, hi);
        while let Some(p) = stack.pop() {
            // Equal distances still enter (ties are broken by position), so a point on the
            // boundary counts.
            if p.plane > best.bound() {
                continue;
            }
            if p.hi - p.lo <= LEAF {
                best.scan(q, p.lo, p.hi);
                continue;
            }
            let (axis, split) = self.splits[p.node];
            let a = axis as usize;
            let mid = p.lo + (p.hi - p.lo) / 2;
            let d = (q[a] - split) * s[a];
            let left = (2 * p.node, p.lo, mid);
            let right = (2 * p.node + 1, mid, p.hi);
            let (near, far) = if d < 0.0 {
                (left, right)
            } else {
                (right, left)
            };
            // The far side: the distance along this axis grows to the plane's, at least.
            let mut far_off = p.off;
            far_off[a] = far_off[a].max(d.abs());
            let far_plane = plane_distance2(far_off);
            stack.push(Pending {
                node: far.0,
                lo: far.1,
                hi: far.2,
                off: far_off,
                plane: far_plane,
            });
            // The near side on top, to be searched first.
            stack.push(Pending {
                node: near.0,
                lo: near.1,
                hi: near.2,
                ..p
            });
        }
    }
}

/// The squared distances from `q` to the points of leaf `lo..hi`, in a loop without branches
/// the compiler can vectorise.
#[inline]
pub(super) fn leaf_distances(tree: &KdTree, q: [f64; 3], lo: usize, hi: usize) -> [f64; LEAF] {
    let s = tree.scale;
    let [x, y, z] = &tree.axes;
    let (x, y, z) = (&x[lo..hi], &y[lo..hi], &z[lo..hi]);
    let mut d2 = [f64::INFINITY; LEAF];
    for i in 0..x.len().min(y.len()).min(z.len()).min(LEAF) {
        let d = [
            (x[i] - q[0]) * s[0],
            (y[i] - q[1]) * s[1],
            (z[i] - q[2]) * s[2],
        ];
        d2[i] = squared_length(d);
    }
    d2
}

/// The squared distance bound from per-axis offsets, summed as `KdTree::distance2` sums (x,
/// then y, then z, no fused multiply-add): each term is no larger than the point's, so neither
/// is the sum, rounding included. (Updated one axis at a time instead, a bound could exceed by
/// a unit in the last place the distance of a point on the region's corner and prune a tie.)
#[inline]
fn plane_distance2(off: [f64; 3]) -> f64 {
    squared_length(off)
}

/// x² + y² + z², summed in that order: the one formula every distance and bound here uses, so
/// that they round alike.
#[inline]
pub(super) fn squared_length(d: [f64; 3]) -> f64 {
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// A subtree still to search and a lower bound on its squared distance from the query: from
/// `off`, the distances along each axis to the planes that bound it.
#[derive(Debug, Clone, Copy)]
pub struct Pending {
    node: usize,
    lo: usize,
    hi: usize,
    off: [f64; 3],
    plane: f64,
}

/// Inner nodes a tree of `n` points has at most, plus the unused slot 0.
fn inner_nodes(n: usize) -> usize {
    let mut leaves = 1usize;
    while n.div_ceil(leaves) > LEAF {
        leaves *= 2;
    }
    2 * leaves
}

/// Splits `items` (keys in steps from `min`) at the median of their longest real extent, and
/// each half again down to leaves.
fn build_node(
    items: &mut [([u32; 3], u32)],
    node: usize,
    splits: &mut [(u8, f64)],
    scale: [f64; 3],
    min: [f64; 3],
) {
    if items.len() <= LEAF {
        return;
    }
    let mut lo = [u32::MAX; 3];
    let mut hi = [0u32; 3];
    for (p, _) in items.iter() {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let extent = |a: usize| f64::from(hi[a] - lo[a]) * scale[a];
    let axis = (0..3)
        .max_by(|&a, &b| extent(a).total_cmp(&extent(b)))
        .unwrap_or(0);
    let mid = items.len() / 2;
    items.select_nth_unstable_by_key(mid, |x| x.0[axis]);
    splits[node] = (axis as u8, f64::from(items[mid].0[axis]) + min[axis]);
    let (left, right) = items.split_at_mut(mid);
    build_node(left, 2 * node, splits, scale, min);
    build_node(right, 2 * node + 1, splits, scale, min);
}

/// The neighbours a search found: squared real distances and tree indices, side by side so
/// that ranking a candidate against them vectorises. `KdTree::nearest` leaves them nearest
/// first (ties by position); `all_nearest` in no order.
#[derive(Debug, Default)]
pub struct Found {
    pub dist: Vec<f64>,
    pub index: Vec<u32>,
}

impl Found {
    pub fn with_capacity(k: usize) -> Self {
        Found {
            dist: Vec::with_capacity(k),
            index: Vec::with_capacity(k),
        }
    }

    pub fn len(&self) -> usize {
        self.dist.len()
    }

    /// The squared distance of the farthest found.
    pub fn farthest(&self) -> f64 {
        self.dist.iter().fold(0.0, |m, &d| m.max(d))
    }

    fn clear(&mut self) {
        self.dist.clear();
        self.index.clear();
    }
}

/// The k best so far.
pub(super) struct Best<'a> {
    tree: &'a KdTree,
    k: usize,
    out: &'a mut Found,
    /// The squared distance within which a point may still enter.
    bound: f64,
    /// A point whose position one already taken has does not enter.
    distinct: bool,
}

impl<'a> Best<'a> {
    /// The squared distance within which a point may still enter.
    pub(super) fn bound(&self) -> f64 {
        self.bound
    }

    /// Offers the points of leaf `lo..hi` (at most `LEAF`).
    pub(super) fn scan(&mut self, q: [f64; 3], lo: usize, hi: usize) {
        let d2 = leaf_distances(self.tree, q, lo, hi);
        for (i, d) in d2[..hi - lo].iter().enumerate() {
            if *d <= self.bound {
                self.offer(*d, (lo + i) as u32);
            }
        }
    }

    /// The k best of the points offered within squared distance `bound`, into `out`.
    pub(super) fn new(tree: &'a KdTree, k: usize, out: &'a mut Found, bound: f64) -> Self {
        out.clear();
        Best {
            tree,
            k,
            out,
            bound,
            distinct: false,
        }
    }

    /// Inserts point `j` at squared distance `d` in order, when it ranks among the k best
    /// (its place counted, the rest shifted; this measured as fast as a heap, and the array
    /// stays sorted for `nearest`'s callers).
    #[inline]
    fn offer(&mut self, d: f64, j: u32) {
        let (k, tree) = (self.k, self.tree);
        let out = &mut *self.out;
        let n = out.dist.len();
        if n == k {
            let last = out.dist[k - 1];
            if d > last || (d == last && !tree.position_before(j, out.index[k - 1])) {
                return;
            }
        }
        let mut at = out.dist.iter().map(|&x| usize::from(x < d)).sum::<usize>();
        // Equal distances sit together from `at` on; the candidate goes after those placed
        // first by position. (Repeats of one position sit side by side among them.)
        while at < n && out.dist[at] == d {
            let placed = out.index[at];
            if tree.position_before(placed, j) {
                at += 1;
            } else if self.distinct && tree.points[placed as usize] == tree.points[j as usize] {
                return;
            } else {
                break;
            }
        }
        if n < k {
            out.dist.push(d);
            out.index.push(j);
        }
        let (dist, index) = (&mut out.dist[..], &mut out.index[..]);
        for i in (at + 1..dist.len()).rev() {
            dist[i] = dist[i - 1];
            index[i] = index[i - 1];
        }
        dist[at] = d;
        index[at] = j;
        if dist.len() == k {
            self.bound = dist[k - 1];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cloud on a coarse grid (many equal distances) with one axis scaled differently.
    fn cloud() -> KdTree {
        let mut seed = 7u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 40) as i32 % 200
        };
        let points: Vec<[f64; 3]> = (0..3000)
            .map(|_| [next(), next(), next() / 8].map(f64::from))
            .collect();
        KdTree::build(points, [0.5, 0.5, 2.0])
    }

    /// The `k` nearest of `at` within `within` by comparing with every point: (squared
    /// distance, position), nearest first, ties by position.
    fn brute_force(tree: &KdTree, at: usize, k: usize, within: f64) -> Vec<(f64, [f64; 3])> {
        let mut all: Vec<(f64, [f64; 3])> = (0..tree.len())
            .map(|i| {
                let d = tree.offset(at, i);
                (d[0] * d[0] + d[1] * d[1] + d[2] * d[2], tree.points[i])
            })
            .filter(|(d, _)| *d <= within * within)
            .collect();
        all.sort_by(|a, b| {
            a.0.total_cmp(&b.0)
                .then(a.1.partial_cmp(&b.1).unwrap_or(std::cmp::Ordering::Equal))
        });
        all.truncate(k);
        all
    }

    /// What `found` holds, nearest first, ties by position.
    fn listed(tree: &KdTree, found: &Found) -> Vec<(f64, [f64; 3])> {
        let mut all: Vec<(f64, [f64; 3])> = found
            .dist
            .iter()
            .zip(&found.index)
            .map(|(&d, &i)| (d, tree.points[i as usize]))
            .collect();
        all.sort_by(|a, b| {
            a.0.total_cmp(&b.0)
                .then(a.1.partial_cmp(&b.1).unwrap_or(std::cmp::Ordering::Equal))
        });
        all
    }

    #[test]
    fn finds_the_same_neighbours_as_brute_force() {
        let tree = cloud();
        let (mut out, mut stack) = (Found::default(), Vec::new());
        // Without bound, and within one that cuts some neighbourhoods short.
        for within in [f64::INFINITY, 9.0] {
            for at in (0..tree.len()).step_by(37) {
                tree.nearest(at, 16, within, &mut out, &mut stack);
                assert_eq!(
                    listed(&tree, &out),
                    brute_force(&tree, at, 16, within),
                    "query {at} within {within}"
                );
            }
        }
    }

    /// A regular lattice: nearly every neighbourhood ends in a tie of distances.
    fn lattice(scale: f64) -> KdTree {
        let points: Vec<[f64; 3]> = (0..24 * 24 * 3)
            .map(|i| [i % 24, i / 24 % 24, i / 576].map(|c| f64::from(c as u32)))
            .collect();
        KdTree::build(points, [scale; 3])
    }

    #[test]
    fn all_nearest_breaks_ties_by_position() {
        // 0.25 a step squares exactly; 0.001 does not, so bounds and distances round.
        for scale in [0.25, 0.001] {
            let tree = lattice(scale);
            // k = 40 is more than a leaf holds: each point searched from the root.
            for k in [7, 16, 30, 40] {
                tree.all_nearest(
                    k,
                    f64::INFINITY,
                    |_| true,
                    |at, found| {
                        assert_eq!(
                            listed(&tree, found),
                            brute_force(&tree, at, k, f64::INFINITY),
                            "query {at} k {k} scale {scale}"
                        );
                    },
                );
            }
        }
    }

    #[test]
    fn all_nearest_finds_the_same_neighbours_as_brute_force() {
        let tree = cloud();
        // k below and above the leaves' sizes (23 and 24 points here), and 24, where some
        // leaves hold k points and some fewer; with and without bound; and k = 250, where a
        // query's bound reaches more candidate leaves than it tests at a time.
        for (k, within) in [
            (16, f64::INFINITY),
            (16, 9.0),
            (12, 30.0),
            (24, f64::INFINITY),
            (24, 9.0),
            (40, 9.0),
            (40, f64::INFINITY),
            (250, 40.0),
        ] {
            let mut seen = 0;
            tree.all_nearest(
                k,
                within,
                |t| t % 7 == 0,
                |at, found| {
                    assert_eq!(at % 7, 0, "only the points asked for");
                    seen += 1;
                    assert_eq!(
                        listed(&tree, found),
                        brute_force(&tree, at, k, within),
                        "query {at} k {k} within {within}"
                    );
                },
            );
            assert_eq!(seen, tree.len().div_ceil(7));
        }
    }
}
