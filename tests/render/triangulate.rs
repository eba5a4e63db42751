//! The `triangulate` pipeline (paper 002) on spheres whose outline and layers are known
//! exactly, from positions and colours alone: it closes the holes `points` leaves without
//! growing past the outline; the previous frame's reconstructed depth culls the inner sphere's
//! points that show through the outer one, and after a camera jump the picture converges
//! within the warm-up; both search paths (one 64-bit pass, two 32-bit passes) agree; a still
//! from the command line reports the hole rate of every warm-up frame; the dataset's normals
//! shade where it has them, steadier than the fans' under range noise; where they tell a thin
//! sheet's faces apart, the face seen is not tinted by the other.

use super::filters::{INNER, OUTER, nested};
use super::surfels::{DISTANCE, FOV_DEG, Gap, H, Sphere, W, gaps, holes_and_overshoot, sphere};
use super::*;
use std::collections::BTreeMap;
use std::sync::Arc;
use strata_viewer::gpu::{GpuContext, ProjectionPath};
use strata_viewer::pipelines::triangulate::{CULLED, HOLE_RATE, TRIANGLES};
use strata_viewer::{Camera, Renderer, Settings};

/// One renderer on one dataset, drawing with `pipeline`.
pub(super) struct Session {
    r: Renderer,
    settings: Settings,
    anchor: glam::Vec3,
}

pub(super) struct Shot {
    rgb: Vec<[u8; 3]>,
    pub(super) covered: Vec<bool>,
    /// The shaded normal per pixel, in view space.
    pub(super) normals: Vec<Option<[f32; 3]>>,
    measures: BTreeMap<&'static str, f32>,
}

impl Session {
    pub(super) fn new(path: ProjectionPath, dataset: &Path, pipeline: &str) -> Session {
        let ds = Arc::new(StreamDataset::open_path(dataset).expect("dataset opens"));
        let ctx = Arc::new(GpuContext::new(path).expect("GPU adapter"));
        let r = Renderer::new(ctx, ds.clone(), 1 << 30, 1).expect("renderer");
        let mut settings = Settings {
            budget: 10_000_000,
            ..Settings::default()
        };
        settings.set_pipeline(pipeline).expect("pipeline");
        // One-pixel points: what `points` leaves open at this density.
        settings.point_size = 1.0;
        settings.size_mode = strata_viewer::settings::SizeMode::Fixed;
        Session {
            r,
            settings,
            anchor: ds.anchor().as_vec3(),
        }
    }

    /// The camera at `DISTANCE` from the centre (the origin) along `from`, looking at it.
    pub(super) fn camera(&self, from: glam::Vec3) -> Camera {
        Camera {
            eye: from.normalize() * DISTANCE - self.anchor,
            target: -self.anchor,
            fov_y: FOV_DEG.to_radians(),
        }
    }

    /// Sets one of the pipeline's parameters, `name=value`.
    pub(super) fn set(&mut self, param: &str) {
        self.settings.set_param(param).expect("parameter");
    }

    pub(super) fn load(&mut self, camera: &Camera) {
        paths::frame_until_complete(&mut self.r, camera, W, H, &self.settings);
    }

    fn frame(&mut self, camera: &Camera) -> Shot {
        self.r.frame(camera, W, H, &self.settings).expect("frame");
        self.r.wait_gpu().expect("GPU");
        let (_, _, rgba) = self.r.read_image().expect("image");
        let surface = self.r.read_surface().expect("surface");
        Shot {
            rgb: rgba.chunks_exact(4).map(|p| [p[0], p[1], p[2]]).collect(),
            covered: surface.iter().map(Option::is_some).collect(),
            normals: surface.iter().map(|s| s.and_then(|s| s.normal)).collect(),
            measures: self.r.read_measures().expect("measures"),
        }
    }

    /// The frame after `warmup` frames of the same view (the pipeline's default).
    pub(super) fn settled(&mut self, camera: &Camera) -> Shot {
        for _ in 0..8 {
            self.frame(camera);
        }
        self.frame(camera)
    }
}

const FRONT: glam::Vec3 = glam::Vec3::NEG_Y;

/// Of the pixels within the middle half of the sphere's outline, the share whose colour is
/// nearer the inner sphere's than the outer's: the inner sphere showing through.
fn inner_share(shot: &Shot) -> f64 {
    let (cx, cy) = (W as f32 / 2.0, H as f32 / 2.0);
    let r = 0.5 * (H as f32 / 2.0) / (FOV_DEG.to_radians() / 2.0).tan() / DISTANCE;
    let dist = |a: [u8; 3], b: [u8; 3]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (*x as f32 - y as f32).abs())
            .sum::<f32>()
    };
    let (mut n, mut inner) = (0, 0);
    for (i, c) in shot.rgb.iter().enumerate() {
        let (x, y) = ((i as u32 % W) as f32 + 0.5, (i as u32 / W) as f32 + 0.5);
        if ((x - cx).powi(2) + (y - cy).powi(2)).sqrt() < r {
            n += 1;
            inner += usize::from(dist(*c, INNER) < dist(*c, OUTER));
        }
    }
    inner as f64 / n.max(1) as f64
}

#[test]
fn triangulation_closes_the_holes_points_leave_from_positions_alone() {
    // The sphere without normals: the triangulation needs positions and colours only.
    let dataset = sphere(Sphere::SparseWithoutNormals);
    let mut points = Session::new(ProjectionPath::Auto, dataset, "points");
    let camera = points.camera(FRONT);
    points.load(&camera);
    let (points_holes, _) = holes_and_overshoot(&points.frame(&camera).covered);
    assert!(
        points_holes > 0.3,
        "points at this density leave holes ({points_holes:.3})"
    );
    let mut tri = Session::new(ProjectionPath::Auto, dataset, "triangulate");
    tri.load(&camera);
    let shot = tri.settled(&camera);
    let (holes, overshoot) = holes_and_overshoot(&shot.covered);
    assert!(
        holes < 0.01 && holes <= 0.5 * points_holes,
        "the triangulation leaves {holes:.4} of the sphere empty (points {points_holes:.3})"
    );
    assert!(
        overshoot < 1.5,
        "the outline reaches {overshoot:.2} px beyond the sphere's"
    );
    // Its own count of the holes inside the silhouette agrees.
    assert!(shot.measures[HOLE_RATE] < 0.01, "{:?}", shot.measures);
    assert!(shot.measures[TRIANGLES] > 10_000.0, "{:?}", shot.measures);
}

#[test]
fn the_shade_closes_the_pinholes_the_fans_leave() {
    let dataset = sphere(Sphere::RandomWithoutNormals);
    let mut tri = Session::new(ProjectionPath::Auto, dataset, "triangulate");
    let camera = tri.camera(FRONT);
    tri.load(&camera);
    let shot = tri.settled(&camera);
    // Before the shade closed them: 25 on this sphere sampled at random.
    let pinholes = gaps(&shot.covered, Gap::Pinhole);
    assert_eq!(pinholes, 0, "{pinholes} empty pixels amid drawn ones");
}

#[test]
fn the_reprojected_depth_culls_what_shows_through_and_a_jump_converges_within_the_warmup() {
    // Nested spheres without normals: the inner (red) sphere's points land in the outer
    // (blue) one's holes until the reconstructed depth culls them.
    let mut s = Session::new(ProjectionPath::Auto, nested(false), "triangulate");
    let front = s.camera(FRONT);
    s.load(&front);
    let settled = s.settled(&front);
    assert!(
        inner_share(&settled) < 0.01,
        "the inner sphere shows through {:.3} of the outer one",
        inner_share(&settled)
    );
    assert!(settled.measures[CULLED] > 1000.0, "{:?}", settled.measures);

    // A jump to the opposite side: the kept depth (the far side now) culls nothing in front,
    // so the first frame shows the inner sphere through the holes; it converges by frame 8.
    let back = s.camera(-FRONT);
    let first = s.frame(&back);
    assert!(
        inner_share(&first) > 0.2,
        "the first frame after the jump culled before any depth of this view was kept ({:.3})",
        inner_share(&first)
    );
    let mut rates = vec![first.measures[HOLE_RATE]];
    let mut last = first;
    for _ in 1..8 {
        last = s.frame(&back);
        rates.push(last.measures[HOLE_RATE]);
    }
    let converged = s.settled(&back).measures[HOLE_RATE];
    assert!(
        inner_share(&s.frame(&back)) < 0.01,
        "after the jump the inner sphere still shows through"
    );
    assert!(
        inner_share(&last) < 0.01 && (rates[7] - converged).abs() <= 0.1 * converged.max(1e-3),
        "not converged 8 frames after the jump: hole rates {rates:?}, converged {converged}"
    );
}

#[test]
fn the_64_bit_search_and_sums_and_the_32_bit_ones_agree() {
    if !GpuContext::new(ProjectionPath::Auto)
        .expect("GPU adapter")
        .int64_atomics
    {
        eprintln!("skipped: the adapter has no 64-bit atomics, so both paths are the 32-bit one");
        return;
    }
    let dataset = sphere(Sphere::SparseWithoutNormals);
    let shots: Vec<Shot> = [ProjectionPath::Auto, ProjectionPath::Int32]
        .into_iter()
        .map(|path| {
            let mut s = Session::new(path, dataset, "triangulate");
            let camera = s.camera(FRONT);
            s.load(&camera);
            s.settled(&camera)
        })
        .collect();
    let differing = shots[0]
        .rgb
        .iter()
        .zip(&shots[1].rgb)
        .filter(|(a, b)| a.iter().zip(b.iter()).any(|(x, y)| x.abs_diff(*y) > 2))
        .count();
    // Nodes may sit in other places of the arenas (ties in depth resolve by index), so a few
    // pixels may differ; the neighbours found are the same. The 64-bit sums round each
    // fragment's colour to 1/255 (the 32-bit ones to 1/4080): a step of at most one.
    assert!(
        differing < (W * H / 500) as usize,
        "{differing} pixels differ between the 64-bit and the 32-bit paths"
    );
    assert_eq!(shots[0].covered, shots[1].covered);
}

#[test]
fn a_still_reports_the_hole_rate_of_every_warmup_frame() {
    let dir = common::fresh_dir("render-triangulate-cli");
    let (png, stats) = (dir.join("still.png"), dir.join("stats.json"));
    let dataset = sphere(Sphere::SparseWithoutNormals);
    gpu_ok(&[
        "render",
        s(dataset),
        "-o",
        s(&png),
        "--pipeline",
        "triangulate",
        "--size",
        "320x240",
        "--set",
        "warmup=3",
        "--stats",
        s(&stats),
    ]);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&stats).expect("stats")).expect("json");
    let warmup = report["warmup"].as_array().expect("warm-up frames");
    assert_eq!(warmup.len(), 3, "{report}");
    let rates: Vec<f64> = warmup
        .iter()
        .chain(report["frames"].as_array().expect("frames"))
        .map(|f| f["measures"][HOLE_RATE].as_f64().expect("hole rate"))
        .collect();
    assert!(rates.iter().all(|r| (0.0..=1.0).contains(r)), "{rates:?}");
    assert!(
        *rates.last().expect("a frame") < 0.02,
        "the still is not closed: {rates:?}"
    );
    let (w, h, _) = read_png(&png);
    assert_eq!((w, h), (320, 240));
}

#[test]
fn a_resize_starts_the_depth_afresh_and_closes_again() {
    let dataset = sphere(Sphere::SparseWithoutNormals);
    let mut s = Session::new(ProjectionPath::Auto, dataset, "triangulate");
    let camera = s.camera(FRONT);
    s.load(&camera);
    s.settled(&camera);
    // Another size: new planes, no previous depth; the kept radii carry over.
    let (w, h) = (W / 2 + 7, H / 2 + 3);
    let mut last = None;
    for k in 0..9 {
        s.r.frame(&camera, w, h, &s.settings)
            .expect("frame at the new size");
        s.r.wait_gpu().expect("GPU");
        let measures = s.r.read_measures().expect("measures");
        if k == 0 {
            // Nothing kept at this size yet: nothing is culled.
            assert_eq!(measures[CULLED], 0.0, "{measures:?}");
        }
        last = Some(measures);
    }
    let measures = last.expect("frames");
    assert!(measures[HOLE_RATE] < 0.02, "{measures:?}");
    let (iw, ih, _) = s.r.read_image().expect("image");
    assert_eq!((iw, ih), (w, h));
}

/// The unit sphere's normal in view space (x right, y up, z towards the eye) at the pixel
/// centre (x, y) of the camera at `DISTANCE` looking at its centre; `None` off the sphere.
fn sphere_normal(x: f32, y: f32) -> Option<glam::Vec3> {
    let t = (FOV_DEG.to_radians() / 2.0).tan();
    let ndc = glam::Vec2::new(x / W as f32 * 2.0 - 1.0, 1.0 - y / H as f32 * 2.0);
    let ray = glam::Vec3::new(ndc.x * t * W as f32 / H as f32, ndc.y * t, -1.0).normalize();
    let eye = glam::Vec3::new(0.0, 0.0, DISTANCE);
    // |eye + s ray| = 1, the nearer root.
    let b = eye.dot(ray);
    let disc = b * b - (eye.length_squared() - 1.0);
    (disc >= 0.0).then(|| (eye + (-b - disc.sqrt()) * ray).normalize())
}

#[test]
fn points_at_the_silhouette_take_their_triangles_normal_not_the_eye_s() {
    // A point whose own fan opens no triangle (at the outline many do) is still a corner of
    // its neighbours' triangles, and covers its own pixel; lit with the eye's direction it was
    // a bright speck along the outline, where the sphere turns away from the eye (39 of 2257
    // rim pixels here, 1.7 %; 31 on the 32-bit sums after the triangles took their own normal,
    // from pixels only such points drew). Sampled at random, as the harness samples its
    // meshes: an even lattice leaves few such points.
    let dataset = sphere(Sphere::RandomWithoutNormals);
    for path in [ProjectionPath::Auto, ProjectionPath::Int32] {
        let mut tri = Session::new(path, dataset, "triangulate");
        let camera = tri.camera(FRONT);
        tri.load(&camera);
        let shot = tri.settled(&camera);
        let (mut rim, mut facing) = (0, 0);
        for (i, n) in shot.normals.iter().enumerate() {
            let (x, y) = ((i as u32 % W) as f32 + 0.5, (i as u32 / W) as f32 + 0.5);
            let (Some(n), Some(truth)) = (n, sphere_normal(x, y)) else {
                continue;
            };
            // The outer rim, where the surface is within 30 degrees of edge-on.
            if truth.z < 0.5 {
                rim += 1;
                facing += usize::from(n[2] > 0.9);
            }
        }
        assert!(rim > 1000, "{path:?}: {rim} pixels on the rim");
        assert!(
            facing * 200 < rim,
            "{path:?}: {facing} of {rim} rim pixels face the eye"
        );
    }
}

/// Of the drawn pixels where the sphere faces the eye (within 70 degrees of it): their count
/// and the mean angle (degrees) of their shaded normal from the sphere's.
fn sphere_normal_error(shot: &Shot) -> (usize, f32) {
    let (mut n, mut sum) = (0, 0.0);
    for (i, shaded) in shot.normals.iter().enumerate() {
        let (x, y) = ((i as u32 % W) as f32 + 0.5, (i as u32 / W) as f32 + 0.5);
        let (Some(shaded), Some(truth)) = (shaded, sphere_normal(x, y)) else {
            continue;
        };
        if truth.z > 0.35 {
            n += 1;
            let cos = glam::Vec3::from(*shaded).normalize_or_zero().dot(truth);
            sum += cos.clamp(-1.0, 1.0).acos().to_degrees();
        }
    }
    (n, sum / n.max(1) as f32)
}

/// The unit sphere scanned with range noise: 60,000 points at random, each moved along its ray
/// from the centre by up to 0.4 % (4 mm at a metre) either way, about a quarter of their
/// spacing; converted with `--normals`, which estimates each point's normal from its 16
/// nearest neighbours.
fn rough_sphere() -> &'static Path {
    static CELL: OnceLock<PathBuf> = OnceLock::new();
    CELL.get_or_init(|| {
        let dir = common::fresh_dir("render-triangulate-rough");
        let ply = dir.join("rough.ply");
        let mut uniform = common::unit_randoms(5);
        let points: Vec<([f64; 3], [u8; 3])> = (0..60_000)
            .map(|_| {
                let z = 1.0 - 2.0 * uniform();
                let a = std::f64::consts::TAU * uniform();
                let r = (1.0 - z * z).sqrt();
                let range = 1.0 + 0.004 * (2.0 * uniform() - 1.0);
                (
                    [r * a.cos(), r * a.sin(), z].map(|v| v * range),
                    [200, 180, 150],
                )
            })
            .collect();
        common::write_coloured_ply(&ply, &points, None);
        let ds = dir.join("rough.strata");
        common::run_ok(&["convert", s(&ply), "-o", s(&ds), "--quiet", "--normals"]);
        ds
    })
}

#[test]
fn a_dataset_s_own_normals_shade_the_surface_and_without_them_the_fans_do() {
    // With range noise, a point's eight sector neighbours a pixel or two away tilt its fan's
    // triangles this way and that; the normals the conversion estimates from 16 neighbours in
    // the world are steadier (measured here: 2.2 degrees off the sphere on average, the fans'
    // 7.0).
    for path in [ProjectionPath::Auto, ProjectionPath::Int32] {
        let mut errors = Vec::new();
        for stored in ["1", "0"] {
            let mut tri = Session::new(path, rough_sphere(), "triangulate");
            tri.settings
                .set_param(&format!("stored_normals={stored}"))
                .expect("stored_normals");
            let camera = tri.camera(FRONT);
            tri.load(&camera);
            let (pixels, error) = sphere_normal_error(&tri.settled(&camera));
            assert!(pixels > 10_000, "{path:?}: {pixels} pixels facing the eye");
            errors.push(error);
        }
        let [own, fans] = errors[..] else {
            unreachable!("two settings")
        };
        assert!(
            own < 3.5,
            "{path:?}: the stored normals {own:.1} degrees off"
        );
        assert!(
            fans > 2.0 * own,
            "{path:?}: the fans' normals {fans:.1} degrees off, the stored {own:.1}"
        );
    }
}

/// A sheet far thinner than its point spacing, sampled at random on both faces with each
/// face's outward normal (as the harness samples a mesh, and a scanner that saw both sides
/// records them), converted keeping the normals; red on the face towards -y, blue on the other
/// (`FRONT_FACE`, `BACK_FACE`). The red face covers the whole square, or its half at x < 0.
fn sheet(red: RedFace) -> &'static Path {
    static CELLS: [OnceLock<PathBuf>; 2] = [const { OnceLock::new() }; 2];
    CELLS[red as usize].get_or_init(|| {
        let dir = common::fresh_dir(&format!("render-triangulate-sheet-{}", red as usize));
        let ply = dir.join("sheet.ply");
        let per_face = 40_000;
        let red_points = match red {
            RedFace::Whole => per_face,
            RedFace::LeftHalf => per_face / 2,
        };
        // 1.6 m square, 40,000 points a face: about 8 mm apart; the faces 2 mm apart.
        let mut uniform = common::unit_randoms(11);
        let (mut points, mut normals) = (Vec::new(), Vec::new());
        for (face, count) in [(-1.0f32, red_points), (1.0, per_face)] {
            for _ in 0..count {
                let mut x = (uniform() as f32 - 0.5) * 1.6;
                if count < per_face {
                    x = -x.abs();
                }
                let z = (uniform() as f32 - 0.5) * 1.6;
                let rgb = if face < 0.0 { FRONT_FACE } else { BACK_FACE };
                points.push(([x, face * 0.001, z].map(f64::from), rgb));
                normals.push([0.0, face, 0.0]);
            }
        }
        common::write_coloured_ply(&ply, &points, Some(&normals));
        let ds = dir.join("sheet.strata");
        common::run_ok(&["convert", s(&ply), "-o", s(&ds), "--quiet", "--normals"]);
        ds
    })
}

#[derive(Clone, Copy)]
enum RedFace {
    Whole,
    LeftHalf,
}

const FRONT_FACE: [u8; 3] = [220, 70, 50];
const BACK_FACE: [u8; 3] = [50, 70, 220];

/// Of the drawn pixels in the middle of the image: their count, the mean of their normals'
/// component towards the eye, and their mean angle (degrees) from the mean normal.
fn normal_spread(shot: &Shot) -> (usize, f32, f32) {
    let middle: Vec<glam::Vec3> = shot
        .normals
        .iter()
        .enumerate()
        .filter(|(i, _)| {
            let (x, y) = (*i as u32 % W, *i as u32 / W);
            x.abs_diff(W / 2) < W / 8 && y.abs_diff(H / 2) < H / 8
        })
        .filter_map(|(_, n)| n.map(glam::Vec3::from))
        .collect();
    let mean = middle.iter().sum::<glam::Vec3>().normalize_or_zero();
    let spread = middle
        .iter()
        .map(|n| {
            n.normalize_or_zero()
                .dot(mean)
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees()
        })
        .sum::<f32>()
        / middle.len().max(1) as f32;
    let towards_eye = middle.iter().map(|n| n.z).sum::<f32>() / middle.len().max(1) as f32;
    (middle.len(), towards_eye, spread)
}

#[test]
fn a_sheet_sampled_on_both_faces_is_not_stitched_across_them_where_normals_tell_the_sides_apart() {
    // Seen 47 degrees off its normal, each face's points show between the other's at one pixel
    // each; fans joining them zigzag across the 2 mm, and their normals scatter (4.0 degrees
    // about their mean here without normals, 0.01 with; 8.7 degrees off the truth on the
    // harness's thin fins before, 2.3 after). Where the normals tell the sides apart, each
    // face is triangulated on its own.
    let from = glam::Vec3::new(1.0, -1.0, 0.4);
    for path in [ProjectionPath::Auto, ProjectionPath::Int32] {
        let mut tri = Session::new(path, sheet(RedFace::Whole), "triangulate");
        // The fans' normals, which show the stitching (the stored ones would shade it flat).
        tri.settings
            .set_param("stored_normals=0")
            .expect("stored_normals");
        let camera = tri.camera(from);
        tri.load(&camera);
        let (pixels, towards_eye, spread) = normal_spread(&tri.settled(&camera));
        assert!(
            pixels > 5000,
            "{path:?}: {pixels} pixels drawn in the middle"
        );
        assert!(
            spread < 1.0,
            "{path:?}: the sheet's normals scatter {spread:.1} degrees about their mean"
        );
        // The face seen is 47 degrees off the eye's direction at the middle.
        assert!(
            (towards_eye - 0.68).abs() < 0.08,
            "{path:?}: the normals' mean component towards the eye is {towards_eye:.2}"
        );
    }
}

/// Blue's share of red and blue in the unlit colour `albedo` (the highlight of the shaded image
/// would add to both), and the share of pixels drawn, in the band of rows about the middle
/// between columns `from` and `to` (pixels from the middle; negative: to the left).
fn band(albedo: &[Option<[u8; 3]>], from: i32, to: i32) -> (f64, f64) {
    let (mut pixels, mut drawn, mut blue) = (0, 0, 0.0);
    for (i, c) in albedo.iter().enumerate() {
        let (x, y) = ((i as u32 % W) as i32 - (W / 2) as i32, i as u32 / W);
        if x >= from && x < to && y.abs_diff(H / 2) < H / 8 {
            pixels += 1;
            if let Some(c) = c {
                drawn += 1;
                blue += c[2] as f64 / (c[0] as f64 + c[2] as f64).max(1.0);
            }
        }
    }
    (
        blue / drawn.max(1) as f64,
        drawn as f64 / pixels.max(1) as f64,
    )
}

#[test]
fn a_sheet_s_back_face_shows_only_where_its_front_face_leaves_a_gap() {
    // Seen from its red face, which covers only the sheet's left half; the blue face covers the
    // whole. Both faces' points survive the projection at one pixel each. Their fans, each on
    // its own face, were summed alike, and the red half showed purple. The back face's fans
    // now draw only where the front's left a pixel empty. Blue's share of red and blue in the
    // unlit colour on the left: 0.185 in the red face's own, measured 0.186 (0.39 with the
    // fans summed alike); the right half is the blue face (0.815), wholly drawn (none of it
    // with the back faces' fans dropped).
    for path in [ProjectionPath::Auto, ProjectionPath::Int32] {
        let mut tri = Session::new(path, sheet(RedFace::LeftHalf), "triangulate");
        let camera = tri.camera(FRONT);
        tri.load(&camera);
        tri.settled(&camera);
        let albedo = tri.r.read_albedo().expect("albedo");
        let (left_blue, left_drawn) = band(&albedo, -(W as i32) / 6, -(W as i32) / 24);
        let (right_blue, right_drawn) = band(&albedo, W as i32 / 24, W as i32 / 6);
        assert!(
            left_drawn > 0.99 && right_drawn > 0.99,
            "{path:?}: drawn {left_drawn:.3} of the red half, {right_drawn:.3} of the blue"
        );
        assert!(
            left_blue < 0.23,
            "{path:?}: the blue face's share of the red face's pixels is {left_blue:.2}"
        );
        assert!(
            right_blue > 0.75,
            "{path:?}: the blue face's share where only it lies is {right_blue:.2}"
        );
    }
}
