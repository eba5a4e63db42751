//! How much of the disc around a point its neighbours cover, seen along its normal. The
//! radius that covers a surface comes from the density its k nearest neighbours measure,
//! ρ = k / (π r_k²), which holds where they lie all round the point. At the open edge of a
//! surface they lie on one side: they fill a share f of the disc, the density is k / (f π r_k²),
//! and a radius from r_k alone is 1/√f too large (√2 on a straight edge, 2 at a square corner),
//! so that the edge's discs reach past it by about their radius.

use super::pca::{any_perpendicular, cross, dot};
use std::f64::consts::TAU;

/// The least share `angular_cover` gives.
pub const LEAST: f64 = 0.25;

/// Neighbours looked at, at most (a neighbourhood grows to 256 where its k lie on one line).
const MOST: usize = 256;

/// The codes of the six sectors `angular_cover` sorts neighbours into.
const ALL_SECTORS: u8 = 0b1110_0111;

/// The chance that a point inside a randomly sampled surface is taken for one at an edge.
const CHANCE: f64 = 0.001;

/// The share (1/4 to 1) of the full angle around `normal` that the `offsets` (from the point
/// to its neighbours, the point itself among them or not) fill.
///
/// The widest gap g between neighbours next to each other in angle tells an edge: m angles at
/// random (a point inside a randomly sampled surface) leave one wider than q only with chance
/// m (1 - q/2π)^(m-1); below the q where that is 0.1 % the point counts as inside, covered
/// whole, so that chance gaps do not open holes in a closed surface (at 1 % they cost the
/// harness's closed nested spheres 1.1 dB). Past it, the share is the full angle less the
/// gap, over what that is all round: 2π less the mean widest gap of m random angles,
/// 2π H(m) / m (H the harmonic number). No less than a quarter (a square corner): a narrower
/// wedge is rarer on a surface than the noise in a few neighbours' angles (the end of a short
/// row of points has them all on one side).
pub fn angular_cover(offsets: impl Iterator<Item = [f64; 3]>, normal: [f64; 3]) -> f64 {
    let u = any_perpendicular(normal);
    let v = cross(normal, u);
    // On the stack, in single precision, with a polynomial atan2, and most points told inside
    // without any angle: every point of a conversion with --normals comes here, and the
    // estimate with libm's atan2 for every neighbour made it half as slow again.
    let mut plane = [(0f32, 0f32); MOST];
    let mut m = 0;
    // Which of six sectors of 60 degrees hold a neighbour: by the sides of the lines at 0, 60
    // and 120 degrees, six of the eight codes.
    let mut sectors = 0u8;
    for o in offsets {
        let (x, y) = (dot(o, u) as f32, dot(o, v) as f32);
        if (x != 0.0 || y != 0.0) && m < MOST {
            plane[m] = (x, y);
            m += 1;
            let t = 3f32.sqrt() * x;
            sectors |= 1 << (u8::from(y > 0.0) * 4 + u8::from(y > t) * 2 + u8::from(y > -t));
        }
    }
    if m < 3 {
        return 1.0;
    }
    let mf = m as f64;
    let inside = TAU * (1.0 - (CHANCE / mf).powf(1.0 / (mf - 1.0)));
    // A neighbour in every sector leaves no gap as wide as two of them.
    if sectors == ALL_SECTORS && inside >= TAU / 3.0 {
        return 1.0;
    }
    let mut angles = [0f32; MOST];
    for (a, &(x, y)) in angles.iter_mut().zip(&plane[..m]) {
        *a = atan2(y, x);
    }
    let angles = &mut angles[..m];
    angles.sort_unstable_by(f32::total_cmp);
    let wrap = f64::from(angles[0]) + TAU - f64::from(angles[m - 1]);
    let widest = angles
        .windows(2)
        .map(|w| f64::from(w[1] - w[0]))
        .fold(wrap, f64::max);
    if widest <= inside {
        return 1.0;
    }
    let harmonic: f64 = (1..=m).map(|i| 1.0 / i as f64).sum();
    let all_round = TAU - TAU * harmonic / mf;
    ((TAU - widest) / all_round).clamp(LEAST, 1.0)
}

/// The angle of (x, y), -π to π, within 2e-5 rad: an odd minimax polynomial of atan on
/// 0..1, taken to the octant.
fn atan2(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let (lo, hi) = (ax.min(ay), ax.max(ay));
    if hi == 0.0 {
        return 0.0;
    }
    let z = lo / hi;
    let z2 = z * z;
    let mut a = z
        * (0.999_866
            + z2 * (-0.330_299_5 + z2 * (0.180_141 + z2 * (-0.085_133 + z2 * 0.020_835_1))));
    if ay > ax {
        a = std::f32::consts::FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = std::f32::consts::PI - a;
    }
    if y < 0.0 { -a } else { a }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_polynomial_atan2_is_libms_within_2e_5() {
        for i in 0..10_000 {
            let t = i as f32 * 0.000_628_3;
            for r in [1e-3f32, 1.0, 7e4] {
                let (x, y) = (r * t.cos(), r * t.sin());
                let d = (atan2(y, x) - y.atan2(x)).abs();
                let d = d.min((d - std::f32::consts::TAU).abs());
                assert!(d < 2e-5, "{x} {y}: {d}");
            }
        }
    }

    fn ring(from: f64, to: f64, n: usize) -> Vec<[f64; 3]> {
        (0..n)
            .map(|i| {
                let a = from + (to - from) * i as f64 / (n - 1) as f64;
                let r = 1.0 + 0.3 * (i % 3) as f64;
                [r * a.cos(), r * a.sin(), 0.0]
            })
            .collect()
    }

    #[test]
    fn neighbours_all_round_cover_the_disc_and_an_edge_half_of_it() {
        let up = [0.0, 0.0, 1.0];
        let whole = angular_cover(ring(0.0, TAU * 14.0 / 15.0, 15).into_iter(), up);
        assert_eq!(whole, 1.0);
        // A straight edge: the neighbours on one side, spread over half the circle.
        let half = angular_cover(ring(0.0, TAU / 2.0, 15).into_iter(), up);
        assert!((0.5..0.75).contains(&half), "{half}");
        let corner = angular_cover(ring(0.0, TAU / 4.0, 15).into_iter(), up);
        assert!((0.25..0.4).contains(&corner), "{corner}");
        assert!(corner < half);
        // Seen along another normal, the same: the plane's own axes do not matter.
        let tilted = [0.0, 0.6, 0.8];
        let (u, v) = (
            any_perpendicular(tilted),
            cross(tilted, any_perpendicular(tilted)),
        );
        let in_plane = |p: [f64; 3]| [0, 1, 2].map(|a| p[0] * u[a] + p[1] * v[a]);
        let again = angular_cover(ring(0.0, TAU / 2.0, 15).into_iter().map(in_plane), tilted);
        assert!((again - half).abs() < 1e-9, "{again} vs {half}");
        // Random neighbours all round: taken for an edge about once in a thousand.
        let mut next = crate::normals::tests::unit_randoms(9);
        let trials = 20_000;
        let shrunk = (0..trials)
            .filter(|_| {
                let random: Vec<[f64; 3]> = (0..15)
                    .map(|_| {
                        let (a, r) = (next() * TAU, next().sqrt());
                        [r * a.cos(), r * a.sin(), 0.0]
                    })
                    .collect();
                angular_cover(random.into_iter(), up) < 1.0
            })
            .count();
        let share = shrunk as f64 / trials as f64;
        assert!((0.0003..0.003).contains(&share), "{share}");
        // Too few to tell: whole. All on one side: a quarter at the least.
        assert_eq!(angular_cover(ring(0.0, 1.0, 2).into_iter(), up), 1.0);
        assert_eq!(angular_cover(ring(0.0, 0.1, 6).into_iter(), up), LEAST);
    }

    /// The rule as SPEC states it, in double precision with libm's atan2 and no shortcut.
    fn spelled_out(offsets: &[[f64; 3]], normal: [f64; 3]) -> f64 {
        let (u, v) = (
            any_perpendicular(normal),
            cross(normal, any_perpendicular(normal)),
        );
        let mut a: Vec<f64> = offsets
            .iter()
            .map(|&o| dot(o, v).atan2(dot(o, u)))
            .collect();
        a.sort_by(f64::total_cmp);
        let m = a.len() as f64;
        let g = a
            .windows(2)
            .map(|w| w[1] - w[0])
            .fold(a[0] + TAU - a[a.len() - 1], f64::max);
        if g <= TAU * (1.0 - (CHANCE / m).powf(1.0 / (m - 1.0))) {
            return 1.0;
        }
        let h: f64 = (1..=a.len()).map(|i| 1.0 / i as f64).sum();
        ((TAU - g) / (TAU - TAU * h / m)).clamp(LEAST, 1.0)
    }

    #[test]
    fn the_shortcuts_give_the_rule_as_spelled_out() {
        let mut next = crate::normals::tests::unit_randoms(21);
        let normal = [0.36, -0.48, 0.8];
        let (u, v) = (
            any_perpendicular(normal),
            cross(normal, any_perpendicular(normal)),
        );
        let (mut edges, mut worst) = (0, 0.0f64);
        for _ in 0..5000 {
            // Neighbours over an arc of random width (an edge, a corner, all round).
            let (m, arc) = (3 + (next() * 30.0) as usize, TAU * (0.2 + 0.8 * next()));
            let offsets: Vec<[f64; 3]> = (0..m)
                .map(|_| {
                    let (a, r) = (arc * next(), 0.1 + next());
                    [0, 1, 2].map(|k| r * (a.cos() * u[k] + a.sin() * v[k]))
                })
                .collect();
            let want = spelled_out(&offsets, normal);
            edges += usize::from(want < 1.0);
            worst = worst.max((angular_cover(offsets.into_iter(), normal) - want).abs());
        }
        assert!(edges > 1000, "{edges} edges");
        assert!(worst < 1e-4, "{worst}");
    }
}
