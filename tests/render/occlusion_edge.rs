//! `triangulate` at an occlusion edge: a small panel near the eye before a wall far behind it.
//! The wall's points behind the panel are culled against the reprojected depth; kept as
//! neighbours (not drawn), they let the fans of the wall's visible points reach under the
//! panel's outline, where the fans stopped a spacing short of it and left a ring of holes.

use super::surfels::{DISTANCE, FOV_DEG, H, W};
use super::triangulate::Session;
use super::*;
use strata_viewer::gpu::ProjectionPath;

const WALL: [u8; 3] = [200, 190, 170];
const PANEL: [u8; 3] = [60, 120, 220];
/// Distances from the eye, which stands DISTANCE before the origin, looking along +y.
const WALL_AT: f64 = 9.0;
const PANEL_AT: f64 = 1.5;
/// The panel's half width and half height, in pixels.
const PANEL_HALF_PX: (f64, f64) = (70.0, 50.0);

/// Metres a pixel spans at `depth` from the eye.
fn pixel_at(depth: f64) -> f64 {
    2.0 * depth * (FOV_DEG as f64 / 2.0).to_radians().tan() / H as f64
}

/// Points scattered at random (as a scan samples, with gaps of every width) over a rectangle
/// at `depth` from the eye, `half_px` pixels to each side of the view's centre, one for every
/// four pixels.
fn sampled(depth: f64, half_px: (f64, f64), rgb: [u8; 3], seed: u64) -> Vec<([f64; 3], [u8; 3])> {
    let size = pixel_at(depth);
    let mut rng = strata_converter::synth::Rng::new(seed, 0, 0);
    let mut unit = move || rng.unit();
    let n = (half_px.0 * half_px.1) as usize;
    (0..n)
        .map(|_| {
            let x = (2.0 * unit() - 1.0) * half_px.0 * size;
            let z = (2.0 * unit() - 1.0) * half_px.1 * size;
            ([x, depth - DISTANCE as f64, z], rgb)
        })
        .collect()
}

fn panel_before_wall() -> &'static Path {
    static CELL: OnceLock<PathBuf> = OnceLock::new();
    CELL.get_or_init(|| {
        let dir = common::fresh_dir("render-occlusion-edge");
        let mut points = sampled(WALL_AT, (230.0, 170.0), WALL, 3);
        points.extend(sampled(PANEL_AT, PANEL_HALF_PX, PANEL, 5));
        let ply = dir.join("panel.ply");
        common::write_coloured_ply(&ply, &points, None);
        let ds = dir.join("panel.strata");
        common::run_ok(&["convert", s(&ply), "-o", s(&ds), "--quiet"]);
        ds
    })
}

#[test]
fn the_wall_behind_a_near_panel_closes_up_to_the_panel_s_outline() {
    let mut session = Session::new(ProjectionPath::Auto, panel_before_wall(), "triangulate");
    let camera = session.camera(glam::Vec3::NEG_Y);
    session.load(&camera);
    let shot = session.settled(&camera);
    // The band from one to four pixels outside the panel's outline, all round it.
    let (cx, cy) = (W as f64 / 2.0, H as f64 / 2.0);
    let (hx, hz) = PANEL_HALF_PX;
    let mut band = 0;
    let mut open = Vec::new();
    for y in 0..H {
        for x in 0..W {
            let (dx, dy) = ((x as f64 + 0.5 - cx).abs(), (y as f64 + 0.5 - cy).abs());
            let outside = (dx - hx).max(dy - hz);
            if (1.0..=4.0).contains(&outside) {
                band += 1;
                if !shot.covered[(y * W + x) as usize] {
                    open.push((x, y));
                }
            }
        }
    }
    assert!(band > 1000, "{band} pixels in the band");
    assert!(
        open.len() <= 2,
        "{} of the {band} pixels round the panel are open: {:?}",
        open.len(),
        &open[..open.len().min(20)]
    );
}
