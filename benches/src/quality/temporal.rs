//! What the harness measures over frames rather than of one frame: how many frames a pipeline
//! that builds on the previous frame needs after a camera jump until its hole rate is within
//! 10 % of its converged value, and how much the picture flickers during a slow orbit (the mean
//! per-pixel change between consecutive frames) against the reference mesh lit the same way.

use super::reference::{ReferenceRenderer, lit_as, reference_clip};
use glam::Mat3;
use strata_viewer::gpu::GpuContext;
use strata_viewer::pipelines::{PipelineInfo, edl, params::ParamSpec};
use strata_viewer::{Camera, Renderer, Settings};

/// The jump the convergence is measured after: the camera turned this far about the target.
pub const JUMP_DEG: f32 = 60.0;
/// The orbit: this many frames, each turned this far about the target's vertical.
pub const ORBIT_FRAMES: u32 = 10;
pub const ORBIT_STEP_DEG: f32 = 0.5;
/// The frames after a jump by which a pipeline's hole rate must have settled (issue #19).
pub const TARGET_JUMP_FRAMES: u32 = 8;
/// Frames after the jump that are looked at; the converged value is the last of them.
const JUMP_HORIZON: u32 = 24;

/// One pipeline's temporal measures on one view.
#[derive(Debug, Clone)]
pub struct Temporal {
    pub scene: String,
    pub view: usize,
    pub density: f64,
    pub pipeline: &'static str,
    /// Frames after the jump until the hole rate stays within 10 % of its converged value (1:
    /// the first frame is already there); `None` for a pipeline that keeps no previous frame.
    pub jump_frames: Option<u32>,
    /// Mean absolute change per pixel and channel (of 255) between consecutive orbit frames,
    /// and the same for the reference mesh lit as the pipeline lights; `None` where the orbit
    /// was not flown (the stability scenes).
    pub flicker: Option<(f64, f64)>,
}

/// `camera` turned by `deg` about the vertical through its target.
pub fn turned(camera: &Camera, deg: f32) -> Camera {
    let r = Mat3::from_rotation_z(deg.to_radians());
    Camera {
        eye: camera.target + r * (camera.eye - camera.target),
        ..*camera
    }
}

/// The frame index (1-based) from which the hole rates stay within 10 % of the last one.
pub fn settled_after(rates: &[f32]) -> u32 {
    let Some(&converged) = rates.last() else {
        return 0;
    };
    // A floor for a converged rate of zero: one pixel in ten thousand.
    let tolerance = (0.1 * converged).max(1e-4);
    let first_outside = rates
        .iter()
        .rposition(|r| (r - converged).abs() > tolerance);
    first_outside.map_or(1, |i| i as u32 + 2)
}

/// Frames `settings` needs after jumping to `camera` from the camera turned `JUMP_DEG` away,
/// settled there first: the hole rate is the harness's own (the reference mesh's surface
/// pixels left empty), not the pipeline's estimate, which cannot see gaps wider than its
/// search.
pub fn jump_frames(
    renderer: &mut Renderer,
    settings: &Settings,
    reference: &ReferenceRenderer,
    ctx: &GpuContext,
    camera: &Camera,
    (w, h): (u32, u32),
) -> anyhow::Result<u32> {
    let (near, far) = reference_clip(renderer.dataset(), camera, w as f32 / h as f32);
    let surface = reference
        .render(
            ctx,
            camera.view(),
            camera.projection(w as f32 / h as f32, near, far),
            w,
            h,
            settings.background,
        )?
        .surface;
    let away = turned(camera, JUMP_DEG);
    for _ in 0..=settings.pipeline.warmup_frames(&settings.params) {
        renderer.frame(&away, w, h, settings)?;
        renderer.wait_gpu()?;
    }
    let mut rates = Vec::new();
    for _ in 0..JUMP_HORIZON {
        renderer.frame(camera, w, h, settings)?;
        renderer.wait_gpu()?;
        let frame = renderer.read_surface()?;
        let (mut holes, mut of) = (0usize, 0usize);
        for (r, f) in surface.iter().zip(&frame) {
            of += usize::from(r.is_some());
            holes += usize::from(r.is_some() && f.is_none());
        }
        rates.push(holes as f32 / of.max(1) as f32);
    }
    Ok(settled_after(&rates))
}

/// The mean absolute difference per channel between two RGBA images (alpha left out).
pub fn mean_change(a: &[u8], b: &[u8]) -> f64 {
    let (sum, n) = a
        .chunks_exact(4)
        .zip(b.chunks_exact(4))
        .fold((0u64, 0u64), |(s, n), (p, q)| {
            let d: u64 = (0..3).map(|k| p[k].abs_diff(q[k]) as u64).sum();
            (s + d, n + 3)
        });
    sum as f64 / n.max(1) as f64
}

/// The orbit's flicker with `settings`, and the reference mesh's lit as `pipeline` lights,
/// starting settled at `camera`.
pub fn orbit_flicker(
    renderer: &mut Renderer,
    settings: &Settings,
    reference: &ReferenceRenderer,
    ctx: &GpuContext,
    camera: &Camera,
    (w, h): (u32, u32),
) -> anyhow::Result<(f64, f64)> {
    let pipeline: &PipelineInfo = settings.pipeline;
    for _ in 0..=pipeline.warmup_frames(&settings.params) {
        renderer.frame(camera, w, h, settings)?;
        renderer.wait_gpu()?;
    }
    let aspect = w as f32 / h as f32;
    let default = |spec: &ParamSpec| spec.default;
    let edl_params = (default(&edl::STRENGTH), default(&edl::RADIUS));
    let (mut before, mut before_ref): (Option<Vec<u8>>, Option<Vec<u8>>) = (None, None);
    let (mut change, mut change_ref) = (0.0, 0.0);
    for k in 0..=ORBIT_FRAMES {
        let cam = turned(camera, k as f32 * ORBIT_STEP_DEG);
        renderer.frame(&cam, w, h, settings)?;
        renderer.wait_gpu()?;
        let (_, _, rgba) = renderer.read_image()?;
        let (near, far) = reference_clip(renderer.dataset(), &cam, w as f32 / h as f32);
        let image = reference.render(
            ctx,
            cam.view(),
            cam.projection(aspect, near, far),
            w,
            h,
            settings.background,
        )?;
        let lit = lit_as(&image, pipeline.lighting, edl_params);
        if let (Some(b), Some(br)) = (&before, &before_ref) {
            change += mean_change(b, &rgba);
            change_ref += mean_change(br, &lit);
        }
        before = Some(rgba);
        before_ref = Some(lit);
    }
    let n = ORBIT_FRAMES as f64;
    Ok((change / n, change_ref / n))
}

/// The markdown table of the temporal measures, worst view per scene, density and pipeline.
pub fn markdown(rows: &[Temporal]) -> String {
    let mut md = String::from(
        "\n## Over frames\n\nFrames until the hole rate is within 10 % of its converged value after a jump of \
         60° about the target (pipelines that build on the previous frame; worst view), and the flicker of a \
         slow orbit (0.5° a frame): the mean change per pixel and channel between consecutive frames, against \
         the reference mesh's lit the same way (ratio 1: as steady as the mesh).\n\n\
         | scene | density | pipeline | frames after a jump | flicker | mesh flicker | ratio |\n|---|---|---|---|---|---|---|\n",
    );
    let mut keys: Vec<(String, u64, &str)> = rows
        .iter()
        .map(|r| (r.scene.clone(), r.density.to_bits(), r.pipeline))
        .collect();
    keys.sort();
    keys.dedup();
    for (scene, bits, pipeline) in keys {
        let of: Vec<&Temporal> = rows
            .iter()
            .filter(|r| r.scene == scene && r.density.to_bits() == bits && r.pipeline == pipeline)
            .collect();
        let jump = of.iter().filter_map(|r| r.jump_frames).max();
        let flown: Vec<(f64, f64)> = of.iter().filter_map(|r| r.flicker).collect();
        let (flicker, reference) = if flown.is_empty() {
            ("- | -".to_string(), "-".to_string())
        } else {
            let n = flown.len() as f64;
            let f = flown.iter().map(|v| v.0).sum::<f64>() / n;
            let r = flown.iter().map(|v| v.1).sum::<f64>() / n;
            (
                format!("{f:.2} | {r:.2}"),
                format!("{:.2}", f / r.max(1e-9)),
            )
        };
        md.push_str(&format!(
            "| {scene} | {:.3} | {pipeline} | {} | {flicker} | {reference} |\n",
            f64::from_bits(bits),
            jump.map_or("-".to_string(), |j| j.to_string()),
        ));
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn a_jump_settles_from_the_first_frame_that_stays_within_ten_percent() {
        assert_eq!(settled_after(&[0.5, 0.3, 0.11, 0.1, 0.1]), 3);
        assert_eq!(settled_after(&[0.1, 0.1]), 1);
        // A rate that strays again later counts from after its last stray.
        assert_eq!(settled_after(&[0.1, 0.5, 0.1, 0.1]), 3);
        // Converged at zero: within one pixel in ten thousand.
        assert_eq!(settled_after(&[0.01, 0.00005, 0.0]), 2);
    }

    #[test]
    fn the_change_between_images_is_per_channel_without_alpha() {
        let a = [10u8, 20, 30, 255, 0, 0, 0, 255];
        let b = [13u8, 20, 30, 0, 0, 0, 6, 0];
        assert!((mean_change(&a, &b) - 9.0 / 6.0).abs() < 1e-12);
        assert_eq!(mean_change(&a, &a), 0.0);
    }

    #[test]
    fn turning_keeps_the_target_and_the_distance() {
        let c = Camera {
            eye: Vec3::new(3.0, 0.0, 1.0),
            target: Vec3::new(0.0, 0.0, 1.0),
            fov_y: 0.8,
        };
        let t = turned(&c, 90.0);
        assert!((t.eye - Vec3::new(0.0, 3.0, 1.0)).length() < 1e-5);
        assert_eq!(t.target, c.target);
    }
}
