//! The spacing a node's points are actually sampled at, measured from the points when the node
//! is loaded.
//!
//! The format records a node's spacing by its level alone (its edge over the grid's cells), and
//! the LOD's count-based estimate (`lod::drawn_spacing`) assumes the surface crossing a cube
//! covers about its face. A leaf holds whatever points are left at any density, and a cube in a
//! city holds ground, facades and roofs, two or three times its face: the estimates then came
//! out well under the points' real spacing, and what is sized by them (the triangulation's
//! reach, the splats of a dataset without stored radii) left holes. Measured from the points,
//! the density needs no assumption about the surface's extent.
//!
//! The density comes from the distance to each sampled point's K-th nearest neighbour: a disc
//! of that radius holds about K points on any surface sampled evenly, at random or on a grid
//! (the distance to the nearest alone depends on the pattern: random sampling puts a point's
//! nearest at about half the spacing, a grid at the spacing). The median over the queries
//! keeps points at a surface's edge, whose discs are half empty, from pulling it up.

use glam::Vec3;

/// Neighbours counted round each query: enough that grids and random samplings give the same
/// density within about 10 % (the first shells of a square grid hold 4, 8, 12 and 20 points).
const K: usize = 16;
/// The points of a node that take part (every n-th one beyond): the density of a sample is
/// the node's scaled by its share.
const SAMPLE_POINTS: usize = 4096;
/// Points whose K-th neighbour is measured.
const QUERIES: usize = 128;
/// Rings of cells searched round a query before it is given up as isolated.
const MAX_RING: i32 = 3;
/// The median of the K-th neighbour's squared distance times π times the density, for points
/// scattered at random (Gamma(K) has its median near K - 1/3) and on grids (a little under K).
const DISC_POINTS: f64 = K as f64 - 0.5;

/// The radius of discs that cover a surface sampled at random at `spacing` but for 1 %: the
/// radius SPEC.md section 4 stores for points of that density, π r² / spacing² = ln 100.
pub(crate) fn covering_radius(spacing: f32) -> f32 {
    spacing * (100f32.ln() / std::f32::consts::PI).sqrt()
}

/// The spacing (one over the square root of the points per unit area) of `points`, x, y, z
/// as f32 bits in the first three words, lying in a cube of edge `edge`; `None` for a node too
/// small to tell, or whose points are all isolated or coincide.
pub(crate) fn sampling_spacing(points: &[[u32; 4]], edge: f32) -> Option<f32> {
    let n = points.len();
    if n <= 2 * K || !edge.is_finite() || edge <= 0.0 {
        return None;
    }
    let stride = n.div_ceil(SAMPLE_POINTS);
    let sample: Vec<Vec3> = points
        .iter()
        .step_by(stride)
        .map(|p| {
            Vec3::new(
                f32::from_bits(p[0]),
                f32::from_bits(p[1]),
                f32::from_bits(p[2]),
            )
        })
        .filter(|p| p.is_finite())
        .collect();
    let m = sample.len();
    if m <= 2 * K {
        return None;
    }
    // Cells about the K-th neighbour's distance wide where the surface covers the cube's face
    // once; where it covers more, or less, the rings search farther or stop sooner.
    let cell = edge * (K as f32 / m as f32).sqrt();
    let grid = Grid::new(&sample, cell);
    let step = (m / QUERIES).max(1);
    let mut squared: Vec<f32> = (0..m)
        .step_by(step)
        .filter_map(|q| grid.kth_nearest_squared(&sample, q))
        .collect();
    if squared.is_empty() {
        return None;
    }
    let mid = squared.len() / 2;
    let (_, &mut median, _) = squared.select_nth_unstable_by(mid, f32::total_cmp);
    if !median.is_finite() || median <= 0.0 {
        return None;
    }
    let sample_density = DISC_POINTS / (std::f64::consts::PI * median as f64);
    let density = sample_density * n as f64 / m as f64;
    Some((1.0 / density.sqrt()) as f32)
}

/// The sample's points sorted by the cell they fall in, for the rings of a query.
struct Grid {
    min: Vec3,
    cell: f32,
    /// (cell key, point) sorted by key.
    entries: Vec<(u64, u32)>,
}

/// Bits of a cell's coordinate on each axis in its key.
const AXIS_BITS: u32 = 21;
const AXIS_MAX: i64 = (1 << AXIS_BITS) - 1;

impl Grid {
    fn new(points: &[Vec3], cell: f32) -> Grid {
        let min = points
            .iter()
            .fold(Vec3::splat(f32::INFINITY), |a, &p| a.min(p));
        let mut grid = Grid {
            min,
            cell,
            entries: Vec::with_capacity(points.len()),
        };
        for (i, &p) in points.iter().enumerate() {
            let c = grid.cell_of(p);
            if let Some(key) = key(c) {
                grid.entries.push((key, i as u32));
            }
        }
        grid.entries.sort_unstable();
        grid
    }

    fn cell_of(&self, p: Vec3) -> [i64; 3] {
        let c = ((p - self.min) / self.cell).floor();
        [c.x as i64, c.y as i64, c.z as i64]
    }

    fn points_in(&self, key: u64) -> impl Iterator<Item = u32> + '_ {
        let start = self.entries.partition_point(|e| e.0 < key);
        self.entries[start..]
            .iter()
            .take_while(move |e| e.0 == key)
            .map(|e| e.1)
    }

    /// The squared distance from point `q` to its K-th nearest other point, searched ring by
    /// ring until no point beyond the rings can be nearer; `None` where the rings run out.
    fn kth_nearest_squared(&self, points: &[Vec3], q: usize) -> Option<f32> {
        let p = points[q];
        let centre = self.cell_of(p);
        // The K smallest squared distances met, ascending.
        let mut nearest: Vec<f32> = Vec::with_capacity(K + 1);
        for ring in 0..=MAX_RING {
            for c in ring_cells(centre, ring) {
                let Some(key) = key(c) else { continue };
                for i in self.points_in(key) {
                    if i as usize == q {
                        continue;
                    }
                    let d = points[i as usize].distance_squared(p);
                    if nearest.len() == K && d >= nearest[K - 1] {
                        continue;
                    }
                    let at = nearest.partition_point(|&x| x <= d);
                    nearest.insert(at, d);
                    nearest.truncate(K);
                }
            }
            // Every point within `ring` cells of the query's own cell has been seen: those
            // beyond lie at least `ring` cell widths away.
            let reach = ring as f32 * self.cell;
            if nearest.len() == K && nearest[K - 1] <= reach * reach {
                return Some(nearest[K - 1]);
            }
        }
        None
    }
}

/// The cell key, `None` outside the keys' range.
fn key(c: [i64; 3]) -> Option<u64> {
    c.iter()
        .all(|&v| (0..=AXIS_MAX).contains(&v))
        .then(|| (c[0] as u64) << (2 * AXIS_BITS) | (c[1] as u64) << AXIS_BITS | c[2] as u64)
}

/// The cells at Chebyshev distance `ring` from `centre`.
fn ring_cells(centre: [i64; 3], ring: i32) -> impl Iterator<Item = [i64; 3]> {
    let r = ring as i64;
    (-r..=r).flat_map(move |dx| {
        (-r..=r).flat_map(move |dy| {
            (-r..=r).filter_map(move |dz| {
                (dx.abs().max(dy.abs()).max(dz.abs()) == r).then_some([
                    centre[0] + dx,
                    centre[1] + dy,
                    centre[2] + dz,
                ])
            })
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn words(points: impl IntoIterator<Item = Vec3>) -> Vec<[u32; 4]> {
        points
            .into_iter()
            .map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits(), 0])
            .collect()
    }

    /// A deterministic generator of uniform values in [0, 1).
    fn uniform(seed: &mut u64) -> f32 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*seed >> 40) as f32 / (1u64 << 24) as f32
    }

    fn assert_near(got: Option<f32>, want: f32, within: f32) {
        let got = got.expect("a spacing");
        assert!(
            (got / want - 1.0).abs() < within,
            "measured {got}, the sampling's {want}"
        );
    }

    #[test]
    fn a_grid_and_a_random_sampling_of_a_plane_measure_their_spacing() {
        // A square grid of spacing 0.01 over a unit face.
        let grid =
            words((0..100).flat_map(|i| {
                (0..100).map(move |j| Vec3::new(i as f32 * 0.01, j as f32 * 0.01, 0.5))
            }));
        assert_near(sampling_spacing(&grid, 1.0), 0.01, 0.1);
        // The same count scattered at random: the same density, so the same spacing.
        let mut seed = 7;
        let random =
            words((0..10_000).map(|_| Vec3::new(uniform(&mut seed), uniform(&mut seed), 0.5)));
        assert_near(sampling_spacing(&random, 1.0), 0.01, 0.1);
    }

    #[test]
    fn a_cube_holding_three_faces_of_surface_measures_the_points_not_its_face() {
        // The count-based estimate, edge over the root of the count, takes 30 000 points on
        // three unit planes for a spacing of 0.0058; they lie 0.01 apart.
        let mut seed = 11;
        let planes = words((0..30_000).map(|i| {
            let (u, v) = (uniform(&mut seed), uniform(&mut seed));
            match i % 3 {
                0 => Vec3::new(u, v, 0.0),
                1 => Vec3::new(u, 0.0, v),
                _ => Vec3::new(0.0, u, v),
            }
        }));
        assert_near(sampling_spacing(&planes, 1.0), 0.01, 0.1);
        // More points than the sample takes: the density scales with them.
        let mut seed = 13;
        let dense =
            words((0..160_000).map(|_| Vec3::new(uniform(&mut seed), uniform(&mut seed), 0.25)));
        assert_near(sampling_spacing(&dense, 1.0), 0.0025, 0.1);
    }

    #[test]
    fn a_sparse_strip_in_a_large_cube_is_measured_at_its_own_spacing() {
        // 4 000 points 0.05 apart along a strip 2 wide: far fewer than the cube's face would
        // hold, so the rings search well beyond the first cell.
        let strip = words(
            (0..4000).map(|i| Vec3::new((i % 40) as f32 * 0.05, (i / 40) as f32 * 0.05, 3.0)),
        );
        assert_near(sampling_spacing(&strip, 8.0), 0.05, 0.12);
    }

    #[test]
    fn too_few_points_coincident_ones_and_bad_values_measure_nothing() {
        let few = words((0..10).map(|i| Vec3::splat(i as f32)));
        assert_eq!(sampling_spacing(&few, 1.0), None);
        let same = words((0..1000).map(|_| Vec3::splat(0.5)));
        assert_eq!(sampling_spacing(&same, 1.0), None);
        let nan = words((0..1000).map(|_| Vec3::splat(f32::NAN)));
        assert_eq!(sampling_spacing(&nan, 1.0), None);
        let grid = words((0..1000).map(|i| Vec3::new(i as f32 * 0.001, 0.0, 0.0)));
        assert_eq!(sampling_spacing(&grid, 0.0), None);
    }
}
