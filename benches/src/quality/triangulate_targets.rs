//! The targets of the `triangulate` pipeline (issue #19) checked per frame: where `points 1px`
//! leaves holes (and on the bunny scans), after its warm-up, a hole rate at most half of
//! points', an albedo SSIM at least every `edl` setting's (the shaded images are each against
//! their own lighting, eye-dome against headlight, as the other pipelines' targets compare them;
//! on the colourless scans every pipeline that covers the surface ties), and on the textured spot
//! an albedo PSNR above every `pyramid` setting's (the paper's claim: finer texture than splats).

use super::report::{Row, frames_of};
use std::fmt::Write;

/// The Markdown lines of the check, and whether every frame met the targets.
pub fn check(rows: &[Row]) -> (String, bool) {
    let frames = frames_of(rows);
    let mut out = String::new();
    let (mut checked, mut failed) = (0, 0);
    for ((scene, view, _, _), rs) in &frames {
        let find = |label: &str| rs.iter().find(|r| r.label() == label);
        let (Some(points), Some(tri)) = (find("points 1px"), find("triangulate 1px")) else {
            continue;
        };
        if scene != "bunny_scans" && points.metrics.hole_rate < 0.01 {
            continue;
        }
        checked += 1;
        let best = |pipeline: &str, f: fn(&Row) -> f64| {
            rs.iter()
                .filter(|r| r.pipeline == pipeline)
                .map(|r| f(r))
                .fold(f64::MIN, f64::max)
        };
        let edl_ssim = best("edl", |r| r.albedo_ssim);
        let pyramid_psnr = best("pyramid", |r| r.albedo_psnr);
        let holes_ok = tri.metrics.hole_rate <= 0.5 * points.metrics.hole_rate;
        let ssim_ok = tri.albedo_ssim >= edl_ssim;
        let texture_ok = scene != "spot" || tri.albedo_psnr > pyramid_psnr;
        if !(holes_ok && ssim_ok && texture_ok) {
            failed += 1;
            let _ = writeln!(
                out,
                "- MISSED {scene} view {view} density {:.3} noise {:.4}: triangulate holes {:.3} vs points {:.3}, albedo SSIM {:.3} vs edl {:.3}, albedo PSNR {:.2} vs pyramid {:.2}",
                points.density,
                points.noise,
                tri.metrics.hole_rate,
                points.metrics.hole_rate,
                tri.albedo_ssim,
                edl_ssim,
                tri.albedo_psnr,
                pyramid_psnr,
            );
        }
    }
    let _ = writeln!(
        out,
        "\ntriangulate: {} of {checked} frames meet its targets (holes at most half of points 1px; albedo SSIM at least every edl setting's; on spot, albedo PSNR above every pyramid setting's).\n",
        checked - failed
    );
    (out, failed == 0)
}
