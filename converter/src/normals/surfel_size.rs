//! Paper 001's global surfel size (section 3.4): a hierarchical clustering cuts the points with
//! planes across their principal axis until clusters of three remain; each cluster is a
//! triangle on the surface, and the surfel size is the mean of the circles enclosing them.
//!
//! The paper clusters the whole cloud; a mean needs only a fair sample, so the converter
//! clusters a share of compact full-density regions of each chunk (`SAMPLE_EVERY`).

use super::pca::{covariance, cross, dot, principal};

/// Cluster one region of `REGION` points out of this many.
pub const SAMPLE_EVERY: usize = 8;
/// Points per region clustered at once: a subtree of the chunk's k-d tree.
pub const REGION: usize = 3 * 1024;

/// Sum of enclosing-circle radii and number of triangles.
#[derive(Debug, Default, Clone, Copy, PartialEq)]
pub struct TriangleSizes {
    pub radius_sum: f64,
    pub triangles: u64,
}

/// Clusters `points` (real units, near each other) and adds their triangles' sizes.
pub fn cluster(points: &mut [[f64; 3]], into: &mut TriangleSizes) {
    if points.len() < 3 {
        return;
    }
    if points.len() <= 5 {
        // Three make a cluster; the one or two left over join no triangle.
        if let Some(r) = enclosing_radius(points[0], points[1], points[2]) {
            into.radius_sum += r;
            into.triangles += 1;
        }
        return;
    }
    let origin = points[0];
    let rel = |p: &[f64; 3]| [p[0] - origin[0], p[1] - origin[1], p[2] - origin[2]];
    let (cov, centre) = covariance(points.iter().map(rel));
    let axis = principal(cov).major();
    // Split into parts whose sizes are multiples of three where possible, so that clusters of
    // exactly three remain at the bottom.
    let left = (points.len() / 6).max(1) * 3;
    let along = |p: &[f64; 3]| dot(rel(p), axis) - dot(centre, axis);
    points.select_nth_unstable_by(left, |x, y| along(x).total_cmp(&along(y)));
    let (a, b) = points.split_at_mut(left);
    cluster(a, into);
    cluster(b, into);
}

/// The radius of the smallest circle holding triangle (a, b, c): its circumcircle when the
/// triangle is acute, else the circle on its longest side. `None` for collinear points.
pub fn enclosing_radius(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> Option<f64> {
    let sub = |p: [f64; 3], q: [f64; 3]| [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
    let (ab, ac, bc) = (sub(b, a), sub(c, a), sub(c, b));
    let (lab, lac, lbc) = (dot(ab, ab), dot(ac, ac), dot(bc, bc));
    let area2 = {
        let n = cross(ab, ac);
        dot(n, n).sqrt()
    };
    let longest = lab.max(lac).max(lbc);
    if area2.is_nan() || area2 <= 1e-12 * longest {
        return None;
    }
    // Obtuse or right: the longest side is a diameter of the smallest enclosing circle.
    if 2.0 * longest >= lab + lac + lbc {
        return Some(longest.sqrt() / 2.0);
    }
    // Circumradius R = |ab| |ac| |bc| / (4 · area) = product / (2 · |ab × ac|).
    Some((lab * lac * lbc).sqrt() / (2.0 * area2))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn enclosing_circles_of_known_triangles() {
        let eq = enclosing_radius(
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, 3f64.sqrt() / 2.0, 0.0],
        );
        assert!((eq.expect("a triangle") - 1.0 / 3f64.sqrt()).abs() < 1e-12);
        let obtuse = enclosing_radius([0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [2.0, 0.1, 0.0]);
        assert!((obtuse.expect("a triangle") - 2.0).abs() < 1e-12);
        assert_eq!(
            enclosing_radius([0.0; 3], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]),
            None
        );
    }

    #[test]
    fn a_square_grid_clusters_into_triangles_of_its_spacing() {
        // A grid of spacing h: three neighbouring grid points are a right triangle with legs h,
        // whose enclosing radius is h·√2/2; clusters may be longer, never smaller.
        let h = 0.25;
        // Jittered: on an exact grid whole clusters fall on one line.
        let jitter = |i: usize, a: u64| ((i as u64 * 2654435761 + a * 97) % 1000) as f64 / 1000.0;
        let mut pts: Vec<[f64; 3]> = (0..48 * 48)
            .map(|i| {
                let (x, y) = ((i % 48) as f64, (i / 48) as f64);
                [
                    (x + 0.4 * jitter(i, 1)) * h,
                    (y + 0.4 * jitter(i, 2)) * h,
                    7.0,
                ]
            })
            .collect();
        let mut sizes = TriangleSizes::default();
        cluster(&mut pts, &mut sizes);
        assert!(sizes.triangles >= 700, "{} triangles", sizes.triangles);
        let mean = sizes.radius_sum / sizes.triangles as f64;
        assert!(
            mean >= h * 0.7 && mean < h * 2.5,
            "mean enclosing radius {mean} for spacing {h}"
        );
    }
}
