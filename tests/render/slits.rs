//! The surfels' pinhole rule closes holes in a near surface, not slits: through a slit the
//! surface behind shows rightly. The rule looks past a hole's own pixels for the near surface
//! across it; applied along any one direction, that would close a slit two pixels wide.

use super::*;

use super::filters::shot;
use super::surfels::{H, W};

const NEAR: [u8; 3] = [40, 80, 200];
const FAR: [u8; 3] = [200, 60, 40];

/// Two parallel planes facing the camera of `shot` (at -y), both with normals towards it: a
/// blue one at y = -0.5 with a vertical slit `gap` wide through it, a red one at y = 0.5.
fn slit_planes(gap: f64) -> PathBuf {
    let dir = common::fresh_dir(&format!("render-slit-{gap}"));
    let step = 0.004;
    let n = 200;
    let (mut points, mut normals) = (Vec::new(), Vec::new());
    for i in 0..n {
        for j in 0..n {
            let (x, z) = (
                (i as f64 - n as f64 / 2.0) * step,
                (j as f64 - n as f64 / 2.0) * step,
            );
            points.push(([x, 0.5, z], FAR));
            normals.push([0.0, -1.0, 0.0]);
            if x.abs() > gap / 2.0 {
                points.push(([x, -0.5, z], NEAR));
                normals.push([0.0, -1.0, 0.0]);
            }
        }
    }
    let ply = dir.join("planes.ply");
    common::write_coloured_ply(&ply, &points, Some(&normals));
    let ds = dir.join("planes.strata");
    common::run_ok(&["convert", s(&ply), "-o", s(&ds), "--quiet"]);
    ds
}

/// Red pixels in each of the rows across the middle of the planes (which reach 62 pixels
/// above and below the centre).
fn far_in_rows(rgb: &[[u8; 3]]) -> Vec<usize> {
    (H / 2 - 40..H / 2 + 40)
        .map(|y| {
            (0..W)
                .filter(|x| {
                    let [r, _, b] = rgb[(y * W + x) as usize].map(i32::from);
                    r - b > 40
                })
                .count()
        })
        .collect()
}

#[test]
fn a_slit_in_a_near_surface_stays_open() {
    // 0.016 wide at 2.5 from the eye, less the near surfels' reach into it: about 2 pixels.
    let shot = shot(&slit_planes(0.016), "surfels", &["mode=0"]);
    let rows = far_in_rows(&shot.rgb);
    assert!(
        rows.iter().all(|&n| n >= 1),
        "the far plane shows in every row of the slit: {rows:?}"
    );
    assert!(
        rows.iter().all(|&n| n <= 3),
        "the slit is a few pixels wide: {rows:?}"
    );
}
