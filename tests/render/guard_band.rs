//! The guard band: a surface that fills the view reaches the view's edges, where the pixels
//! fill from points just outside it as they do inside, and a pick there names the view's pixel.

use super::near::{converted_points, rendered_320x240};
use super::*;

/// A grid of points 3 cm apart over 4 x 4 m, and a view of it from 1 above that it fills, its
/// points 3 to 6 pixels apart on the screen; converted once for the tests here.
fn filled_view() -> (&'static Path, &'static str) {
    static DATASET: OnceLock<PathBuf> = OnceLock::new();
    let dataset = DATASET.get_or_init(|| {
        let grid: Vec<[f64; 3]> = (0..134 * 134)
            .map(|i| [(i % 134) as f64 * 0.03, (i / 134) as f64 * 0.03, 0.0])
            .collect();
        converted_points("guard-grid", &grid, true)
    });
    (dataset, "eye=2,1.4,1;target=2,2,0;fov=60")
}

/// The share of background pixels within `band` pixels of the image's edge.
fn background_at_the_edge(rgba: &[u8], (w, h): (usize, usize), band: usize) -> f64 {
    let (mut bg, mut all) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            if x < band || y < band || x >= w - band || y >= h - band {
                all += 1;
                bg += usize::from(!drawn(&rgba[(y * w + x) * 4..][..4]));
            }
        }
    }
    bg as f64 / all as f64
}

#[test]
fn a_surface_filling_the_view_reaches_its_edges() {
    // Without the band, the pixels at the edge had only the points inside to fill from: a
    // ragged frame of background 12 pixels deep covered a tenth to a half of it.
    let (dataset, camera) = filled_view();
    for pipeline in ["pyramid", "filters", "triangulate", "surfels"] {
        let rgba = rendered_320x240(dataset, &["--pipeline", pipeline, "--camera", camera]);
        let edge = background_at_the_edge(&rgba, (320, 240), 12);
        assert!(
            edge < 0.01,
            "{pipeline}: {:.1} % of the 12-pixel edge is background",
            edge * 100.0
        );
    }
}

#[test]
fn a_pick_at_the_edge_of_a_banded_view_names_the_pixel_of_the_view() {
    let (dataset, camera) = filled_view();
    for pixel in [[0u32, 120u32], [319, 120], [160, 0], [160, 239]] {
        let at = format!("{},{}", pixel[0], pixel[1]);
        let o = gpu_ok(&[
            "pick",
            s(dataset),
            "--size",
            "320x240",
            "--camera",
            camera,
            "--pixel",
            &at,
            "--pipeline",
            "triangulate",
            "--json",
        ]);
        let p: serde_json::Value = serde_json::from_slice(&o.stdout).expect("pick JSON");
        let got: Vec<i64> = (0..2)
            .map(|i| p["pixel"][i].as_i64().expect("pixel"))
            .collect();
        assert!(
            (0..2).all(|i| (got[i] - pixel[i] as i64).abs() <= 8),
            "picked at {at}, named {got:?}"
        );
        assert!(
            (0..320).contains(&got[0]) && (0..240).contains(&got[1]),
            "{got:?}"
        );
    }
}
