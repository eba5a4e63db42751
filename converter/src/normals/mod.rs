//! `strata convert --normals`: per point, by principal component analysis of its k nearest
//! neighbours (the chunk's points and the halo around it), the normal, the surface variation
//! σ = λ0 / (λ0 + λ1 + λ2) and a disc radius; and paper 001's global surfel size. Runs as the
//! per-chunk step of the conversion, so it works out of core like the rest of it.

mod all_nearest;
mod attrs;
mod coverage;
mod duplicates;
mod kdtree;
mod pca;
mod row_order;
mod select;
mod surfel_size;
mod widen;

use crate::chunk_step::{ChunkRows, ChunkStep, Halo, StepTotals};
use crate::error::{ConvertError, Result};
use crate::prepare::Plan;
use attrs::Targets;
use duplicates::Distinct;
use kdtree::KdTree;
use pca::{covariance_of_steps, dot, principal};
#[cfg(test)]
use strata_format::AttrType;
use strata_format::{Attribute, Metadata, NormalsInfo, row_position};
use surfel_size::{REGION, SAMPLE_EVERY, TriangleSizes, cluster};
use widen::Wider;

/// Which normals the step estimates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum NormalMode {
    /// Keep the inputs' normals where a point has one; estimate the others.
    Keep,
    /// Estimate every normal, replacing the inputs'.
    Compute,
}

/// Which way an estimated normal points (PCA gives a line, not a direction).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Orient {
    /// Towards the scanner where the input says where it stood (or `--viewpoint`), else up.
    Auto,
    /// Towards +z: airborne and mobile data.
    Up,
    /// Towards the point's scanner; refused when no input says where scanners stood.
    Scanner,
    /// As the analysis gives it.
    None,
}

#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NormalOptions {
    /// Points per neighbourhood, the point itself included.
    pub k: usize,
    pub mode: NormalMode,
    pub orient: Orient,
    /// Where a single static scanner stood, in real coordinates.
    pub viewpoint: Option<[f64; 3]>,
    /// Neighbours farther than this (real units) are not used, so that a point's estimate
    /// depends on its surroundings alone, however the cloud is cut into chunks. Default: from
    /// the inputs' density.
    pub radius: Option<f64>,
}

impl Default for NormalOptions {
    fn default() -> Self {
        NormalOptions {
            k: 16,
            mode: NormalMode::Keep,
            orient: Orient::Auto,
            viewpoint: None,
            radius: None,
        }
    }
}

/// For a random (Poisson) sample of a surface with k points within r_k, discs of radius
/// r_k · √(ln 100 / k) leave 1% of the surface uncovered (the uncovered share of a Poisson
/// disc cover is e^(−ρπr²) and ρπr_k² = k); on a scanner's regular grid they leave none.
const COVER: f64 = 2.145_966_026_289_347; // √(ln 100)

/// The search radius is this many times the distance to the k-th neighbour expected where
/// points are sparser than 90% of them.
const SEARCH_FACTOR: f64 = 2.0;

/// The estimate's rules, in a run's fingerprint: a run begun by a build that estimated
/// otherwise (before points that fit no plane got none; before neighbourhoods on one line
/// grew; before the radius at a surface's edge took the share of the disc its neighbours fill)
/// does not resume into a mix of both.
pub(crate) const RULES: u32 = 4;

/// The surface variation of a point with no normal: the most any neighbourhood has (an
/// isotropic one), since none of its planes fits.
const NO_PLANE_VARIATION: f64 = 1.0 / 3.0;

/// Warn when more than this share of the points have their radius cut to the search radius:
/// those are too sparse for the search to see how sparse, and their discs leave gaps.
const CAPPED_WARNING: f64 = 0.02;

/// Indices into the step's totals.
mod total {
    pub const COMPUTED: usize = 0;
    pub const KEPT: usize = 1;
    pub const PARTIAL: usize = 2;
    pub const RADIUS_SUM: usize = 3;
    pub const TRIANGLE_RADIUS_SUM: usize = 4;
    pub const TRIANGLES: usize = 5;
    pub const NO_NORMAL: usize = 6;
    pub const CAPPED: usize = 7;
    /// Points whose input radius `--normals compute` replaced.
    pub const RADIUS_REPLACED: usize = 8;
    pub const LEN: usize = 9;
}

pub struct NormalStep {
    opts: NormalOptions,
    /// The search radius of this run, once the plan has given it (for the metadata).
    search: std::sync::OnceLock<f64>,
}

impl NormalStep {
    pub fn new(opts: NormalOptions) -> Result<Self> {
        if !(3..=256).contains(&opts.k) {
            return Err(ConvertError::Usage(format!(
                "--normal-k {} is out of range (3 to 256 neighbours)",
                opts.k
            )));
        }
        if let Some(r) = opts.radius
            && !(r > 0.0 && r.is_finite())
        {
            return Err(ConvertError::Usage(format!(
                "--normal-radius {r} must be a positive distance"
            )));
        }
        if let Some(v) = opts.viewpoint
            && v.iter().any(|c| !c.is_finite())
        {
            return Err(ConvertError::Usage(
                "--viewpoint must be three finite numbers".into(),
            ));
        }
        Ok(NormalStep {
            opts,
            search: std::sync::OnceLock::new(),
        })
    }

    fn orient_name(&self, has_scanners: bool) -> &'static str {
        match self.opts.orient {
            Orient::Auto if has_scanners || self.opts.viewpoint.is_some() => "scanner",
            Orient::Auto | Orient::Up => "up",
            Orient::Scanner => "scanner",
            Orient::None => "none",
        }
    }
}

impl ChunkStep for NormalStep {
    fn fingerprint(&self) -> String {
        format!("normals:{RULES}:{:?}", self.opts)
    }

    fn attributes(&self, inputs: &[Attribute]) -> Result<Vec<Attribute>> {
        if self.opts.orient == Orient::Scanner
            && self.opts.viewpoint.is_none()
            && !inputs.iter().any(|a| a.name == attrs::SCANNER)
        {
            return Err(ConvertError::Usage(
                "--orient scanner needs to know where the scanner stood: give --viewpoint X,Y,Z or an E57 input with scan poses".into(),
            ));
        }
        attrs::added(inputs)
    }

    fn bytes_per_point(&self, _stride: usize) -> usize {
        // The positions (kept as the tree's), with the tree's order and, while the tree is
        // built, (position, index) items; once they are gone, the positions again, axis by
        // axis; its leaves' boxes (64 bytes a leaf of 16 or more points); and while the rows
        // are put in its order (in place), their sources and a flag each.
        24 + 4 + 24 + 4 + 4 + 1
    }

    fn halo_margin(&self, plan: &Plan) -> f64 {
        let r = self
            .opts
            .radius
            .unwrap_or_else(|| search_radius(plan, self.opts.k));
        *self.search.get_or_init(|| r)
    }

    fn process(&self, chunk: &mut ChunkRows, halo: &Halo) -> Result<StepTotals> {
        let layout = chunk.layout;
        let targets = Targets::find(layout)?;
        let stride = layout.stride;
        let own = chunk.rows.len() / stride;
        let mut totals = vec![0.0; total::LEN];
        if own == 0 {
            return Ok(totals);
        }
        let scale = chunk.scale;
        // Whole steps from the chunk's corner (see `kdtree`).
        let origin = chunk.bounds.min;
        let steps = |q: [i32; 3]| [0, 1, 2].map(|a| (q[a] as i64 - origin[a]) as f64);
        let points: Vec<[f64; 3]> = chunk
            .rows
            .chunks_exact(stride)
            .map(|r| steps(row_position(r)))
            .chain(halo.rows().map(|r| steps(row_position(r))))
            .collect();
        let tree = KdTree::build(points, scale);
        let search = halo.margin();
        // Not capped at the chunk's points: how many a chunk (and its halo) holds depends on
        // how the cloud was cut, and a point's values must not.
        let k = self.opts.k;
        let at = Placement {
            offset: chunk.offset,
            scanners: chunk.scanners,
        };
        // The rows in the order the search visits them, so that reading and writing them runs
        // through memory once (rows may come in any order; the tree sorts them afterwards).
        let source: Vec<u32> = tree
            .order
            .iter()
            .copied()
            .filter(|&i| (i as usize) < own)
            .collect();
        row_order::permute_rows(chunk.rows, stride, &source);
        drop(source);
        let mut next_row = 0;
        let rows = &mut *chunk.rows;
        let opts = &self.opts;
        let mut distinct = Distinct::default();
        let mut wider = Wider::default();
        tree.all_nearest(
            k,
            search,
            |t| (tree.order[t] as usize) < own,
            |t, near| {
                let i = next_row;
                next_row += 1;
                let near = if Distinct::repeats(&tree, near) {
                    distinct.nearest(&tree, t, k, search);
                    &distinct.found
                } else {
                    near
                };
                let steps = near.index.iter().map(|&j| tree.steps(t, j as usize));
                let pc = principal(covariance_of_steps(steps, scale));
                let mut plane = near.len() >= 3 && pc.spans_a_plane(scale);
                if near.len() < k {
                    totals[total::PARTIAL] += 1.0;
                }
                // k on one line, with more within the radius: perhaps one scan line of several.
                let grown = match plane || near.len() < k {
                    true => None,
                    false => wider.plane(&tree, t, (near, pc), search, scale),
                };
                let (near, pc, k, cover) = match grown {
                    Some(g) => {
                        plane = true;
                        (&wider.found, g.pc, g.size, g.cover)
                    }
                    None => (near, pc, k, 0.0),
                };
                // At a surface's open edge the neighbours fill part of the disc, and the
                // density they measure is that much too low (`coverage`).
                let edge = match plane {
                    true => {
                        let offsets = near.index.iter().map(|&j| tree.offset(t, j as usize));
                        coverage::angular_cover(offsets, pc.normal).sqrt()
                    }
                    false => 1.0,
                };
                let radius = if !plane {
                    // No surface to cover: a disc as wide as the gap to its nearest neighbour
                    // (a wire's points touch), and a point alone within the search radius (a
                    // bird, a stray return) the disc of the density the search radius was made
                    // for, not one as wide as the search (which the density formula gives).
                    let nearest = near
                        .dist
                        .iter()
                        .filter(|&&d| d > 0.0)
                        .fold(f64::INFINITY, |m, &d| m.min(d));
                    if nearest.is_finite() {
                        nearest.sqrt()
                    } else if search.is_finite() {
                        search * COVER / ((k as f64).sqrt() * SEARCH_FACTOR)
                    } else {
                        0.0
                    }
                } else if near.len() < k {
                    // Fewer than k within the search radius: the k-th is beyond it, and the
                    // density is what the n found within it give, ρπR² = n; no farther than
                    // the search looked.
                    let n = near.len() as f64;
                    if search.is_finite() {
                        let r = search * COVER / n.sqrt() * edge;
                        if r >= search {
                            totals[total::CAPPED] += 1.0;
                        }
                        r.min(search)
                    } else {
                        // No bound on the search (no density estimate): every point was
                        // found, and the farthest of them gives the density.
                        near.farthest().sqrt() * COVER / n.sqrt() * edge
                    }
                } else {
                    near.farthest().sqrt() * COVER / (k as f64).sqrt() * edge
                }
                .max(cover);
                let p = tree.points[t];
                let q = [0, 1, 2].map(|a| (p[a] + origin[a] as f64) * scale[a]);
                let row = &mut rows[i * stride..(i + 1) * stride];
                // An input's disc (a splat's size) is kept as its normal is.
                match (opts.mode, targets.radius(row)) {
                    (NormalMode::Keep, Some(given)) => totals[total::RADIUS_SUM] += given,
                    (mode, given) => {
                        if mode == NormalMode::Compute && given.is_some() {
                            totals[total::RADIUS_REPLACED] += 1.0;
                        }
                        totals[total::RADIUS_SUM] += radius;
                        targets.put_radius(row, radius);
                    }
                }
                targets.put_variation(
                    row,
                    if plane {
                        pc.surface_variation()
                    } else {
                        NO_PLANE_VARIATION
                    },
                );
                if opts.mode == NormalMode::Keep
                    && let Some(given) = targets.normal(row)
                {
                    totals[total::KEPT] += 1.0;
                    // A rule the user named holds for every normal; by default the inputs'
                    // stay as they are (a mesh's face outwards, which `up` would undo).
                    if matches!(opts.orient, Orient::Up | Orient::Scanner) {
                        let turned = self.orient(given, q, targets.scanner(row), &at);
                        if turned != given {
                            targets.put_normal(row, turned);
                        }
                    }
                    return;
                }
                totals[total::COMPUTED] += 1.0;
                if !plane {
                    // No plane fits better than another: the honest value is none, not a
                    // made-up direction that renderers would light and cull by.
                    totals[total::NO_NORMAL] += 1.0;
                    targets.put_no_normal(row);
                    return;
                }
                let normal = self.orient(pc.normal, q, targets.scanner(row), &at);
                targets.put_normal(row, normal);
            },
        );
        let mut sizes = TriangleSizes::default();
        let mut region = Vec::with_capacity(REGION);
        for (r, range) in (0..tree.len()).step_by(REGION).enumerate() {
            if r % SAMPLE_EVERY != 0 {
                continue;
            }
            region.clear();
            let end = (range + REGION).min(tree.len());
            region.extend(
                (range..end)
                    .filter(|&t| (tree.order[t] as usize) < own)
                    .map(|t| tree.offset(range, t)),
            );
            // A position counts once, as in the neighbourhoods: three copies of one point
            // are no triangle.
            region.sort_unstable_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
            region.dedup();
            cluster(&mut region, &mut sizes);
        }
        totals[total::TRIANGLE_RADIUS_SUM] = sizes.radius_sum;
        totals[total::TRIANGLES] = sizes.triangles as f64;
        Ok(totals)
    }

    fn record(&self, totals: &[f64], meta: &mut Metadata) {
        let t = |i: usize| totals.get(i).copied().unwrap_or(0.0);
        let triangles = t(total::TRIANGLES);
        meta.normals = Some(NormalsInfo {
            k: self.opts.k as u32,
            orient: self.orient_name(!meta.scanners.is_empty()).into(),
            computed: t(total::COMPUTED) as u64,
            kept: t(total::KEPT) as u64,
            partial: t(total::PARTIAL) as u64,
            no_normal: t(total::NO_NORMAL) as u64,
            search_radius: self
                .search
                .get()
                .copied()
                .filter(|r| r.is_finite())
                .unwrap_or(0.0),
            mean_radius: t(total::RADIUS_SUM) / (meta.points.max(1) as f64),
            surfel_radius: if triangles > 0.0 {
                t(total::TRIANGLE_RADIUS_SUM) / triangles
            } else {
                0.0
            },
            triangles: triangles as u64,
        });
    }

    fn warnings(&self, totals: &[f64]) -> Vec<String> {
        let t = |i: usize| totals.get(i).copied().unwrap_or(0.0);
        let points = t(total::COMPUTED) + t(total::KEPT);
        let share = |n: f64| 100.0 * n / points.max(1.0);
        let r = self.search.get().copied().unwrap_or(f64::INFINITY);
        let mut out = Vec::new();
        if t(total::CAPPED) > CAPPED_WARNING * points {
            out.push(format!(
                "{:.1} % of the points had four or fewer (themselves included) within the normals' search \
                 radius {r:.6}: their discs are cut to that radius, which leaves gaps where a \
                 surface is sampled that sparsely; a --normal-radius of {:.1} times the point \
                 spacing there finds their neighbours",
                share(t(total::CAPPED)),
                2.0 * (self.opts.k as f64 / std::f64::consts::PI).sqrt(),
            ));
        }
        if t(total::RADIUS_REPLACED) > 0.0 {
            out.push(format!(
                "--normals compute replaced the inputs' radius of {} points with the estimate \
                 (--normals keep keeps them)",
                t(total::RADIUS_REPLACED)
            ));
        }
        if t(total::NO_NORMAL) > 0.01 * points {
            out.push(format!(
                "{:.1} % of the points have no normal, and small discs: fewer than three \
                 distinct positions within the search radius {r:.6}, or all on one line; where \
                 they are a surface sampled that sparsely, a --normal-radius of {:.1} times its \
                 point spacing finds their neighbours, and where they are scan lines, one of \
                 twice the gap between the lines",
                share(t(total::NO_NORMAL)),
                2.0 * (self.opts.k as f64 / std::f64::consts::PI).sqrt(),
            ));
        }
        out
    }
}

impl NormalStep {
    /// `n` turned the way the options say; `q` is the point in real units without the offset,
    /// `scan` the index of the scan that took it, where known.
    fn orient(&self, n: [f64; 3], q: [f64; 3], scan: Option<usize>, at: &Placement) -> [f64; 3] {
        let up = || if n[2] < 0.0 { n.map(|c| -c) } else { n };
        let towards = |s: [f64; 3]| {
            let to = [0, 1, 2].map(|a| s[a] - (at.offset[a] + q[a]));
            if dot(n, to) < 0.0 { n.map(|c| -c) } else { n }
        };
        let scanner = scan
            .and_then(|i| at.scanners.get(i))
            .copied()
            .or(self.opts.viewpoint);
        match (self.opts.orient, scanner) {
            (Orient::None, _) => n,
            (Orient::Up, _) => up(),
            (Orient::Auto | Orient::Scanner, Some(s)) => towards(s),
            (Orient::Auto | Orient::Scanner, None) => up(),
        }
    }
}

/// What orienting towards a scanner needs of the chunk.
struct Placement<'a> {
    offset: [f64; 3],
    scanners: &'a [[f64; 3]],
}

/// The neighbour search's radius (and the halo's width), from the plan's spacing estimate;
/// see `SEARCH_FACTOR`.
fn search_radius(plan: &Plan, k: usize) -> f64 {
    let r = plan.spacing_quantiles[1] * (k as f64 / std::f64::consts::PI).sqrt() * SEARCH_FACTOR;
    // No estimate (every point in one place): search without bound, one chunk holds them.
    if r > 0.0 && r.is_finite() {
        r
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests;
