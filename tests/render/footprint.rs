//! A point's footprint: `--point-size N` draws a disc N pixels across, even sizes included.

use super::near::{converted_points, rendered_320x240};
use super::*;

#[test]
fn a_point_of_size_n_covers_a_disc_n_pixels_across() {
    // Four points far apart: each covers its own pixels.
    let corners = [
        [0.0, 0.0, 0.0],
        [10.0, 0.0, 0.0],
        [0.0, 10.0, 0.0],
        [10.0, 10.0, 0.0],
    ];
    let dataset = converted_points("footprint", &corners, false);
    // Per point: 1, a 2x2 square (it was 3x3, as size 3), the 3x3 square, the 4x4 square
    // without its corners.
    for (size, pixels) in [(1, 1), (2, 4), (3, 9), (4, 12)] {
        let size = size.to_string();
        let rgba = rendered_320x240(&dataset, &["--pipeline", "points", "--point-size", &size]);
        let covered = rgba.chunks_exact(4).filter(|px| drawn(px)).count();
        assert_eq!(covered, 4 * pixels, "point size {size}");
    }
}

#[test]
fn attenuated_points_default_to_two_spacings() {
    // Sized by their spacing, points keep the default multiple of 2 (the pixel default of 3
    // would draw them half again as wide). Fine enough that neither reaches the largest splat
    // (15 pixels), at about four pixels a spacing.
    let grid: Vec<[f64; 3]> = (0..3600)
        .map(|i| [(i % 60) as f64, (i / 60) as f64, 0.0])
        .collect();
    let dataset = converted_points("attenuated", &grid, false);
    let covered = |args: &[&str]| {
        let mut all = vec!["--pipeline", "points", "--attenuate"];
        all.extend_from_slice(args);
        let rgba = rendered_320x240(&dataset, &all);
        rgba.chunks_exact(4).filter(|px| drawn(px)).count()
    };
    let (default, two, three) = (
        covered(&[]),
        covered(&["--point-size", "2"]),
        covered(&["--point-size", "3"]),
    );
    assert_eq!(default, two);
    assert!(three > two, "{three} pixels at 3 spacings, {two} at 2");
}
