//! The k nearest neighbours of every point, a leaf of the k-d tree at a time. The leaves that
//! may hold a neighbour of any point of a leaf are found once, by one walk down the tree, and
//! each of the leaf's points then checks those alone against the tight boxes around their
//! points: no walk from the root per point, and tighter boxes than the splitting planes give.
//! The neighbours found are the same set as `KdTree::nearest`'s, ties included, in no order.

use super::kdtree::{Best, Found, KdTree, LEAF, leaf_distances, squared_length};
use super::select::Taken;

/// Consecutive leaves (neighbours in space) whose candidates are gathered together.
const GROUP: usize = 8;

/// Candidate leaves a query tests at a time before scanning those it needs (a leaf has about
/// 24 candidates).
const LISTED: usize = 32;

/// A leaf: its range of tree points and the tight box around them, in steps.
#[derive(Debug, Clone, Copy)]
struct Leaf {
    lo: usize,
    hi: usize,
    min: [f64; 3],
    max: [f64; 3],
}

/// The leaves a leaf's points search.
struct Scope<'a> {
    /// The points' own leaf, and the query's squared distances to its points.
    leaf: usize,
    own: &'a [f64; LEAF],
    candidates: &'a [Candidate],
    leaves: &'a [Leaf],
}

/// A leaf that may hold neighbours, and its squared gap to the queries' leaf.
type Candidate = (f64, usize);

impl KdTree {
    /// Calls `each(t, found)` for every tree point `t` that `wanted` picks, in tree order, with
    /// its `k` nearest points within distance `within` (the set `nearest` finds, in no order).
    pub fn all_nearest(
        &self,
        k: usize,
        within: f64,
        wanted: impl Fn(usize) -> bool,
        mut each: impl FnMut(usize, &Found),
    ) {
        let leaves = self.leaves();
        let within2 = within * within;
        let mut found = Found::with_capacity(k);
        let mut candidates: Vec<Candidate> = Vec::new();
        let mut stack = Vec::new();
        // The neighbours found of the leaf's points done so far.
        let mut done_found: Vec<u32> = Vec::new();
        let mut last_done: Vec<u32> = Vec::new();
        let mut taken = Taken::default();
        let mut outside: Vec<f64> = Vec::with_capacity(k);
        let mut group: (usize, Vec<Candidate>) = (usize::MAX, Vec::new());
        // The position `found` holds the neighbours of.
        let mut searched_from: Option<[f64; 3]> = None;
        for (li, leaf) in leaves.iter().enumerate() {
            if !(leaf.lo..leaf.hi).any(&wanted) {
                continue;
            }
            // A leaf of repeats of the position just searched (a heap of them fills many
            // leaves) has its neighbours already: gathering the leaves near it would walk
            // the whole heap again.
            let wanted_points = (leaf.lo..leaf.hi).filter(|&t| wanted(t));
            if searched_from.is_some()
                && wanted_points
                    .clone()
                    .all(|t| Some(self.points[t]) == searched_from)
            {
                for t in wanted_points {
                    each(t, &found);
                }
                if found.len() == k {
                    last_done.clear();
                    last_done.extend_from_slice(&found.index);
                }
                continue;
            }
            let reach2 = self.reach2(leaf, k, within2);
            if !reach2.is_finite() {
                // No bound on the search (a cloud without a density estimate): one point at a
                // time.
                for t in (leaf.lo..leaf.hi).filter(|&t| wanted(t)) {
                    if searched_from != Some(self.points[t]) {
                        self.nearest(t, k, within, &mut found, &mut stack);
                        searched_from = Some(self.points[t]);
                    }
                    each(t, &found);
                }
                continue;
            }
            // The leaves near the leaf's group, found once for the group, then those near
            // the leaf.
            let g = li / GROUP;
            if group.0 != g {
                group = (g, self.group_candidates(&leaves, g, k, within2));
            }
            candidates.clear();
            candidates.extend(group.1.iter().filter_map(|&(_, c)| {
                let other = &leaves[c];
                let gap = gap2(
                    &other.min, &other.max, &leaf.min, &leaf.max, self.scale, false,
                );
                (gap <= reach2).then_some((gap, c))
            }));
            candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
            // For each point of the leaf whose k neighbours are known, where they are in
            // `done_found` (k each).
            let mut slot = [usize::MAX; LEAF];
            done_found.clear();
            for t in (leaf.lo..leaf.hi).filter(|&t| wanted(t)) {
                let q = self.points[t];
                // A repeat of the position just searched has its neighbours: searching
                // again would meet every repeat at distance 0 (a heap of n points, n² work).
                if searched_from != Some(q) {
                    let own = leaf_distances(self, q, leaf.lo, leaf.hi);
                    // The leaf's point nearest to q whose k neighbours are known: they are k
                    // points, so q's k-th nearest is no farther than the farthest of them.
                    let mut nearest_done = (f64::INFINITY, usize::MAX);
                    // Points are done in tree order: those done lie before q in its leaf.
                    let before = t - leaf.lo;
                    for (&d, &s) in own[..before].iter().zip(&slot[..before]) {
                        let d = if s == usize::MAX { f64::INFINITY } else { d };
                        nearest_done = if d < nearest_done.0 {
                            (d, s)
                        } else {
                            nearest_done
                        };
                    }
                    // With none done yet in this leaf, the last point done before it (in the leaf
                    // before, a neighbour in space) gives the bound.
                    let hint = match nearest_done.1 {
                        usize::MAX if last_done.len() == k => Some(&last_done[..]),
                        usize::MAX => None,
                        s => Some(&done_found[s * k..(s + 1) * k]),
                    };
                    if let Some(hint) = hint {
                        // The hint's points outside the leaf, by distance (those inside are in
                        // `own`): with the leaf's, a tighter bound where k of them are nearer.
                        outside.resize(k, 0.0);
                        for (o, &j) in outside.iter_mut().zip(hint) {
                            *o = self.distance2(q, j as usize);
                        }
                        let bound = farthest(&outside);
                        for (o, &j) in outside.iter_mut().zip(hint) {
                            if (leaf.lo..leaf.hi).contains(&(j as usize)) {
                                *o = f64::INFINITY;
                            }
                        }
                        let bound = tighter(bound.min(within2), k, &own, &outside);
                        let scope = Scope {
                            leaf: li,
                            own: &own,
                            candidates: &candidates,
                            leaves: &leaves,
                        };
                        self.within_bound(q, k, bound, &scope, &mut taken, &mut found);
                    } else {
                        let mut best = Best::new(self, k, &mut found, within2);
                        best.scan(q, leaf.lo, leaf.hi);
                        for &(gap, c) in &candidates {
                            if gap > best.bound() {
                                break;
                            }
                            let other = &leaves[c];
                            // Equal distances still enter (ties are broken by position), so a
                            // leaf at the bound is searched.
                            if c != li && self.box_gap2(q, other) <= best.bound() {
                                best.scan(q, other.lo, other.hi);
                            }
                        }
                    }
                    searched_from = Some(q);
                }
                each(t, &found);
                if found.len() == k {
                    slot[t - leaf.lo] = done_found.len() / k;
                    done_found.extend_from_slice(&found.index);
                }
            }
            if let Some(last) = done_found.len().checked_sub(k) {
                last_done.clear();
                last_done.extend_from_slice(&done_found[last..]);
            }
        }
    }

    /// The leaves within reach (`reach2`) of some point of group `g` (leaves `g × GROUP` on).
    fn group_candidates(
        &self,
        leaves: &[Leaf],
        g: usize,
        k: usize,
        within2: f64,
    ) -> Vec<Candidate> {
        let members = &leaves[g * GROUP..((g + 1) * GROUP).min(leaves.len())];
        let mut union = members[0];
        let mut reach2 = 0.0f64;
        for m in members {
            for a in 0..3 {
                union.min[a] = union.min[a].min(m.min[a]);
                union.max[a] = union.max[a].max(m.max[a]);
            }
            // A leaf without a bound searches a point at a time and needs no candidates.
            let r = self.reach2(m, k, within2);
            if r.is_finite() {
                reach2 = reach2.max(r);
            }
        }
        let mut out = Vec::new();
        if reach2.is_finite() {
            self.gather(
                1,
                0,
                self.len(),
                Region::all(),
                &union,
                reach2,
                leaves,
                &mut out,
            );
        }
        out
    }

    /// How far, squared, the k nearest of any point of `leaf` can be: within the leaf's
    /// diagonal where it holds k points (those), and within `within2` in any case.
    fn reach2(&self, leaf: &Leaf, k: usize, within2: f64) -> f64 {
        if leaf.hi - leaf.lo >= k {
            gap2(&leaf.min, &leaf.max, &leaf.min, &leaf.max, self.scale, true).min(within2)
        } else {
            within2
        }
    }

    /// The squared real distance from `q` to the nearest point of `leaf`'s box.
    #[inline]
    fn box_gap2(&self, q: [f64; 3], leaf: &Leaf) -> f64 {
        gap2(&q, &q, &leaf.min, &leaf.max, self.scale, false)
    }

    /// Into `found`, the k nearest of `q` among the points of the leaves in `scope`, given
    /// that they are all within squared distance `bound`: every point within it is taken,
    /// without a branch per point, then the k best of those selected (nearest, then by
    /// position). `found` is in no order.
    fn within_bound(
        &self,
        q: [f64; 3],
        k: usize,
        bound: f64,
        scope: &Scope,
        taken: &mut Taken,
        found: &mut Found,
    ) {
        let mut m = 0;
        // A leaf's points are written to a window of LEAF slots from `m` on, each over the
        // last unless taken.
        let mut take = |d2: &[f64; LEAF], lo: usize, hi: usize| {
            let points = &mut taken.points;
            if points.len() < m + LEAF {
                points.resize(m + LEAF, (0.0, 0));
            }
            let window = &mut points[m..m + LEAF];
            let mut j = 0;
            for (i, &d) in d2[..(hi - lo).min(LEAF)].iter().enumerate() {
                // j ≤ i < LEAF, a power of two: the mask changes nothing but spares a check.
                window[j & (LEAF - 1)] = (d, (lo + i) as u32);
                j += usize::from(d <= bound);
            }
            m += j;
        };
        let own = &scope.leaves[scope.leaf];
        take(scope.own, own.lo, own.hi);
        // The candidates come in order of their boxes' gap to the query's leaf, and no point
        // of a candidate is nearer the query than its box is to that leaf: once a gap exceeds
        // the bound, so does every point of the rest. Of those before, the leaves whose box
        // is within the bound of the query itself are listed without a branch per leaf (a
        // branch there, taken by about a third of them in no pattern, is mispredicted often),
        // then scanned.
        let within = scope.candidates.partition_point(|&(gap, _)| gap <= bound);
        for some in scope.candidates[..within].chunks(LISTED) {
            let mut listed = [0u32; LISTED];
            let mut n = 0;
            for &(_, c) in some {
                listed[n] = c as u32;
                n += usize::from(c != scope.leaf && self.box_gap2(q, &scope.leaves[c]) <= bound);
            }
            for &c in &listed[..n] {
                let other = &scope.leaves[c as usize];
                take(
                    &leaf_distances(self, q, other.lo, other.hi),
                    other.lo,
                    other.hi,
                );
            }
        }
        // The k nearest by distance alone, then, where the k-th distance is shared with
        // points left out, those ties settled by position.
        let n = taken.select_nearest(m, k, bound);
        let nearest = if n > k {
            // The k nearest, ties by position, are among those picked.
            let picked = &mut taken.picked[..n];
            picked.sort_unstable_by(|a, b| {
                a.0.total_cmp(&b.0).then_with(|| {
                    let (p, r) = (self.points[a.1 as usize], self.points[b.1 as usize]);
                    p.partial_cmp(&r).unwrap_or(std::cmp::Ordering::Equal)
                })
            });
            &picked[..k]
        } else {
            &taken.picked[..n]
        };
        found.dist.clear();
        found.index.clear();
        found.dist.extend(nearest.iter().map(|p| p.0));
        found.index.extend(nearest.iter().map(|p| p.1));
    }

    /// The leaves in tree order with their tight boxes.
    fn leaves(&self) -> Vec<Leaf> {
        let mut out = Vec::with_capacity(self.len() / (LEAF / 2) + 1);
        let mut ranges = vec![(0usize, self.len())];
        while let Some((lo, hi)) = ranges.pop() {
            if hi - lo > LEAF {
                let mid = lo + (hi - lo) / 2;
                // Right first, so that the left comes off the stack first: tree order.
                ranges.push((mid, hi));
                ranges.push((lo, mid));
                continue;
            }
            let mut min = [f64::INFINITY; 3];
            let mut max = [f64::NEG_INFINITY; 3];
            for p in &self.points[lo..hi] {
                for a in 0..3 {
                    min[a] = min[a].min(p[a]);
                    max[a] = max[a].max(p[a]);
                }
            }
            out.push(Leaf { lo, hi, min, max });
        }
        out
    }

    /// Adds to `out` the leaves under `node` (points `lo..hi`, inside `region`) whose points
    /// may lie within squared distance `reach2` of some point of `leaf`.
    #[allow(clippy::too_many_arguments)]
    fn gather(
        &self,
        node: usize,
        lo: usize,
        hi: usize,
        region: Region,
        leaf: &Leaf,
        reach2: f64,
        leaves: &[Leaf],
        out: &mut Vec<Candidate>,
    ) {
        if gap2(
            &region.min,
            &region.max,
            &leaf.min,
            &leaf.max,
            self.scale,
            false,
        ) > reach2
        {
            return;
        }
        if hi - lo <= LEAF {
            let i = leaves.partition_point(|l| l.lo < lo);
            if let Some(other) = leaves.get(i) {
                let g = gap2(
                    &other.min, &other.max, &leaf.min, &leaf.max, self.scale, false,
                );
                if g <= reach2 {
                    out.push((g, i));
                }
            }
            return;
        }
        let (axis, split) = self.split(node);
        let mid = lo + (hi - lo) / 2;
        // A point equal to the split value may lie on either side.
        let mut left = region;
        left.max[axis] = split;
        let mut right = region;
        right.min[axis] = split;
        self.gather(2 * node, lo, mid, left, leaf, reach2, leaves, out);
        self.gather(2 * node + 1, mid, hi, right, leaf, reach2, leaves, out);
    }
}

/// The closed box a subtree's points lie in, from the splitting planes above it.
#[derive(Debug, Clone, Copy)]
struct Region {
    min: [f64; 3],
    max: [f64; 3],
}

impl Region {
    fn all() -> Self {
        Region {
            min: [f64::NEG_INFINITY; 3],
            max: [f64::INFINITY; 3],
        }
    }
}

/// The squared real distance between boxes `a` and `b` (in steps), or with `span` the squared
/// diagonal of `a`. No larger than the squared distance of any point of `a` to any of `b` as
/// `KdTree` computes it, rounding included: each term is rounded the same way from a smaller or
/// equal difference, and summed by the same `squared_length`.
#[inline]
fn gap2(
    a_min: &[f64; 3],
    a_max: &[f64; 3],
    b_min: &[f64; 3],
    b_max: &[f64; 3],
    scale: [f64; 3],
    span: bool,
) -> f64 {
    squared_length(std::array::from_fn(|i| {
        // Comparisons rather than `f64::max`, whose NaN rules cost instructions: no
        // coordinate here is NaN.
        let d = if span {
            a_max[i] - a_min[i]
        } else {
            let (below, above) = (b_min[i] - a_max[i], a_min[i] - b_max[i]);
            let d = if below > above { below } else { above };
            if d > 0.0 { d } else { 0.0 }
        };
        d * scale[i]
    }))
}

/// `bound`, or a fraction of it within which `k` of the points at squared distances `own` and
/// `outside` (distinct points) lie, so that fewer candidates are taken.
fn tighter(bound: f64, k: usize, own: &[f64; LEAF], outside: &[f64]) -> f64 {
    let mut best = bound;
    for f in [0.85, 0.7, 0.55] {
        let t = bound * f;
        let n = own.iter().map(|&d| usize::from(d <= t)).sum::<usize>()
            + outside.iter().map(|&d| usize::from(d <= t)).sum::<usize>();
        if n < k {
            break;
        }
        best = t;
    }
    best
}

/// The largest of `d` (none NaN), or 0: in four independent lanes, not one chain of
/// dependent comparisons.
fn farthest(d: &[f64]) -> f64 {
    let mut lanes = [0.0f64; 4];
    let mut quads = d.chunks_exact(4);
    for q in &mut quads {
        for (l, &x) in lanes.iter_mut().zip(q) {
            *l = if x > *l { x } else { *l };
        }
    }
    for &x in quads.remainder() {
        lanes[0] = if x > lanes[0] { x } else { lanes[0] };
    }
    lanes.iter().fold(0.0, |m, &x| if x > m { x } else { m })
}
