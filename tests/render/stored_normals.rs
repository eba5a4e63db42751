//! `pyramid` with the dataset's normals (`stored_normals`): a flat square facing the eye whose
//! points carry normals tilted 30 degrees off it, half of them stored pointing the other way.
//! The shading takes the stored normal, turned towards the eye, at every pixel, the holes the
//! pull-push fills included; without them, the paper's normals from the filled depth are the
//! square's own.

use super::surfels::{DISTANCE, FOV_DEG, H, W};
use super::triangulate::Session;
use super::*;
use strata_viewer::gpu::ProjectionPath;

/// The square's half width and half height, in pixels; one point for every two pixels, at
/// random (a pixel in two is left empty by one-pixel points).
const HALF_PX: (f64, f64) = (120.0, 80.0);
const TILT_DEG: f32 = 30.0;

/// The stored normal, world space: towards the eye (-y) turned TILT_DEG towards +x.
fn tilted() -> [f32; 3] {
    let t = TILT_DEG.to_radians();
    [t.sin(), -t.cos(), 0.0]
}

fn tilted_square() -> &'static Path {
    static CELL: OnceLock<PathBuf> = OnceLock::new();
    CELL.get_or_init(|| {
        let dir = common::fresh_dir("render-stored-normals");
        let size = 2.0 * DISTANCE as f64 * (FOV_DEG as f64 / 2.0).to_radians().tan() / H as f64;
        let mut uniform = common::unit_randoms(17);
        let n = (2.0 * HALF_PX.0 * HALF_PX.1) as usize;
        let (mut points, mut normals) = (Vec::new(), Vec::new());
        for k in 0..n {
            let x = (2.0 * uniform() - 1.0) * HALF_PX.0 * size;
            let z = (2.0 * uniform() - 1.0) * HALF_PX.1 * size;
            points.push(([x, 0.0, z], [200, 190, 170]));
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            normals.push(tilted().map(|c| c * sign));
        }
        let ply = dir.join("square.ply");
        common::write_coloured_ply(&ply, &points, Some(&normals));
        let ds = dir.join("square.strata");
        common::run_ok(&["convert", s(&ply), "-o", s(&ds), "--quiet"]);
        ds
    })
}

/// Of the drawn pixels inside the square, clear of its outline: how many, and their mean and
/// largest angle (degrees) from `want`, a view-space normal.
fn angle_inside(normals: &[Option<[f32; 3]>], want: glam::Vec3) -> (usize, f32, f32) {
    let (mut n, mut sum, mut worst) = (0, 0.0, 0.0f32);
    for (i, normal) in normals.iter().enumerate() {
        let (x, y) = ((i as u32 % W) as f64 + 0.5, (i as u32 / W) as f64 + 0.5);
        let (dx, dy) = ((x - W as f64 / 2.0).abs(), (y - H as f64 / 2.0).abs());
        if dx > HALF_PX.0 - 4.0 || dy > HALF_PX.1 - 4.0 {
            continue;
        }
        if let Some(normal) = normal {
            let cos = glam::Vec3::from(*normal).normalize_or_zero().dot(want);
            let angle = cos.clamp(-1.0, 1.0).acos().to_degrees();
            sum += angle;
            worst = worst.max(angle);
            n += 1;
        }
    }
    (n, sum / n.max(1) as f32, worst)
}

#[test]
fn the_pyramid_shades_with_the_stored_normals_through_its_holes() {
    let t = TILT_DEG.to_radians();
    // View space: x right (+x in the world), z towards the eye (-y).
    let stored = glam::Vec3::new(t.sin(), 0.0, t.cos());
    let square = glam::Vec3::Z;
    let inside = ((2.0 * HALF_PX.0 - 8.0) * (2.0 * HALF_PX.1 - 8.0)) as usize;
    for path in [ProjectionPath::Auto, ProjectionPath::Int32] {
        let points = {
            let mut points = Session::new(path, tilted_square(), "points");
            let camera = points.camera(glam::Vec3::NEG_Y);
            points.load(&camera);
            points.settled(&camera)
        };
        let open = points.covered.iter().filter(|c| !**c).count();
        for (on, want, off_by) in [("1", stored, 1.0), ("0", square, 5.0)] {
            let mut pyramid = Session::new(path, tilted_square(), "pyramid");
            pyramid.set(&format!("stored_normals={on}"));
            let camera = pyramid.camera(glam::Vec3::NEG_Y);
            pyramid.load(&camera);
            let shot = pyramid.settled(&camera);
            let (pixels, error, worst) = angle_inside(&shot.normals, want);
            // Every pixel inside is drawn, those one-pixel points leave open too.
            assert!(
                pixels == inside && open > inside / 4,
                "{path:?} stored_normals={on}: {pixels} of {inside} pixels drawn ({open} open by points)"
            );
            assert!(
                error < off_by,
                "{path:?} stored_normals={on}: the normals {error:.2} degrees off {want}"
            );
            // Every pixel, the holes the push fills included, takes the stored normal (the
            // octahedral encoding keeps it within a hundredth of a degree).
            if on == "1" {
                assert!(
                    worst < 0.5,
                    "{path:?}: a pixel's normal {worst:.2} degrees off the stored {want}"
                );
            }
        }
    }
}
