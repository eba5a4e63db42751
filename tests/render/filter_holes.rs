//! The `filters` background fill on holes in a sampling whose radii are stored: a hole the
//! masks cannot close (four pixels and more across: they see three by three pixels, and take
//! its edge for an outline) is closed where it is no wider than two radii, the widest gap the
//! sampling can leave; a wider one is a hole in the data, and stays open.

use super::filters::shot_at;
use super::surfels::{DISTANCE, FOV_DEG, H, W};
use super::*;
use strata_viewer::gpu::ProjectionPath;

/// Grid spacing of the samples, in pixels.
const STEP: u32 = 3;
/// The square's side, in grid steps.
const STEPS: u32 = 40;
/// Grid cells left out: a small block (3 steps between the points round it) and a large one
/// (7 steps), as (first column, first row, side).
const SMALL: (u32, u32, u32) = (8, 8, 2);
const LARGE: (u32, u32, u32) = (24, 24, 6);

fn in_block((c0, r0, side): (u32, u32, u32), c: u32, r: u32) -> bool {
    (c0..c0 + side).contains(&c) && (r0..r0 + side).contains(&r)
}

/// The pixel at grid step (c, r).
fn pixel(c: u32, r: u32) -> (u32, u32) {
    (
        W / 2 - STEPS * STEP / 2 + c * STEP,
        H / 2 - STEPS * STEP / 2 + r * STEP,
    )
}

/// A square facing the camera, sampled every STEP pixels, with the two blocks left out;
/// normals given (towards the camera), radii from `--normals`.
fn holed_square() -> &'static Path {
    static CELL: OnceLock<PathBuf> = OnceLock::new();
    CELL.get_or_init(|| {
        let dir = common::fresh_dir("render-filter-holes");
        let size = 2.0 * DISTANCE as f64 * (FOV_DEG as f64 / 2.0).to_radians().tan() / H as f64;
        let mut points = Vec::new();
        for r in 0..STEPS {
            for c in 0..STEPS {
                if in_block(SMALL, c, r) || in_block(LARGE, c, r) {
                    continue;
                }
                let (x, y) = pixel(c, r);
                let x = (x as f64 + 0.5 - W as f64 / 2.0) * size;
                let z = (H as f64 / 2.0 - y as f64 - 0.5) * size;
                points.push(([x, 0.0, z], super::filters::OUTER));
            }
        }
        let ply = dir.join("holed.ply");
        let towards_camera = vec![[0f32, -1.0, 0.0]; points.len()];
        common::write_coloured_ply(&ply, &points, Some(&towards_camera));
        let ds = dir.join("holed.strata");
        common::run_ok(&["convert", s(&ply), "-o", s(&ds), "--quiet", "--normals"]);
        ds
    })
}

#[test]
fn a_hole_no_wider_than_the_sampling_can_leave_closes_and_a_wider_one_stays_open() {
    let shot = shot_at(
        ProjectionPath::Auto,
        holed_square(),
        "filters",
        &[],
        Some(0.0),
    );
    let at = |(x, y): (u32, u32)| shot.covered[(y * W + x) as usize];
    // The pixels between the points round the small block: all covered.
    let (c0, r0, side) = SMALL;
    let (x0, y0) = pixel(c0 - 1, r0 - 1);
    let (x1, y1) = pixel(c0 + side, r0 + side);
    let open: Vec<(u32, u32)> = (y0..=y1)
        .flat_map(|y| (x0..=x1).map(move |x| (x, y)))
        .filter(|&p| !at(p))
        .collect();
    assert!(open.is_empty(), "the small hole leaves {open:?} open");
    // The large block's middle: open.
    let (c0, r0, side) = LARGE;
    let (mx, my) = pixel(c0 + side / 2, r0 + side / 2);
    let filled: Vec<(u32, u32)> = (my - 3..=my + 3)
        .flat_map(|y| (mx - 3..=mx + 3).map(move |x| (x, y)))
        .filter(|&p| at(p))
        .collect();
    assert!(filled.is_empty(), "the large hole is filled at {filled:?}");
}
