//! Scan lines far apart for their spacing along them (a mobile scanner's profiles, a
//! profiler's lines): a point's k nearest all lie on its own line, where no plane fits, though
//! the lines beside it lie within the search radius. Its neighbourhood then grows, four times
//! at a time up to `WIDEST` points, within the same radius, until it spans a plane. The points
//! of a line alone (a wire) still get none; what a point gets depends on the points within the
//! search radius only, as every estimate does, so chunk borders still change nothing.

use super::kdtree::{Found, KdTree, Pending};
use super::pca::{Principal, covariance_of_steps, dot, principal};

/// The most points a grown neighbourhood takes: the most `--normal-k` allows.
pub const WIDEST: usize = 256;

/// Room for the searches that grow a neighbourhood.
#[derive(Default)]
pub struct Wider {
    stack: Vec<Pending>,
    pub found: Found,
}

/// A neighbourhood grown until it spans a plane.
pub struct Grown {
    pub pc: Principal,
    /// How many points it was searched for.
    pub size: usize,
    /// The covering radius of the lines: how far a spot between the point's line and the
    /// nearest beside it can lie from every sample (half the gap across, half the spacing
    /// along, at right angles). The density's disc (a Poisson sample's) is far smaller where
    /// the lines lie far apart for their spacing, and would leave strips open between them.
    pub cover: f64,
}

impl Wider {
    /// Grown from `line`, the `k` nearest of tree point `t` (within `within`, all on one line),
    /// the first neighbourhood (into `self.found`) that spans a plane; `None` where the search
    /// radius holds none of up to `WIDEST` points.
    pub fn plane(
        &mut self,
        tree: &KdTree,
        t: usize,
        line: (&Found, Principal),
        within: f64,
        scale: [f64; 3],
    ) -> Option<Grown> {
        let (near, line_pc) = line;
        let mut size = near.len();
        while size < WIDEST {
            size = (size * 4).min(WIDEST);
            tree.nearest_distinct(t, size, within, &mut self.found, &mut self.stack);
            let steps = self.found.index.iter().map(|&j| tree.steps(t, j as usize));
            let pc = principal(covariance_of_steps(steps, scale));
            if self.found.len() >= 3 && pc.spans_a_plane(scale) {
                let cover = self.cover(tree, t, near, line_pc.major(), scale);
                return Some(Grown { pc, size, cover });
            }
            if self.found.len() < size {
                // Every point within the radius was seen.
                return None;
            }
        }
        None
    }

    /// See `Grown::cover`: `near` lies on the line through tree point `t` along `along`.
    fn cover(
        &self,
        tree: &KdTree,
        t: usize,
        near: &Found,
        along: [f64; 3],
        scale: [f64; 3],
    ) -> f64 {
        let off_line = |j: u32| {
            let d: [f64; 3] = {
                let s = tree.steps(t, j as usize);
                [0, 1, 2].map(|a| s[a] * scale[a])
            };
            let on = dot(d, along);
            (dot(d, d) - on * on).max(0.0).sqrt()
        };
        // The line's own points stray from it by the grid's rounding.
        let step = scale.iter().fold(0.0f64, |m, s| m.max(s.abs()));
        let thickness = near.index.iter().fold(0.0f64, |m, &j| m.max(off_line(j))) + step;
        let gap = self
            .found
            .index
            .iter()
            .map(|&j| off_line(j))
            .filter(|&d| d > thickness)
            .fold(f64::INFINITY, f64::min);
        let spacing = near
            .dist
            .iter()
            .filter(|&&d| d > 0.0)
            .fold(f64::INFINITY, |m, &d| m.min(d))
            .sqrt();
        if gap.is_finite() && spacing.is_finite() {
            (0.25 * gap * gap + 0.25 * spacing * spacing).sqrt()
        } else {
            0.0
        }
    }
}
