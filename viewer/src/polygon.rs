//! Whether a polygon of picked points crosses itself, seen across its own plane.

use glam::DVec3;

/// The first two edges (numbered from 1, the closing edge last) of the polygon `points` that
/// cross each other, seen across its plane: that of the largest triangle its first corner
/// makes with two others (a bowtie's loops cancel in its vector area, so that cannot say).
/// `None` for fewer than four corners, or corners on one line.
pub fn crossing_edges(points: &[[f64; 3]]) -> Option<(usize, usize)> {
    let n = points.len();
    if n < 4 {
        return None;
    }
    // Relative to the first corner: real-world coordinates are large, their products larger.
    let o = DVec3::from_array(points[0]);
    let rel: Vec<DVec3> = points.iter().map(|p| DVec3::from_array(*p) - o).collect();
    let mut normal = DVec3::ZERO;
    for i in 1..n {
        for j in i + 1..n {
            let c = rel[i].cross(rel[j]);
            if c.length() > normal.length() {
                normal = c;
            }
        }
    }
    let normal = normal.try_normalize()?;
    let u = normal.any_orthonormal_vector();
    let v = normal.cross(u);
    let flat: Vec<[f64; 2]> = rel.iter().map(|p| [p.dot(u), p.dot(v)]).collect();
    let side = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
        ((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])).signum()
    };
    let edge = |i: usize| (flat[i], flat[(i + 1) % n]);
    for i in 0..n {
        // Edges that share a corner with edge i meet it there; they do not cross it.
        for j in i + 2..n {
            if i == 0 && j == n - 1 {
                continue;
            }
            let ((p, q), (r, s)) = (edge(i), edge(j));
            let (d1, d2) = (side(p, q, r), side(p, q, s));
            let (d3, d4) = (side(r, s, p), side(r, s, q));
            if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
                return Some((i + 1, j + 1));
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    const O: [f64; 3] = [500_000.0, 4_600_000.0, 100.0];

    fn at(points: &[[f64; 3]]) -> Vec<[f64; 3]> {
        points
            .iter()
            .map(|p| [O[0] + p[0], O[1] + p[1], O[2] + p[2]])
            .collect()
    }

    #[test]
    fn crossings_are_found_across_the_polygons_own_plane() {
        // A bowtie seen from above, and the same square with its corners in order.
        let bowtie = at(&[
            [0.0, 0.0, 0.0],
            [2.0, 2.0, 0.0],
            [2.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
        ]);
        assert_eq!(crossing_edges(&bowtie), Some((1, 3)));
        let square = at(&[
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 2.0, 0.0],
            [0.0, 2.0, 0.0],
        ]);
        assert_eq!(crossing_edges(&square), None);
        // On a wall (x fixed), seen across it.
        let wall = at(&[
            [1.0, 0.0, 0.0],
            [1.0, 2.0, 2.0],
            [1.0, 2.0, 0.0],
            [1.0, 0.0, 2.0],
        ]);
        assert_eq!(crossing_edges(&wall), Some((1, 3)));
        // On a wall at 45 degrees, wider than tall: seen from above it is a line.
        let slanted = at(&[
            [0.0, 0.0, 0.0],
            [10.0, 10.0, 2.0],
            [10.0, 10.0, 0.0],
            [0.0, 0.0, 2.0],
        ]);
        assert_eq!(crossing_edges(&slanted), Some((1, 3)));
        // The same wall's corners in order, picked a centimetre off: no crossing.
        let picked = at(&[
            [0.0, 0.0, 0.0],
            [10.0, 10.01, 0.0],
            [10.01, 10.0, 2.0],
            [0.0, 0.01, 2.0],
        ]);
        assert_eq!(crossing_edges(&picked), None);
        // A non-convex polygon that does not cross itself.
        let notch = at(&[
            [0.0, 0.0, 0.0],
            [4.0, 0.0, 0.0],
            [4.0, 4.0, 0.0],
            [2.0, 1.0, 0.0],
            [0.0, 4.0, 0.0],
        ]);
        assert_eq!(crossing_edges(&notch), None);
        // Corners on one line: no plane, no answer.
        let line = at(&[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
        ]);
        assert_eq!(crossing_edges(&line), None);
    }
}
