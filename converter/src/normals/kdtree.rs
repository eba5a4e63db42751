//! k nearest neighbours in a chunk and its halo: a balanced k-d tree over the points,
//! reordered so that every subtree is one contiguous range (queries in that order touch
//! memory that is already cached).
//!
//! Positions are whole quantization steps from the chunk's corner and a distance is taken
//! from their exact difference, so it depends on the two points alone, not on the chunk: the
//! same cloud cut into other chunks finds the same neighbours, bit for bit.

/// Points per leaf: about twice k, so that the query's own leaf gives a tight first bound.
const LEAF: usize = 32;

pub struct KdTree {
    /// Positions in quantization steps from the chunk's corner (whole numbers), in tree order.
    pub points: Vec<[f64; 3]>,
    /// Each point's index in the input order.
    pub order: Vec<u32>,
    /// Real units per step, per axis.
    pub scale: [f64; 3],
    /// Per inner node (implicit heap numbering from 1): split axis and value.
    splits: Vec<(u8, f64)>,
}

/// A neighbour found: squared distance in real units and tree index.
pub type Neighbour = (f64, u32);

impl KdTree {
    /// Builds the tree over `points` (whole steps of `scale`).
    pub fn build(points: Vec<[f64; 3]>, scale: [f64; 3]) -> Self {
        let n = points.len();
        let mut items: Vec<([f64; 3], u32)> = points
            .into_iter()
            .enumerate()
            .map(|(i, p)| (p, i as u32))
            .collect();
        let mut splits = vec![(0u8, 0.0); inner_nodes(n)];
        build_node(&mut items, 1, &mut splits, scale);
        let mut tree = KdTree {
            points: Vec::with_capacity(n),
            order: Vec::with_capacity(n),
            scale,
            splits,
        };
        for (p, i) in items {
            tree.points.push(p);
            tree.order.push(i);
        }
        tree
    }

    /// The offset from point `from` to point `to` in whole steps.
    #[inline]
    pub fn steps(&self, from: usize, to: usize) -> [i64; 3] {
        let (a, b) = (self.points[from], self.points[to]);
        [0, 1, 2].map(|i| (b[i] - a[i]) as i64)
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
    /// in no order, into `out`: fewer where fewer are that near.
    pub fn nearest(
        &self,
        at: usize,
        k: usize,
        within: f64,
        out: &mut Vec<Neighbour>,
        stack: &mut Vec<Pending>,
    ) {
        out.clear();
        stack.clear();
        let q = self.points[at];
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
                plane: far_off.iter().map(|v| v * v).sum(),
            });
            (node, lo, hi) = if at < mid {
                (2 * node, lo, mid)
            } else {
                (2 * node + 1, mid, hi)
            };
        }
        let mut best = Best::new(self, k, out, within * within);
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
            let far_plane = p.plane - p.off[a] * p.off[a] + far_off[a] * far_off[a];
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

/// Position order, for ties.
pub fn ranks_before(tree: &KdTree, a: u32, b: u32) -> bool {
    let (p, q) = (tree.points[a as usize], tree.points[b as usize]);
    p.partial_cmp(&q) == Some(std::cmp::Ordering::Less)
}

/// A subtree still to search and a lower bound on its squared distance from the query: the
/// sum of `off`, the distances along each axis to the planes that bound it.
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

fn build_node(
    items: &mut [([f64; 3], u32)],
    node: usize,
    splits: &mut [(u8, f64)],
    scale: [f64; 3],
) {
    if items.len() <= LEAF {
        return;
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for (p, _) in items.iter() {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let axis = (0..3)
        .max_by(|&a, &b| ((hi[a] - lo[a]) * scale[a]).total_cmp(&((hi[b] - lo[b]) * scale[b])))
        .unwrap_or(0);
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |x, y| x.0[axis].total_cmp(&y.0[axis]));
    splits[node] = (axis as u8, items[mid].0[axis]);
    let (left, right) = items.split_at_mut(mid);
    build_node(left, 2 * node, splits, scale);
    build_node(right, 2 * node + 1, splits, scale);
}

/// The k best so far as a binary max-heap: the worst, which a better candidate replaces, on
/// top.
struct Best<'a> {
    tree: &'a KdTree,
    k: usize,
    out: &'a mut Vec<Neighbour>,
    /// The squared distance within which a point may still enter.
    bound: f64,
}

impl<'a> Best<'a> {
    fn new(tree: &'a KdTree, k: usize, out: &'a mut Vec<Neighbour>, bound: f64) -> Self {
        Best {
            tree,
            k,
            out,
            bound,
        }
    }

    fn bound(&self) -> f64 {
        self.bound
    }

    /// Whether neighbour `a` ranks before `b`: nearer, or as near and first in position
    /// order (so that ties do not depend on the order points came in).
    fn before(&self, a: Neighbour, b: Neighbour) -> bool {
        a.0 < b.0 || (a.0 == b.0 && ranks_before(self.tree, a.1, b.1))
    }

    /// Offers the points of leaf `lo..hi` (at most `LEAF`).
    fn scan(&mut self, q: [f64; 3], lo: usize, hi: usize) {
        // Distances first, in a loop without branches the compiler can vectorise; the
        // branchy offers after.
        let s = self.tree.scale;
        let mut d2 = [f64::INFINITY; LEAF];
        for (out, p) in d2.iter_mut().zip(&self.tree.points[lo..hi]) {
            let d = [
                (p[0] - q[0]) * s[0],
                (p[1] - q[1]) * s[1],
                (p[2] - q[2]) * s[2],
            ];
            *out = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        }
        for (i, d) in d2[..hi - lo].iter().enumerate() {
            if *d <= self.bound {
                self.offer((*d, (lo + i) as u32));
            }
        }
    }

    fn offer(&mut self, cand: Neighbour) {
        if self.out.len() < self.k {
            self.out.push(cand);
            let mut at = self.out.len() - 1;
            while at > 0 {
                let up = (at - 1) / 2;
                if !self.before(self.out[up], self.out[at]) {
                    break;
                }
                self.out.swap(up, at);
                at = up;
            }
        } else if self.before(cand, self.out[0]) {
            self.out[0] = cand;
            let n = self.out.len();
            let mut at = 0;
            loop {
                let (l, r) = (2 * at + 1, 2 * at + 2);
                let mut top = at;
                if l < n && self.before(self.out[top], self.out[l]) {
                    top = l;
                }
                if r < n && self.before(self.out[top], self.out[r]) {
                    top = r;
                }
                if top == at {
                    break;
                }
                self.out.swap(top, at);
                at = top;
            }
        } else {
            return;
        }
        if self.out.len() == self.k {
            self.bound = self.out[0].0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_same_neighbours_as_brute_force() {
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
        let tree = KdTree::build(points, [0.5, 0.5, 2.0]);
        let (mut out, mut stack) = (Vec::new(), Vec::new());
        for at in (0..tree.len()).step_by(37) {
            tree.nearest(at, 16, f64::INFINITY, &mut out, &mut stack);
            let mut all: Vec<(f64, [f64; 3])> = (0..tree.len())
                .map(|i| {
                    let d = tree.offset(at, i);
                    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2], tree.points[i])
                })
                .collect();
            let order = |a: &(f64, [f64; 3]), b: &(f64, [f64; 3])| {
                a.0.total_cmp(&b.0)
                    .then(a.1.partial_cmp(&b.1).unwrap_or(std::cmp::Ordering::Equal))
            };
            all.sort_by(order);
            let mut got: Vec<(f64, [f64; 3])> = out
                .iter()
                .map(|&(d, i)| (d, tree.points[i as usize]))
                .collect();
            got.sort_by(order);
            assert_eq!(got, all[..16].to_vec(), "query {at}");
        }
    }
}
