//! The `filters` pipeline (paper 004) on spheres whose outline and layers are known exactly:
//! it closes the holes `points` leaves without growing past the outline, back faces are culled
//! in the projection (past a margin, as fitted normals lean off a face at its edges) and
//! strictly in every peel, the layers blend front to back with the opacities
//! (per class too), and without normals it says so and peels back faces as layers.

use super::*;
use std::sync::Arc;
use strata_viewer::gpu::{GpuContext, ProjectionPath};
use strata_viewer::pipelines::filters::{LAYERS_USED, NO_NORMALS};
use strata_viewer::{Camera, Renderer, Settings};

use super::filter_shadows::grey;

// The surfels' view of a unit sphere, and their measure of its outline.
use super::surfels::{DISTANCE, FOV_DEG, H, W, holes_and_overshoot};
pub(super) const OUTER: [u8; 3] = [40, 80, 200];
pub(super) const INNER: [u8; 3] = [200, 60, 40];

/// Points evenly over a sphere of `radius` (a Fibonacci lattice, like a scan).
fn lattice(n: usize, radius: f64) -> impl Iterator<Item = [f64; 3]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n).map(move |i| {
        let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
        let r = (1.0 - z * z).sqrt();
        let a = golden * i as f64;
        [radius * r * a.cos(), radius * r * a.sin(), radius * z]
    })
}

/// Two nested spheres (radius 1, blue, and 0.5, red), as a PLY with their outward normals
/// (`normals`) or as a LAS without normals whose outer sphere is class 2 and inner class 6.
pub(super) fn nested(normals: bool) -> &'static Path {
    static CELLS: [OnceLock<PathBuf>; 2] = [OnceLock::new(), OnceLock::new()];
    CELLS[normals as usize].get_or_init(|| {
        let dir = common::fresh_dir(&format!("render-filters-{normals}"));
        let spheres = [(1.0, 60_000, OUTER, 2u8), (0.5, 15_000, INNER, 6u8)];
        let input = if normals {
            let ply = dir.join("nested.ply");
            let (mut points, mut normals) = (Vec::new(), Vec::new());
            for (radius, n, rgb, _) in spheres {
                for p in lattice(n, radius) {
                    points.push((p, rgb));
                    normals.push(p.map(|v| (v / radius) as f32));
                }
            }
            common::write_coloured_ply(&ply, &points, Some(&normals));
            ply
        } else {
            let path = dir.join("nested.las");
            let mut builder = las::Builder::from((1, 2));
            builder.point_format = las::point::Format::new(2).expect("format 2");
            builder.transforms = las::Vector {
                x: las::Transform {
                    scale: 1e-4,
                    offset: 0.0,
                },
                y: las::Transform {
                    scale: 1e-4,
                    offset: 0.0,
                },
                z: las::Transform {
                    scale: 1e-4,
                    offset: 0.0,
                },
            };
            let header = builder.into_header().expect("header");
            let mut writer = las::Writer::from_path(&path, header).expect("las");
            for (radius, n, [r, g, b], class) in spheres {
                for [x, y, z] in lattice(n, radius) {
                    let point = las::Point {
                        x,
                        y,
                        z,
                        classification: las::point::Classification::new(class).expect("class"),
                        color: Some(las::Color::new(
                            u16::from(r) * 257,
                            u16::from(g) * 257,
                            u16::from(b) * 257,
                        )),
                        ..Default::default()
                    };
                    writer.write_point(point).expect("point");
                }
            }
            writer.close().expect("close");
            path
        };
        let ds = dir.join("nested.strata");
        common::run_ok(&["convert", s(&input), "-o", s(&ds), "--quiet"]);
        ds
    })
}

pub(super) struct Shot {
    pub(super) rgb: Vec<[u8; 3]>,
    pub(super) covered: Vec<bool>,
    measures: std::collections::BTreeMap<&'static str, f32>,
    pub(super) note: Option<&'static str>,
    /// The facing check's verdict (`FrameStats::normal_sides`).
    pub(super) sides: Option<&'static str>,
}

impl Shot {
    fn centre(&self) -> [u8; 3] {
        self.rgb[(H / 2 * W + W / 2) as usize]
    }
}

pub(super) fn shot(dataset: &Path, pipeline: &str, set: &[&str]) -> Shot {
    shot_on(ProjectionPath::Auto, dataset, pipeline, set)
}

pub(super) fn shot_on(path: ProjectionPath, dataset: &Path, pipeline: &str, set: &[&str]) -> Shot {
    shot_at(path, dataset, pipeline, set, None)
}

/// `shot_on` with the LOD's finest drawn spacing set (0: every node drawn).
pub(super) fn shot_at(
    path: ProjectionPath,
    dataset: &Path,
    pipeline: &str,
    set: &[&str],
    min_spacing_px: Option<f32>,
) -> Shot {
    let ds = Arc::new(StreamDataset::open_path(dataset).expect("dataset opens"));
    let ctx = Arc::new(GpuContext::new(path).expect("GPU adapter"));
    let mut r = Renderer::new(ctx, ds.clone(), 1 << 30, 1).expect("renderer");
    let anchor = ds.anchor().as_vec3();
    let camera = Camera {
        eye: glam::Vec3::new(0.0, -DISTANCE, 0.0) - anchor,
        target: -anchor,
        fov_y: FOV_DEG.to_radians(),
    };
    let mut settings = Settings {
        budget: 10_000_000,
        ..Settings::default()
    };
    if let Some(px) = min_spacing_px {
        settings.min_spacing_px = px;
    }
    settings.set_pipeline(pipeline).expect("pipeline");
    // One-pixel points: what `points` leaves open at this density.
    settings.point_size = 1.0;
    settings.size_mode = strata_viewer::settings::SizeMode::Fixed;
    for a in set {
        settings.set_param(a).expect("parameter");
    }
    paths::frame_until_complete(&mut r, &camera, W, H, &settings);
    let stats = r.frame(&camera, W, H, &settings).expect("frame");
    r.wait_gpu().expect("GPU");
    let (_, _, rgba) = r.read_image().expect("image");
    let covered = r
        .read_surface()
        .expect("surface")
        .iter()
        .map(Option::is_some)
        .collect();
    Shot {
        rgb: rgba.chunks_exact(4).map(|p| [p[0], p[1], p[2]]).collect(),
        covered,
        measures: r.read_measures().expect("measures"),
        note: stats.note,
        sides: stats.normal_sides,
    }
}

/// A surface seen head-on under the shared headlight: albedo · (ambient + diffuse) + specular.
fn head_on(albedo: [u8; 3]) -> [f32; 3] {
    albedo.map(|c| (c as f32 / 255.0 + 0.25).min(1.0) * 255.0)
}

fn near(got: [u8; 3], want: [f32; 3], tolerance: f32) -> bool {
    got.iter()
        .zip(want)
        .all(|(g, w)| (*g as f32 - w).abs() <= tolerance)
}

#[test]
fn filters_close_the_holes_points_leave_without_growing_past_the_outline() {
    let points = shot(nested(true), "points", &[]);
    let (points_holes, _) = holes_and_overshoot(&points.covered);
    assert!(
        points_holes > 0.2,
        "points at this density leave holes ({points_holes:.3})"
    );
    let filters = shot(nested(true), "filters", &[]);
    let (holes, overshoot) = holes_and_overshoot(&filters.covered);
    assert!(
        holes < 0.01 && holes <= 0.5 * points_holes,
        "filters leave {holes:.4} of the sphere empty (points {points_holes:.3})"
    );
    assert!(
        overshoot < 1.5,
        "the outline reaches {overshoot:.2} px beyond the sphere's"
    );
    assert_eq!(filters.note, None, "kept normals face out: culling applies");
    // The outer sphere's front, lit head-on, in front of everything at the centre.
    assert!(
        near(filters.centre(), head_on(OUTER), 12.0),
        "{:?}",
        filters.centre()
    );
}

#[test]
fn sparse_points_are_drawn_as_wide_as_their_radius_and_the_masks_close_the_rest() {
    use super::surfels::{Lod, Sphere, shot as sphere_shot};
    let points = sphere_shot(Sphere::Sparse, "points", &[], Lod::Full);
    let (points_holes, _) = holes_and_overshoot(&points.covered);
    // The paper's one pixel a point: its masks take holes this wide for the outside, but the
    // stored radii say how wide a gap the sampling can leave, and the fill closes those.
    let one_pixel = sphere_shot(Sphere::Sparse, "filters", &["splat=0"], Lod::Full);
    let (one_pixel_holes, one_pixel_overshoot) = holes_and_overshoot(&one_pixel.covered);
    assert!(
        points_holes > 0.15 && one_pixel_holes < 0.02 && one_pixel_overshoot < 0.5,
        "one-pixel points leave {one_pixel_holes:.3} of the sphere empty (points \
         {points_holes:.3}) and reach {one_pixel_overshoot:.2} px beyond its outline"
    );
    let splats = sphere_shot(Sphere::Sparse, "filters", &[], Lod::Full);
    let (holes, overshoot) = holes_and_overshoot(&splats.covered);
    assert!(
        holes < 0.02 && holes <= 0.5 * points_holes,
        "points as wide as their radius leave {holes:.4} of the sphere empty (points {points_holes:.3})"
    );
    // Squares as large as the discs seen obliquely (0.8 px beyond the outline where as wide
    // as the discs themselves).
    assert!(
        overshoot < 0.5,
        "the outline reaches {overshoot:.2} px beyond the sphere's"
    );
    // Where the LOD stopped at the root, its points stand for the ones it did not load: they
    // are drawn as wide as the root's spacing, and leave no hole either.
    let coarse = sphere_shot(Sphere::Dense, "filters", &[], Lod::Root);
    let (coarse_holes, _) = holes_and_overshoot(&coarse.covered);
    assert!(
        coarse_holes < 0.02,
        "a coarse LOD leaves {coarse_holes:.4} of the sphere empty"
    );
    let coarse_one_pixel = sphere_shot(Sphere::Dense, "filters", &["splat=0"], Lod::Root);
    let (coarse_one_pixel_holes, _) = holes_and_overshoot(&coarse_one_pixel.covered);
    assert!(
        coarse_one_pixel_holes > 2.0 * coarse_holes + 0.05,
        "one-pixel points of the root alone leave {coarse_one_pixel_holes:.4} empty"
    );
}

#[test]
fn peeled_layers_blend_front_to_back_and_back_faces_stay_culled() {
    let one = shot(nested(true), "filters", &["layers=1", "opacity=0.5"]);
    assert_eq!(one.measures[LAYERS_USED], 1.0);
    let background = BACKGROUND.map(f32::from);
    let (outer, inner) = (head_on(OUTER), head_on(INNER));
    let blend = |parts: &[([f32; 3], f32)]| {
        let mut out = [0.0; 3];
        for (c, w) in parts {
            for k in 0..3 {
                out[k] += c[k] * w;
            }
        }
        out
    };
    assert!(
        near(
            one.centre(),
            blend(&[(outer, 0.5), (background, 0.5)]),
            12.0
        ),
        "{:?}",
        one.centre()
    );
    // Four layers asked, two there: the back halves are culled in every peel.
    let four = shot(nested(true), "filters", &["layers=4", "opacity=0.5"]);
    assert_eq!(four.measures[LAYERS_USED], 2.0, "{:?}", four.measures);
    assert!(
        near(
            four.centre(),
            blend(&[(outer, 0.5), (inner, 0.25), (background, 0.25)]),
            12.0
        ),
        "{:?}",
        four.centre()
    );
}

#[test]
fn peels_are_the_same_on_the_32_and_64_bit_paths() {
    // One 64-bit pass where the device has the atomics, two 32-bit passes where not (GL).
    let set = ["layers=4", "opacity=0.5"];
    let wide = shot_on(ProjectionPath::Auto, nested(true), "filters", &set);
    let narrow = shot_on(ProjectionPath::Int32, nested(true), "filters", &set);
    assert_eq!(wide.measures[LAYERS_USED], narrow.measures[LAYERS_USED]);
    assert!(
        wide.rgb == narrow.rgb,
        "the two paths peel different layers"
    );
}

#[test]
fn class_opacities_and_without_normals_every_surface_is_a_layer() {
    let opaque = shot(nested(false), "filters", &["layers=4"]);
    assert_eq!(opaque.note, Some(NO_NORMALS));
    // Not culled: both halves of both spheres are layers.
    assert_eq!(opaque.measures[LAYERS_USED], 4.0, "{:?}", opaque.measures);
    assert!(
        near(opaque.centre(), head_on(OUTER), 16.0),
        "{:?}",
        opaque.centre()
    );
    // The outer sphere (class 2) made clear: the inner one shows, lit head-on.
    let clear = shot(nested(false), "filters", &["layers=4", "opacity.2=0"]);
    assert!(
        near(clear.centre(), head_on(INNER), 16.0),
        "{:?}",
        clear.centre()
    );
    let (holes, _) = holes_and_overshoot(&clear.covered);
    assert!(
        holes < 0.01,
        "the first layer's surface is kept for the harness ({holes:.4} empty)"
    );
}

/// The shading is compiled per mode (anti-aliasing, normals estimated or carried): each mode
/// must reach the image, not the default's pass.
#[test]
fn each_shade_mode_draws_its_own_image() {
    let smooth = shot(nested(true), "filters", &[]);
    let aliased = shot(nested(true), "filters", &["antialias=0"]);
    let changed = smooth
        .rgb
        .iter()
        .zip(&aliased.rgb)
        .filter(|(a, b)| a != b)
        .count();
    assert!(
        changed >= 50,
        "anti-aliasing the silhouette changes {changed} pixels"
    );
    // Without normals they are estimated from the filled depth: the sphere darkens towards its
    // outline under the headlight, where a normal facing the eye would light it as its centre.
    let estimated = shot(nested(false), "filters", &["antialias=0"]);
    let row = (H / 2 * W) as usize;
    let first = (0..W as usize)
        .find(|&x| estimated.covered[row + x])
        .expect("the sphere crosses the middle row");
    let rim = grey(estimated.rgb[row + first + 2]);
    let centre = grey(estimated.centre());
    assert!(
        rim < centre - 30.0,
        "near the outline {rim:.0}, at the centre {centre:.0}"
    );
}

const TREE: [u8; 3] = [40, 200, 60];
const WALL: [u8; 3] = [200, 200, 200];
const FAR: [u8; 3] = [40, 80, 200];
// The tree's half-width, and the depths (along +y, the view) of the tree, the wall and the far
// plane.
const TREE_HALF: f64 = 0.15;
const PLANE_Y: [f64; 3] = [-0.5, 0.0, 0.5];

/// Three planes facing the camera of `shot`, their normals towards it: a small dense square
/// (the tree) in front of a wide wall with half its points missing at random, one pixel
/// each, so that a far plane shows through its holes.
fn tree_before_a_sparse_wall() -> &'static Path {
    static CELL: OnceLock<PathBuf> = OnceLock::new();
    CELL.get_or_init(|| {
        let dir = common::fresh_dir("render-filters-wall");
        let mut points: Vec<([f64; 3], [u8; 3])> = Vec::new();
        let mut grid =
            |half: f64, spacing: f64, y: f64, rgb: [u8; 3], keep: &dyn Fn(u64) -> bool| {
                let n = (2.0 * half / spacing) as i64;
                for i in 0..=n {
                    for j in 0..=n {
                        let index = (i * (n + 1) + j) as u64;
                        if keep(index) {
                            let at = |k: i64| -half + k as f64 * spacing;
                            points.push(([at(i), y, at(j)], rgb));
                        }
                    }
                }
            };
        // A pixel is 0.0065 units at the tree and 0.0078 at the wall.
        grid(TREE_HALF, 0.004, PLANE_Y[0], TREE, &|_| true);
        let hash = |k: u64| k.wrapping_mul(0x9e37_79b9_7f4a_7c15).rotate_left(29) % 2;
        grid(0.8, 0.0075, PLANE_Y[1], WALL, &|k| hash(k) != 0);
        grid(0.9, 0.008, PLANE_Y[2], FAR, &|_| true);
        let ply = dir.join("wall.ply");
        let towards_camera = vec![[0f32, -1.0, 0.0]; points.len()];
        common::write_coloured_ply(&ply, &points, Some(&towards_camera));
        let ds = dir.join("wall.strata");
        common::run_ok(&["convert", s(&ply), "-o", s(&ds), "--quiet"]);
        ds
    })
}

/// Which of the three planes' colours a pixel is nearest to.
fn plane_of(rgb: [u8; 3]) -> usize {
    let lit = [TREE, WALL, FAR].map(head_on);
    let distance = |want: [f32; 3]| {
        rgb.iter()
            .zip(want)
            .map(|(g, w)| (*g as f32 - w).powi(2))
            .sum::<f32>()
    };
    (0..3)
        .min_by(|&a, &b| distance(lit[a]).total_cmp(&distance(lit[b])))
        .unwrap_or(0)
}

/// The occluded fill takes the surface that occludes the pixel. The paper takes the nearest
/// neighbour's texel; iterated, that carries a front surface through the holes of the one behind
/// it, one hole an iteration, and the tree grows over the wall.
#[test]
fn the_occluded_fill_closes_a_wall_s_holes_with_the_wall_not_what_stands_before_it() {
    let filled = shot(tree_before_a_sparse_wall(), "filters", &["splat=0"]);
    // The tree's square seen from the camera, in pixels.
    let pixel =
        2.0 * (DISTANCE as f64 + PLANE_Y[0]) * (FOV_DEG as f64 / 2.0).to_radians().tan() / H as f64;
    let side = 2.0 * TREE_HALF / pixel;
    let mut counts = [0usize; 3];
    let mut tree_outside = 0;
    for (k, rgb) in filled.rgb.iter().enumerate() {
        if !filled.covered[k] {
            continue;
        }
        let plane = plane_of(*rgb);
        counts[plane] += 1;
        let (x, y) = ((k as u32 % W) as f64 + 0.5, (k as u32 / W) as f64 + 0.5);
        let off = (x - W as f64 / 2.0).abs().max((y - H as f64 / 2.0).abs());
        if plane == 0 && off > side / 2.0 + 1.5 {
            tree_outside += 1;
        }
    }
    // Within 1.5 px of its square: the rim anti-aliased (the paper's nearest neighbour grew it
    // 26 pixels beyond that here).
    let tree = counts[0] as f64;
    assert!(
        tree > 0.95 * side * side && tree_outside <= 3,
        "the tree covers {tree} pixels ({tree_outside} beyond its outline), its square {:.0}",
        side * side
    );
    // The wall's holes show the far plane until filled: the wall is the surface the camera
    // sees everywhere but behind the tree and beyond its edges.
    let far = counts[2] as f64;
    let all = (W * H) as f64;
    assert!(
        far < 0.01 * all,
        "{far} pixels show the far plane through the wall"
    );
}

/// Two squares facing the camera, their points' normals leaning away: the left one's 15° past
/// grazing (as a normal fitted across an edge, or a mesh's interpolated at a sharp corner,
/// leans off a visible face), the right one's straight away.
fn leaning() -> &'static Path {
    static CELL: OnceLock<PathBuf> = OnceLock::new();
    CELL.get_or_init(|| {
        let dir = common::fresh_dir("render-filters-leaning");
        let ply = dir.join("leaning.ply");
        let (mut points, mut normals) = (Vec::new(), Vec::new());
        let tilt = 15f32.to_radians();
        for (x0, normal) in [
            (-0.9, [0.0, tilt.sin(), tilt.cos()]),
            (0.1, [0.0, 1.0, 0.0]),
        ] {
            for i in 0..200 {
                for k in 0..200 {
                    let x = x0 + 0.8 * (i as f64 + 0.5) / 200.0;
                    let z = -0.4 + 0.8 * (k as f64 + 0.5) / 200.0;
                    points.push(([x, 0.0, z], OUTER));
                    normals.push(normal);
                }
            }
        }
        common::write_coloured_ply(&ply, &points, Some(&normals));
        let ds = dir.join("leaning.strata");
        common::run_ok(&["convert", s(&ply), "-o", s(&ds), "--quiet"]);
        ds
    })
}

/// A visible face whose normals lean a little past grazing was culled whole (a strip along
/// every sharp edge of a building or a box); one that turns clearly away still is, and the
/// peels still cull strictly.
#[test]
fn points_leaning_a_little_past_grazing_are_drawn_and_back_faces_are_not() {
    let opaque = shot(leaning(), "filters", &[]);
    let share = |x0: u32, x1: u32| {
        let (mut n, mut covered) = (0, 0);
        for y in H / 2 - 20..H / 2 + 20 {
            for x in x0..x1 {
                n += 1;
                covered += usize::from(opaque.covered[(y * W + x) as usize]);
            }
        }
        covered as f64 / n as f64
    };
    // The squares' middles: a third and two thirds across.
    let (left, right) = (
        share(W / 3 - 20, W / 3 + 20),
        share(2 * W / 3 - 20, 2 * W / 3 + 20),
    );
    assert!(left > 0.99, "the leaning face is {left:.3} covered");
    assert!(right < 0.01, "the face turned away is {right:.3} covered");
    let peeled = shot(leaning(), "filters", &["layers=2"]);
    assert_eq!(peeled.measures[LAYERS_USED], 1.0, "{:?}", peeled.measures);
}

/// The square of `SIDE` pixels at the centre of `shot`'s view, sampled 4 x 4 a pixel, with a
/// comb along its right edge: every other pixel row sticks out one pixel further, as a scan's
/// scattered points do along a silhouette. Normals given (towards the camera), radii from
/// `--normals`.
const SIDE: u32 = 120;

fn combed_square() -> &'static Path {
    static CELL: OnceLock<PathBuf> = OnceLock::new();
    CELL.get_or_init(|| {
        let dir = common::fresh_dir("render-filters-comb");
        let pixel = 2.0 * DISTANCE as f64 * (FOV_DEG as f64 / 2.0).to_radians().tan() / H as f64;
        let (x0, y0) = (W / 2 - SIDE / 2, H / 2 - SIDE / 2);
        let mut points = Vec::new();
        for row in y0..y0 + SIDE {
            let teeth = u32::from((row - y0) % 2 == 0);
            for col in x0..x0 + SIDE + teeth {
                for (i, j) in (0..4).flat_map(|i| (0..4).map(move |j| (i, j))) {
                    // Inside the pixel, an eighth of one from its edges.
                    let x = (col as f64 + 0.125 + 0.25 * i as f64 - W as f64 / 2.0) * pixel;
                    let z = (H as f64 / 2.0 - row as f64 - 0.125 - 0.25 * j as f64) * pixel;
                    points.push(([x, 0.0, z], OUTER));
                }
            }
        }
        let ply = dir.join("comb.ply");
        let towards_camera = vec![[0f32, -1.0, 0.0]; points.len()];
        common::write_coloured_ply(&ply, &points, Some(&towards_camera));
        let ds = dir.join("comb.strata");
        common::run_ok(&["convert", s(&ply), "-o", s(&ds), "--quiet", "--normals"]);
        ds
    })
}

/// The background fill closes the holes a point's sampling can leave, and no wider: between
/// the teeth of a dense comb no sampling gap can be, and filling them grew the outline by the
/// teeth's length (the masks of Figure 3 see no outline there). Sparse points still close
/// (`sparse_points_are_drawn_as_wide_as_their_radius_and_the_masks_close_the_rest`).
#[test]
fn the_fill_leaves_gaps_wider_than_the_sampling_open_between_a_dense_outline_s_teeth() {
    let filters = shot_at(
        ProjectionPath::Auto,
        combed_square(),
        "filters",
        &[],
        Some(0.0),
    );
    let (x0, y0) = (W / 2 - SIDE / 2, H / 2 - SIDE / 2);
    let at = |x: u32, y: u32| filters.covered[(y * W + x) as usize];
    let rows = y0 + 2..y0 + SIDE - 2;
    let teeth = rows.clone().filter(|r| (r - y0) % 2 == 0);
    let gaps = rows.clone().filter(|r| (r - y0) % 2 == 1);
    let (teeth_drawn, gaps_filled) = (
        teeth.filter(|&r| at(x0 + SIDE, r)).count(),
        gaps.clone().filter(|&r| at(x0 + SIDE, r)).count(),
    );
    assert!(
        teeth_drawn >= 55,
        "{teeth_drawn} of the comb's 58 teeth are drawn"
    );
    assert!(
        gaps_filled <= 2,
        "{gaps_filled} of the {} gaps between the teeth are filled",
        gaps.count()
    );
    let inside = (y0..y0 + SIDE)
        .flat_map(|y| (x0..x0 + SIDE).map(move |x| (x, y)))
        .filter(|&(x, y)| at(x, y))
        .count();
    assert_eq!(
        inside,
        (SIDE * SIDE) as usize,
        "the square is covered whole"
    );
}
