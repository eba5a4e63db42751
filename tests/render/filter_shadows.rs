//! Paper 004's point shadows on a plate over the ground, whose shadow is known exactly: hard
//! and soft in `filters`, the same in `pyramid`, casters outside the view loaded for the light,
//! and the lit stream kept while nothing it depends on changes.

use super::*;
use std::sync::Arc;
use strata_viewer::gpu::{GpuContext, ProjectionPath};
use strata_viewer::{Camera, Renderer, Settings};

// The surfels' view, whose size the shadow shots share.
use super::surfels::{H, W};
/// A grey ground (3 x 3, z = 0) under a plate (0.6 x 0.6 at z = 0.6), points 0.01 apart with
/// normals up, as a PLY.
fn plate_over_ground() -> &'static Path {
    static CELL: OnceLock<PathBuf> = OnceLock::new();
    CELL.get_or_init(|| {
        let dir = common::fresh_dir("render-filters-shadow");
        let mut pts = Vec::new();
        let step = 0.01;
        for (half, z) in [(1.5, 0.0), (0.3, 0.6)] {
            let n = (2.0 * half / step) as i32;
            for i in 0..=n {
                for j in 0..=n {
                    pts.push([-half + i as f64 * step, -half + j as f64 * step, z]);
                }
            }
        }
        let ply = dir.join("plate.ply");
        let grey: Vec<([f64; 3], [u8; 3])> = pts.iter().map(|p| (*p, [180, 180, 180])).collect();
        common::write_coloured_ply(&ply, &grey, Some(&vec![[0.0, 0.0, 1.0]; pts.len()]));
        let ds = dir.join("plate.strata");
        common::run_ok(&["convert", s(&ply), "-o", s(&ds), "--quiet"]);
        ds
    })
}

/// A renderer of the plate scene, its camera from above, and the dataset's anchor.
fn plate_from_above() -> (Renderer, Camera, glam::Vec3) {
    let ds = Arc::new(StreamDataset::open_path(plate_over_ground()).expect("dataset opens"));
    let ctx = Arc::new(GpuContext::new(ProjectionPath::Auto).expect("GPU adapter"));
    let r = Renderer::new(ctx, ds.clone(), 1 << 30, 1).expect("renderer");
    let anchor = ds.anchor().as_vec3();
    let camera = Camera {
        eye: glam::Vec3::new(0.0, -0.5, 4.0) - anchor,
        target: -anchor,
        fov_y: 45f32.to_radians(),
    };
    (r, camera, anchor)
}

/// The plate scene seen from above, lit from +x and above; the image and the pixel of each
/// ground point asked for.
fn shadow_shot(set: &[&str], ground: &[[f32; 2]]) -> (Vec<[u8; 3]>, Vec<usize>) {
    shadow_shot_in("filters", set, ground)
}

/// `shadow_shot` through `pipeline`.
fn shadow_shot_in(pipeline: &str, set: &[&str], ground: &[[f32; 2]]) -> (Vec<[u8; 3]>, Vec<usize>) {
    let (mut r, camera, anchor) = plate_from_above();
    let settings = lit_from_x_in(pipeline, set);
    paths::frame_until_complete(&mut r, &camera, W, H, &settings);
    r.frame(&camera, W, H, &settings).expect("frame");
    r.wait_gpu().expect("GPU");
    let (_, _, rgba) = r.read_image().expect("image");
    let pixels = ground
        .iter()
        .map(|p| pixel_of(&camera, anchor, *p))
        .collect();
    (
        rgba.chunks_exact(4).map(|p| [p[0], p[1], p[2]]).collect(),
        pixels,
    )
}

pub(super) fn grey(p: [u8; 3]) -> f32 {
    p.iter().map(|&c| c as f32).sum::<f32>() / 3.0
}

/// `filters` lit from +x and above (the plate's shadow falls towards -x), with `set`.
fn lit_from_x(set: &[&str]) -> Settings {
    lit_from_x_in("filters", set)
}

fn lit_from_x_in(pipeline: &str, set: &[&str]) -> Settings {
    let mut settings = Settings {
        budget: 10_000_000,
        ..Settings::default()
    };
    settings.set_pipeline(pipeline).expect("pipeline");
    for a in ["light=1,0,1"].iter().chain(set) {
        settings.set_param(a).expect("parameter");
    }
    settings
}

/// The pixel (row-major index) a point of the floor at (x, y) lands on.
fn pixel_of(camera: &Camera, anchor: glam::Vec3, [x, y]: [f32; 2]) -> usize {
    let aspect = W as f32 / H as f32;
    let view_proj = glam::camera::rh::proj::directx::perspective(camera.fov_y, aspect, 0.1, 100.0)
        * camera.view();
    let clip = view_proj * (glam::Vec3::new(x, y, 0.0) - anchor).extend(1.0);
    let ndc = clip.truncate() / clip.w;
    let px = ((ndc.x * 0.5 + 0.5) * W as f32) as usize;
    let py = ((0.5 - ndc.y * 0.5) * H as f32) as usize;
    py * W as usize + px
}

#[test]
fn the_plate_shades_the_ground_hard_and_soft() {
    // The light from +x at 45°: the plate's shadow lies 0.6 towards -x, x in [-0.9, -0.3].
    let ground = [[-0.6, 0.0], [0.6, 0.0], [-0.6, 0.8]];
    let (plain, at) = shadow_shot(&[], &ground);
    let (hard, _) = shadow_shot(&["shadows=1"], &ground);
    let [shadowed, lit, beside] = [at[0], at[1], at[2]].map(|i| grey(hard[i]));
    let albedo = 180.0;
    assert!(
        (shadowed - albedo * 0.25).abs() < 12.0,
        "in the shadow only the ambient term: {shadowed} (lit {lit})"
    );
    assert!(
        lit > 2.0 * shadowed && beside > 2.0 * shadowed,
        "{shadowed} {lit} {beside}"
    );
    assert!(
        (grey(plain[at[1]]) - lit).abs() < 4.0,
        "a lit point is lit as without shadows: {} against {lit}",
        grey(plain[at[1]])
    );
    // Soft: across the shadow's edge at x = -0.3 the light's share rises monotonically.
    let across: Vec<[f32; 2]> = (0..=40).map(|k| [-0.6 + 0.015 * k as f32, 0.0]).collect();
    let (soft, line) = shadow_shot(
        &["shadows=2", "shadow_samples=16", "light_size=20"],
        &across,
    );
    let values: Vec<f32> = line.iter().map(|&i| grey(soft[i])).collect();
    let dips = values
        .windows(3)
        .filter(|w| w[1] < w[0] - 2.0 && w[1] < w[2] - 2.0)
        .count();
    assert_eq!(dips, 0, "speckle across the penumbra: {values:?}");
    let (first, last) = (values[0], values[values.len() - 1]);
    let middle = values
        .iter()
        .filter(|v| **v > first + 8.0 && **v < last - 8.0)
        .count();
    assert!(
        last > 2.0 * first && middle >= 3,
        "a penumbra, not a step: {values:?}"
    );
}

/// Beyond the paper: `pyramid` shades with the same per-point lit stream, its shares carried
/// through the pull-push with the colour, so its picture shows the plate's shadow as the
/// filters' does, and a lit point looks as it does without shadows.
#[test]
fn the_pyramid_shows_the_same_shadows() {
    let ground = [[-0.6, 0.0], [0.6, 0.0], [-0.6, 0.8]];
    let (plain, at) = shadow_shot_in("pyramid", &[], &ground);
    let (hard, _) = shadow_shot_in("pyramid", &["shadows=1"], &ground);
    let [shadowed, lit, beside] = [at[0], at[1], at[2]].map(|i| grey(hard[i]));
    assert!(
        (shadowed - 180.0 * 0.25).abs() < 12.0,
        "in the shadow only the ambient term: {shadowed} (lit {lit})"
    );
    assert!(
        lit > 2.0 * shadowed && beside > 2.0 * shadowed,
        "{shadowed} {lit} {beside}"
    );
    // Without shadows the point in the shadow is lit (its normal, estimated beside the plate's
    // edge, turns it a little from the light: 142 against 152 on lavapipe).
    let unshadowed = [at[0], at[1]].map(|i| grey(plain[i]));
    assert!(
        unshadowed[0] > 2.5 * shadowed && (unshadowed[1] - lit).abs() < 4.0,
        "without shadows both points are lit, the lit one as with them: {unshadowed:?} against {lit}"
    );
}

#[test]
fn shadow_casters_outside_the_view_are_loaded_for_the_light() {
    // Close over one corner of the floor: the plate and most of the floor lie outside the view.
    let ds = Arc::new(StreamDataset::open_path(plate_over_ground()).expect("dataset opens"));
    let ctx = Arc::new(GpuContext::new(ProjectionPath::Auto).expect("GPU adapter"));
    let anchor = ds.anchor().as_vec3();
    let camera = Camera {
        eye: glam::Vec3::new(-1.2, -1.2, 0.5) - anchor,
        target: glam::Vec3::new(-1.4, -1.4, 0.0) - anchor,
        fov_y: 30f32.to_radians(),
    };
    let resident = |set: &[&str]| {
        let mut r = Renderer::new(ctx.clone(), ds.clone(), 1 << 30, 1).expect("renderer");
        let settings = lit_from_x(set);
        paths::frame_until_complete(&mut r, &camera, W, H, &settings);
        let stats = r.frame(&camera, W, H, &settings).expect("frame");
        assert!(stats.complete);
        (stats.nodes_resident, stats.nodes_drawn)
    };
    let (plain, drawn) = resident(&[]);
    let (shadowed, shadowed_drawn) = resident(&["shadows=1"]);
    assert_eq!(drawn, shadowed_drawn, "the camera draws the same nodes");
    assert!(
        shadowed > plain,
        "the light's view loads casters beyond the {plain} nodes the view needs ({shadowed})"
    );
}

#[test]
fn hiding_the_caster_takes_its_shadow_away() {
    // The same renderer, so the kept shadow must be computed again when the filters change.
    let (mut r, camera, anchor) = plate_from_above();
    let mut settings = lit_from_x(&["shadows=1"]);
    let at = pixel_of(&camera, anchor, [-0.6, 0.0]);
    let mut grey_at = |settings: &Settings| {
        paths::frame_until_complete(&mut r, &camera, W, H, settings);
        r.frame(&camera, W, H, settings).expect("frame");
        r.wait_gpu().expect("GPU");
        let (_, _, rgba) = r.read_image().expect("image");
        grey([rgba[4 * at], rgba[4 * at + 1], rgba[4 * at + 2]])
    };
    let shadowed = grey_at(&settings);
    settings.filter.elevation = Some((-1.0, 0.3));
    let uncovered = grey_at(&settings);
    assert!(
        uncovered > 2.0 * shadowed,
        "the hidden plate still casts: {shadowed} before, {uncovered} after"
    );
}

#[test]
fn shadows_are_kept_while_nothing_they_depend_on_changes() {
    let (mut r, camera, _) = plate_from_above();
    let mut settings = lit_from_x(&["shadows=2", "shadow_samples=8"]);
    settings.pass_clock = strata_viewer::gpu::timing::PassClock::Wall;
    paths::frame_until_complete(&mut r, &camera, W, H, &settings);
    let mut shadow_ms = |settings: &Settings, camera: &Camera| {
        let stats = r.frame(camera, W, H, settings).expect("frame");
        r.wait_gpu().expect("GPU");
        stats.passes.get("shadows")
    };
    shadow_ms(&settings, &camera);
    assert_eq!(
        shadow_ms(&settings, &camera),
        None,
        "a still frame recomputed the shadows"
    );
    // A new light: computed again.
    settings.set_param("light=1,0.5,1").expect("light");
    assert!(
        shadow_ms(&settings, &camera).is_some(),
        "a new light kept the old shadows"
    );
    assert_eq!(
        shadow_ms(&settings, &camera),
        None,
        "all samples in one still frame"
    );
}
