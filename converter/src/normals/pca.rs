//! Principal component analysis of a neighbourhood (paper 001, section 3.4): the covariance
//! of the points about their centroid and its eigenvalues λ0 ≤ λ1 ≤ λ2, with the eigenvector
//! of λ0 as the normal and σ = λ0 / (λ0 + λ1 + λ2) as the surface variation.

/// What the analysis of one neighbourhood gives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Principal {
    /// Unit eigenvector of the smallest eigenvalue; its sign is arbitrary.
    pub normal: [f64; 3],
    /// λ0 ≤ λ1 ≤ λ2.
    pub eigenvalues: [f64; 3],
    /// The covariance scaled to unit size and shifted by its mean eigenvalue, and its largest
    /// eigenvalue so shifted, for `major`.
    unit: [f64; 6],
    unit_l2: f64,
    /// The middle eigenvalue of `unit`.
    unit_l1: f64,
}

impl Principal {
    /// Unit eigenvector of the largest eigenvalue (the BSP clustering splits across it); found
    /// when asked, as most neighbourhoods need only their normal.
    pub fn major(&self) -> [f64; 3] {
        eigenvector(self.unit, self.unit_l2).unwrap_or_else(|| any_perpendicular(self.normal))
    }

    /// Whether the points span a plane: not all on one line (or at one position), up to the
    /// solver's rounding and to the grid positions are stored on (`scale` per axis). Across a
    /// line every direction fits equally, so its normal says nothing. A line's points rounded
    /// to the grid stray from it by half a step on each axis at most: across it, along a unit
    /// direction u, by Σ |u_a| scale_a / 2, whose square bounds their variance there; a strip
    /// two steps wide spreads more.
    pub fn spans_a_plane(&self, scale: [f64; 3]) -> bool {
        let [_, middle, largest] = self.eigenvalues;
        if middle <= 1e-9 * largest {
            return false;
        }
        let coarsest = scale.iter().fold(0.0f64, |m, s| m.max(s.abs()));
        // Most neighbourhoods spread far more than a step: no direction needed.
        if middle > 0.75 * coarsest * coarsest {
            return true;
        }
        let reach = |u: [f64; 3]| (0..3).map(|a| u[a].abs() * scale[a].abs()).sum::<f64>() / 2.0;
        // Along the middle axis (across a line, the normal is another such direction where
        // the two spreads are too alike to tell apart).
        let across = reach(eigenvector(self.unit, self.unit_l1).unwrap_or(self.normal));
        middle > across * across
    }

    pub fn surface_variation(&self) -> f64 {
        let sum: f64 = self.eigenvalues.iter().sum();
        if sum > 0.0 {
            (self.eigenvalues[0] / sum).clamp(0.0, 1.0 / 3.0)
        } else {
            0.0
        }
    }
}

/// The covariance of `points` about their centroid, as its six distinct entries
/// (xx, xy, xz, yy, yz, zz), with the centroid. `points` should be near the origin (relative
/// to the query point) for precision.
pub fn covariance(points: impl Iterator<Item = [f64; 3]> + Clone) -> ([f64; 6], [f64; 3]) {
    let mut n = 0.0;
    let mut c = [0.0; 3];
    for p in points.clone() {
        n += 1.0;
        for a in 0..3 {
            c[a] += p[a];
        }
    }
    if n == 0.0 {
        return ([0.0; 6], c);
    }
    let c = c.map(|v| v / n);
    let mut m = [0.0; 6];
    for p in points {
        let d = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
        m[0] += d[0] * d[0];
        m[1] += d[0] * d[1];
        m[2] += d[0] * d[2];
        m[3] += d[1] * d[1];
        m[4] += d[1] * d[2];
        m[5] += d[2] * d[2];
    }
    (m.map(|v| v / n), c)
}

/// The covariance of points given as whole-step offsets from one of them (whole numbers held
/// as f64), `scale` real units a step, as (xx, xy, xz, yy, yz, zz). The sums are exact
/// integers, so the result does not depend on the order the points come in (nor on which
/// chunk found them).
pub fn covariance_of_steps(
    steps: impl Iterator<Item = [f64; 3]> + Clone,
    scale: [f64; 3],
) -> [f64; 6] {
    // Summed in f64, exactly, where offsets are under 2^20 steps and there are at most 256
    // points (the sums stay under 2^48 < 2^53), which is every neighbourhood of a real scan;
    // else again in 128-bit integers. Either gives the same exact integers.
    const SMALL: f64 = (1u64 << 20) as f64;
    let mut small = true;
    let (n, s1, s2) = moment_sums(
        steps
            .clone()
            .inspect(|d| small &= d.iter().all(|v| v.abs() < SMALL)),
    );
    if !(small && n <= 256) {
        let (n, s1, s2) = moment_sums(steps.map(|d| d.map(|v| i128::from(v as i64))));
        return from_sums(
            n,
            |i, (a, b)| (n as i128 * s2[i] - s1[a] * s1[b]) as f64,
            scale,
        );
    }
    // n Σ d_a d_b and Σ d_a Σ d_b reach 2^56: in i64, from the exact sums.
    let (s1, s2) = (s1.map(|v| v as i64), s2.map(|v| v as i64));
    from_sums(
        n,
        |i, (a, b)| (n as i64 * s2[i] - s1[a] * s1[b]) as f64,
        scale,
    )
}

/// How many offsets, their sum per axis and the sums of their products (xx, xy, xz, yy, yz,
/// zz), in the number type of the offsets.
fn moment_sums<T>(steps: impl Iterator<Item = [T; 3]>) -> (usize, [T; 3], [T; 6])
where
    T: Copy + Default + std::ops::Add<Output = T> + std::ops::Mul<Output = T>,
{
    let zero = T::default();
    let (mut n, mut s1, mut s2) = (0, [zero; 3], [zero; 6]);
    for d in steps {
        n += 1;
        for a in 0..3 {
            s1[a] = s1[a] + d[a];
        }
        let products = [
            d[0] * d[0],
            d[0] * d[1],
            d[0] * d[2],
            d[1] * d[1],
            d[1] * d[2],
            d[2] * d[2],
        ];
        for (s, p) in s2.iter_mut().zip(products) {
            *s = *s + p;
        }
    }
    (n, s1, s2)
}

/// The covariance from `n` points and `centred(i, (a, b))`, the exact n Σ d_a d_b − Σ d_a Σ d_b
/// of entry i (= n² cov) rounded once to f64.
fn from_sums(
    n: usize,
    centred: impl Fn(usize, (usize, usize)) -> f64,
    scale: [f64; 3],
) -> [f64; 6] {
    if n == 0 {
        return [0.0; 6];
    }
    let n = n as f64;
    let pairs = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
    let nn = n * n;
    let mut cov = [0.0; 6];
    for (i, &(a, b)) in pairs.iter().enumerate() {
        cov[i] = centred(i, (a, b)) / nn * scale[a] * scale[b];
    }
    cov
}

/// Eigen-decomposition of a covariance (a symmetric 3x3 matrix with no negative eigenvalue;
/// the solver relies on it) given as (xx, xy, xz, yy, yz, zz): shifted
/// by the mean eigenvalue, the smallest eigenvalue by Newton's method on the characteristic
/// cubic, the other two from the quadratic left once it is divided out, then eigenvectors
/// from cross products of the rows of (A − λI).
pub fn principal(cov: [f64; 6]) -> Principal {
    // Scale to unit size so that the cubic's terms neither overflow nor vanish.
    let s = cov.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if !(s > 0.0 && s.is_finite()) {
        return Principal {
            normal: [0.0, 0.0, 1.0],
            eigenvalues: [0.0; 3],
            unit: [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            unit_l2: 1.0,
            unit_l1: 0.0,
        };
    }
    let inv = 1.0 / s;
    let [a, b, c, d, e, f] = cov.map(|v| v * inv);
    // B = A − qI, q the mean eigenvalue, has the eigenvalues μ = λ − q and the characteristic
    // polynomial μ³ + c1 μ − det, whose coefficients carry no rounding of q's size: eigenvalues
    // close together stay apart.
    let q = (a + d + f) / 3.0;
    let shifted = [a - q, b, c, d - q, e, f - q];
    let [a, b, c, d, e, f] = shifted;
    let c1 = (a * d - b * b) + (a * f - c * c) + (d * f - e * e);
    let det = a * (d * f - e * e) - b * (b * f - e * c) + c * (b * e - d * c);
    let m0 = smallest_root(c1, det, shifted, -q);
    // The other two: their sum is −μ0 and their product c1 + μ0².
    let half_gap = (-3.0 * m0 * m0 - 4.0 * c1).max(0.0).sqrt() * 0.5;
    let (m1, m2) = ((-0.5 * m0 - half_gap).max(m0), -0.5 * m0 + half_gap);
    let normal = eigenvector(shifted, m0).unwrap_or_else(|| {
        // λ0 = λ1: any direction across the major axis will do.
        let major = eigenvector(shifted, m2).unwrap_or([1.0, 0.0, 0.0]);
        any_perpendicular(major)
    });
    Principal {
        normal,
        eigenvalues: [m0, m1, m2].map(|m| (m + q).max(0.0) * s),
        unit: shifted,
        unit_l2: m2,
        unit_l1: m1,
    }
}

/// The smallest root of μ³ + c1 μ − det, the characteristic polynomial of the symmetric
/// matrix `m` of trace 0. Left of that root the cubic rises and bends down, so Newton's steps
/// from any point there climb to it without passing it: no trigonometry, and a few steps.
/// `floor` is known not to exceed the root: −q for a covariance shifted by q, whose
/// eigenvalues are not negative. Most neighbourhoods lie nearly in a plane, λ0 near 0, so the
/// climb from there takes a step or two.
fn smallest_root(c1: f64, det: f64, m: [f64; 6], floor: f64) -> f64 {
    let [a, b, c, d, e, f] = m;
    // Three points left of the root, the nearest taken: `floor`, Gershgorin's bound, and
    // −2√(−c1/3), below which no root of a cubic μ³ + c1 μ − det with three real roots lies
    // (exact for a disc, λ1 = λ2).
    let gershgorin = (a - b.abs() - c.abs())
        .min(d - b.abs() - e.abs())
        .min(f - c.abs() - e.abs());
    let mut x = gershgorin
        .max(-2.0 * (-c1 / 3.0).max(0.0).sqrt())
        .max(floor);
    let cubic = |x: f64| (x * x + c1) * x - det;
    let slope = |x: f64| 3.0 * x * x + c1;
    let mut rise = slope(x);
    for _ in 0..64 {
        let next = x - cubic(x) / rise;
        // Rounding ends the climb: a step that does not rise, or one that lands beyond the
        // cubic's first peak (where it falls) or beyond 0 (the mean of the roots), as only a
        // slope rounded to nearly nothing near a double root gives.
        if !(next > x && next <= 0.0) {
            break;
        }
        let next_rise = slope(next);
        if !(next_rise > 0.0 && next_rise.is_finite()) {
            break;
        }
        (x, rise) = (next, next_rise);
    }
    x
}

/// A unit vector spanning the null space of (M − λI), when that space is one direction.
fn eigenvector(m: [f64; 6], l: f64) -> Option<[f64; 3]> {
    let [a, b, c, d, e, f] = m;
    let r0 = [a - l, b, c];
    let r1 = [b, d - l, e];
    let r2 = [c, e, f - l];
    let (c01, c02, c12) = (cross(r0, r1), cross(r0, r2), cross(r1, r2));
    let (n01, n02, n12) = (norm2(c01), norm2(c02), norm2(c12));
    // The longest of the three, by comparisons a compiler can turn into selects.
    let (best, n2) = if n01 > n02 && n01 > n12 {
        (c01, n01)
    } else if n02 > n12 {
        (c02, n02)
    } else {
        (c12, n12)
    };
    // Below this the rows are (nearly) parallel: a double eigenvalue, no single direction.
    if n2 <= 1e-24 {
        return None;
    }
    let inv = 1.0 / n2.sqrt();
    Some(best.map(|v| v * inv))
}

pub fn cross(u: [f64; 3], v: [f64; 3]) -> [f64; 3] {
    [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]
}

pub fn dot(u: [f64; 3], v: [f64; 3]) -> f64 {
    u[0] * v[0] + u[1] * v[1] + u[2] * v[2]
}

fn norm2(u: [f64; 3]) -> f64 {
    dot(u, u)
}

pub fn any_perpendicular(v: [f64; 3]) -> [f64; 3] {
    let other = if v[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let p = cross(v, other);
    let l = norm2(p).sqrt().max(1e-300);
    p.map(|c| c / l)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn angle(a: [f64; 3], b: [f64; 3]) -> f64 {
        dot(a, b).abs().clamp(0.0, 1.0).acos().to_degrees()
    }

    #[test]
    fn a_tilted_plane_gives_its_normal_and_no_variation() {
        let n = {
            let v = [0.3, -0.5, 0.8];
            let l = norm2(v).sqrt();
            v.map(|c| c / l)
        };
        let u = any_perpendicular(n);
        let w = cross(n, u);
        let pts: Vec<[f64; 3]> = (0..40)
            .map(|i| {
                let (s, t) = ((i % 7) as f64 - 3.0, (i / 7) as f64 * 0.7 - 2.0);
                [0, 1, 2].map(|a| s * u[a] + t * w[a])
            })
            .collect();
        let (cov, _) = covariance(pts.iter().copied());
        let pc = principal(cov);
        assert!(angle(pc.normal, n) < 1e-6, "{:?}", pc.normal);
        assert!(pc.surface_variation() < 1e-12);
        assert!(pc.eigenvalues[0] <= pc.eigenvalues[1] && pc.eigenvalues[1] <= pc.eigenvalues[2]);
    }

    #[test]
    fn an_anisotropic_cloud_gives_its_axes_and_eigenvalues() {
        // Variances 9, 4 and 0.25 along x, z and y, rotated by nothing: λ = 0.25, 4, 9.
        let mut pts = Vec::new();
        for sx in [-3.0, 3.0] {
            for sz in [-2.0, 2.0] {
                for sy in [-0.5, 0.5] {
                    pts.push([sx, sy, sz]);
                }
            }
        }
        let (cov, c) = covariance(pts.iter().copied());
        assert_eq!(c, [0.0; 3]);
        let pc = principal(cov);
        for (got, want) in pc.eigenvalues.iter().zip([0.25, 4.0, 9.0]) {
            assert!((got - want).abs() < 1e-9, "{:?}", pc.eigenvalues);
        }
        assert!(angle(pc.normal, [0.0, 1.0, 0.0]) < 1e-6);
        assert!(angle(pc.major(), [1.0, 0.0, 0.0]) < 1e-6);
        assert!((pc.surface_variation() - 0.25 / 13.25).abs() < 1e-12);
    }

    #[test]
    fn covariance_of_steps_is_the_same_in_either_width() {
        let steps: Vec<[i64; 3]> = (0..17).map(|i| [i * 3 % 7, i * i % 11, -i]).collect();
        let as_f64 =
            |s: &[[i64; 3]]| -> Vec<[f64; 3]> { s.iter().map(|d| d.map(|v| v as f64)).collect() };
        // More points than the f64 sums take: the wide path, and the float estimate agrees.
        let many: Vec<[f64; 3]> = (0..300)
            .map(|i| [i % 7, i % 11, i % 5].map(f64::from))
            .collect();
        let exact = covariance_of_steps(many.iter().copied(), [1.0; 3]);
        let (float, _) = covariance(many.iter().copied());
        for (e, f) in exact.iter().zip(float) {
            assert!((e - f).abs() < 1e-9, "{exact:?} vs {float:?}");
        }
        // Offsets too far for exact f64 sums take the wide path and are still exact.
        let far = as_f64(&steps.iter().map(|d| d.map(|v| v << 30)).collect::<Vec<_>>());
        let steps = as_f64(&steps);
        let wide = covariance_of_steps(far.iter().copied(), [1.0; 3]);
        let near = covariance_of_steps(steps.iter().copied(), [1.0; 3]);
        for (w, n) in wide.iter().zip(near) {
            assert_eq!(*w, n * (1u64 << 60) as f64);
        }
    }

    #[test]
    fn covariance_of_steps_matches_the_float_one_in_any_order() {
        let steps: Vec<[f64; 3]> = (0..17)
            .map(|i| [i * 3 % 7, i * i % 11, -i].map(f64::from))
            .collect();
        let scale = [0.01, 0.02, 0.005];
        let exact = covariance_of_steps(steps.iter().copied(), scale);
        let reversed = covariance_of_steps(steps.iter().rev().copied(), scale);
        assert_eq!(exact, reversed);
        let (float, _) = covariance(steps.iter().map(|d| [0, 1, 2].map(|a| d[a] * scale[a])));
        for (e, f) in exact.iter().zip(float) {
            assert!((e - f).abs() < 1e-12, "{exact:?} vs {float:?}");
        }
    }

    /// The eigenvalues by the trigonometric closed form (Smith 1961), for reference.
    fn closed_form(m: [f64; 6]) -> [f64; 3] {
        let [a, b, c, d, e, f] = m;
        let p1 = b * b + c * c + e * e;
        let q = (a + d + f) / 3.0;
        if p1 == 0.0 {
            let mut l = [a, d, f];
            l.sort_by(f64::total_cmp);
            return l;
        }
        let p2 = (a - q).powi(2) + (d - q).powi(2) + (f - q).powi(2) + 2.0 * p1;
        let p = (p2 / 6.0).sqrt();
        let (ba, bd, bf) = ((a - q) / p, (d - q) / p, (f - q) / p);
        let (bb, bc, be) = (b / p, c / p, e / p);
        let det = ba * (bd * bf - be * be) - bb * (bb * bf - be * bc) + bc * (bb * be - bd * bc);
        let phi = (det / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
        let hi = q + 2.0 * p * phi.cos();
        let lo = q + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
        [lo, 3.0 * q - hi - lo, hi]
    }

    #[test]
    fn newton_finds_the_eigenvalues_of_the_closed_form() {
        let mut rng = crate::synth::Rng::new(3, 4, 5);
        // Random spreads along three random axes, from flat to round, some exactly
        // degenerate: a plane (λ0 = 0), a line (λ0 = λ1 = 0), a disc (λ1 = λ2), a ball.
        let spreads = |i: usize, r: &mut crate::synth::Rng| match i % 8 {
            0 => [0.0, 1.0, 2.0],
            1 => [0.0, 0.0, 1.0],
            2 => [0.1, 1.0, 1.0],
            3 => [0.5, 0.5, 0.5],
            // Nearly round: eigenvalues 1, 1 + g, 1 + 2g.
            4 => {
                let g = 10f64.powi(-3 - (i / 8 % 4) as i32);
                [1.0, 1.0 + g, 1.0 + 2.0 * g].map(f64::sqrt)
            }
            _ => [r.unit() * 0.05, r.unit(), r.unit() * 3.0],
        };
        for i in 0..800 {
            let sd = spreads(i, &mut rng);
            let u = {
                let v = [rng.gaussian(), rng.gaussian(), rng.gaussian()];
                let l = norm2(v).sqrt();
                v.map(|c| c / l)
            };
            let v = any_perpendicular(u);
            let w = cross(u, v);
            let axes = [u, v, w];
            // Σ sd_i² axis_i axis_iᵀ, scaled by a power of ten to test the unit scaling.
            let scale = 10f64.powi(i as i32 % 9 - 4);
            let mut m = [0.0; 6];
            let pairs = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
            for (slot, &(r, c)) in pairs.iter().enumerate() {
                m[slot] = (0..3)
                    .map(|j| sd[j] * sd[j] * axes[j][r] * axes[j][c])
                    .sum::<f64>()
                    * scale;
            }
            let pc = principal(m);
            let want = closed_form(m);
            // Repeated roots are where rounding shows, in any method (the closed form's
            // included): Newton's steps near one lose their way at about the cube root of the
            // rounding for a triple root, and the other two come from a square root of
            // nearly nothing.
            let single =
                |i: usize| (0..3).all(|j| j == i || (want[i] - want[j]).abs() > 1e-3 * scale);
            let tolerance = [0, 1, 2].map(|i| if single(i) { 1e-9 } else { 1e-5 });
            for ((got, want), tolerance) in pc.eigenvalues.iter().zip(want).zip(tolerance) {
                assert!(
                    (got - want.max(0.0)).abs() <= tolerance * scale,
                    "{i}: {:?} vs {want:?}",
                    pc.eigenvalues
                );
            }
            assert!((norm2(pc.normal) - 1.0).abs() < 1e-9);
            // The normal is the axis of least spread, as exact as the gap g (relative to λ2)
            // to the next eigenvalue allows: the closed form this replaced turned it by up to
            // about 1e-11 / g (a line with g = 1e-6: 1.2e-5), and this must do as well.
            let mut by_spread = [0, 1, 2];
            by_spread.sort_by(|&x, &y| sd[x].total_cmp(&sd[y]));
            let gap =
                (sd[by_spread[1]].powi(2) - sd[by_spread[0]].powi(2)) / sd[by_spread[2]].powi(2);
            if gap > 1e-9 {
                let axis = axes[by_spread[0]];
                // The sine of the angle: acos near 1 cannot tell 1e-8 from 0.
                let sine = norm2(cross(pc.normal, axis)).sqrt();
                assert!(
                    sine < (1e-11 / gap).max(1e-9),
                    "{i}: {:?} vs {axis:?}, gap {gap}",
                    pc.normal
                );
            }
        }
    }

    #[test]
    fn a_line_or_a_point_still_gives_a_unit_normal() {
        let line: Vec<[f64; 3]> = (0..5).map(|i| [i as f64, 0.0, 0.0]).collect();
        let pc = principal(covariance(line.iter().copied()).0);
        assert!((norm2(pc.normal) - 1.0).abs() < 1e-9);
        assert!(dot(pc.normal, [1.0, 0.0, 0.0]).abs() < 1e-9);
        let point = principal(covariance([[1.0, 2.0, 3.0]; 4].into_iter()).0);
        assert!((norm2(point.normal) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn a_line_rounded_to_the_grid_spans_no_plane_and_a_strip_does() {
        let mm = [0.001; 3];
        let on_grid = |p: [f64; 3]| p.map(|c| (c / 0.001).round() * 0.001);
        // 1 cm apart along a slanted direction, each rounded to the millimetre grid: off the
        // line by up to half a millimetre on each axis.
        let dir = [1.0, 0.37, 0.21];
        let len = norm2(dir).sqrt();
        let line: Vec<[f64; 3]> = (0..16)
            .map(|i| on_grid(dir.map(|c| c / len * 0.01 * i as f64 + 0.1234)))
            .collect();
        let pc = principal(covariance(line.iter().copied()).0);
        assert!(!pc.spans_a_plane(mm), "{:?}", pc.eigenvalues);
        // Two rows of it 2 mm apart are a plane, as is a patch of the same spacing.
        let strip: Vec<[f64; 3]> = line
            .iter()
            .flat_map(|&p| [p, on_grid([p[0], p[1], p[2] + 0.002])])
            .collect();
        assert!(principal(covariance(strip.iter().copied()).0).spans_a_plane(mm));
        let patch: Vec<[f64; 3]> = (0..16)
            .map(|i| {
                on_grid([
                    0.01 * (i % 4) as f64,
                    0.013 * (i / 4) as f64,
                    0.003 * i as f64,
                ])
            })
            .collect();
        assert!(principal(covariance(patch.iter().copied()).0).spans_a_plane(mm));
        // A plane across an axis stored coarsely (an outlier far along x) is still a plane:
        // x does not vary on it.
        let coarse_x = [0.01, 1e-9, 1e-9];
        let across_x: Vec<[f64; 3]> = (0..16)
            .map(|i| [5.0, 0.001 * (i % 4) as f64, 0.001 * (i / 4) as f64])
            .collect();
        assert!(principal(covariance(across_x.iter().copied()).0).spans_a_plane(coarse_x));
    }
}
