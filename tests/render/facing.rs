//! The facing check: a sphere whose stored normals point into it is drawn as the same sphere
//! with outward normals by every pipeline that takes a side from them (the filters' culling,
//! the surfels' bend and back faces, the triangulation's sides, the pyramid's culling), and one
//! whose normals point either way is culled nowhere. A sparse thin shell keeps its normals as
//! stored, and the pyramid shows it from outside.

use super::*;

use super::filters::{shot, shot_on};
use super::surfels::{H, W};
use strata_viewer::gpu::ProjectionPath;
use strata_viewer::pipelines::filters::NOT_OUTWARD;

const NEAR_SIDE: [u8; 3] = [40, 80, 200];
const FAR_SIDE: [u8; 3] = [200, 60, 40];

#[derive(Clone, Copy, PartialEq, Eq)]
enum Normals {
    Outward,
    Inward,
    /// Every other point's inward.
    Mixed,
}

/// A unit sphere (a Fibonacci lattice, like a scan) with the given normals: blue on the side
/// the camera of `shot` (at -y) sees, red on the far side.
fn sphere(normals: Normals) -> &'static Path {
    static CELLS: [OnceLock<PathBuf>; 3] = [OnceLock::new(), OnceLock::new(), OnceLock::new()];
    CELLS[normals as usize].get_or_init(|| {
        let dir = common::fresh_dir(&format!("render-facing-{}", normals as u8));
        let n = 60_000;
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let (mut points, mut stored) = (Vec::new(), Vec::new());
        for i in 0..n {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * i as f64;
            let p = [r * a.cos(), r * a.sin(), z];
            points.push((p, if p[1] < 0.0 { NEAR_SIDE } else { FAR_SIDE }));
            let inward = match normals {
                Normals::Outward => false,
                Normals::Inward => true,
                Normals::Mixed => i % 2 == 1,
            };
            let sign = if inward { -1.0 } else { 1.0 };
            stored.push(p.map(|v| (sign * v) as f32));
        }
        let ply = dir.join("sphere.ply");
        common::write_coloured_ply(&ply, &points, Some(&stored));
        let ds = dir.join("sphere.strata");
        common::run_ok(&["convert", s(&ply), "-o", s(&ds), "--quiet"]);
        ds
    })
}

/// The share of pixels of `a` and `b` that differ by more than `tolerance` in a channel.
fn differing(a: &[[u8; 3]], b: &[[u8; 3]], tolerance: u8) -> f64 {
    let n = a
        .iter()
        .zip(b)
        .filter(|(p, q)| {
            p.iter()
                .zip(q.iter())
                .any(|(x, y)| x.abs_diff(*y) > tolerance)
        })
        .count();
    n as f64 / a.len() as f64
}

/// How much bluer than red pixel (x, y) is: the near side is blue, the far side red.
fn blueness(rgb: &[[u8; 3]], x: u32, y: u32) -> i32 {
    let [r, _, b] = rgb[(y * W + x) as usize].map(i32::from);
    b - r
}

fn near_side_at_centre(rgb: &[[u8; 3]]) -> bool {
    blueness(rgb, W / 2, H / 2) > 40
}

#[test]
fn normals_pointing_into_the_surface_are_turned_and_draw_the_same_picture() {
    // Curved surfels everywhere: each bends away from its normal.
    let runs: [(&str, &[&str]); 4] = [
        ("filters", &[]),
        ("pyramid", &[]),
        ("surfels", &["mode=1"]),
        ("triangulate", &[]),
    ];
    for (pipeline, set) in runs {
        let outward = shot(sphere(Normals::Outward), pipeline, set);
        assert_eq!(
            outward.sides,
            Some("as stored"),
            "{pipeline}: outward normals"
        );
        assert!(
            near_side_at_centre(&outward.rgb),
            "{pipeline}: the near side shows"
        );
        let inward = shot(sphere(Normals::Inward), pipeline, set);
        assert_eq!(
            inward.sides,
            Some("turned"),
            "{pipeline}: inward normals are found out"
        );
        // Culled as stored, the near side was lost and the far side shown from inside.
        assert!(
            near_side_at_centre(&inward.rgb),
            "{pipeline}: the near side shows"
        );
        let share = differing(&outward.rgb, &inward.rgb, 3);
        assert!(
            share < 0.001,
            "{pipeline}: {share:.4} of the pixels differ from the outward sphere's"
        );
    }
    // The 32-bit projection (no 64-bit atomics, as on GL) culls by the same turned normals.
    let outward = shot_on(
        ProjectionPath::Int32,
        sphere(Normals::Outward),
        "filters",
        &[],
    );
    let inward = shot_on(
        ProjectionPath::Int32,
        sphere(Normals::Inward),
        "filters",
        &[],
    );
    assert_eq!(inward.sides, Some("turned"));
    let share = differing(&outward.rgb, &inward.rgb, 3);
    assert!(
        share < 0.001,
        "32-bit path: {share:.4} of the pixels differ"
    );
}

#[test]
fn normals_pointing_either_way_mark_no_side_and_nothing_is_culled() {
    let mixed = shot(sphere(Normals::Mixed), "filters", &[]);
    assert_eq!(mixed.sides, Some("mixed"));
    assert_eq!(mixed.note, Some(NOT_OUTWARD), "nothing is culled");
    assert!(near_side_at_centre(&mixed.rgb), "the near side shows");
}

/// Pixels of the far side (red) with the near side (blue) two pixels off on both sides, across
/// or along: the far side seen through a pinhole of the near one (the far side's own rim,
/// just past the silhouette, has no near side beyond it).
fn far_side_in_pinholes(rgb: &[[u8; 3]]) -> usize {
    let near = |x: u32, y: u32| blueness(rgb, x, y) > 40;
    let mut n = 0;
    for y in 2..H - 2 {
        for x in 2..W - 2 {
            let across = near(x - 2, y) && near(x + 2, y);
            let along = near(x, y - 2) && near(x, y + 2);
            n += usize::from(blueness(rgb, x, y) < -40 && (across || along));
        }
    }
    n
}

#[test]
fn surfels_of_normals_pointing_either_way_keep_the_far_side_out_of_the_pinholes() {
    // Planar surfels, so that no bend tells the two runs apart. With outward normals the far
    // side's surfels are back faces, and one that wins a pinhole of the near side gives it to
    // the near side about it; with normals either way no face is a back face, and depth
    // alone has to find the pinholes.
    let outward = shot(sphere(Normals::Outward), "surfels", &["mode=0"]);
    let mixed = shot(sphere(Normals::Mixed), "surfels", &["mode=0"]);
    assert_eq!(mixed.sides, Some("mixed"));
    assert!(near_side_at_centre(&mixed.rgb), "the near side shows");
    let (seen_outward, seen_mixed) = (
        far_side_in_pinholes(&outward.rgb),
        far_side_in_pinholes(&mixed.rgb),
    );
    eprintln!("far side in pinholes: outward {seen_outward}, mixed {seen_mixed}");
    assert!(
        seen_mixed <= 2 && seen_outward <= 2,
        "the far side shows in {seen_mixed} pinholes with normals either way, {seen_outward} with outward ones"
    );
}

/// An open cylinder whose wall is 1 % of its radius thick, sampled sparsely (a few points per
/// hundred pixels of each wall), its normals pointing out of the wall on both faces: grey
/// outside, red inside. Its radii come from both walls' points, so its surfels leave gaps.
fn sparse_shell() -> &'static Path {
    static SHELL: OnceLock<PathBuf> = OnceLock::new();
    SHELL.get_or_init(|| {
        let dir = common::fresh_dir("render-facing-shell");
        let mut unit = common::unit_randoms(11);
        let (mut points, mut normals) = (Vec::new(), Vec::new());
        for k in 0..20_000 {
            let outer = k % 2 == 0;
            let radius = if outer { 1.0 } else { 0.99 };
            let a = unit() * std::f64::consts::TAU;
            let (c, s) = (a.cos(), a.sin());
            let colour = if outer {
                [200, 200, 200]
            } else {
                [200, 40, 40]
            };
            points.push(([radius * c, radius * s, unit() * 2.0], colour));
            let side = if outer { 1.0 } else { -1.0 };
            normals.push([(side * c) as f32, (side * s) as f32, 0.0]);
        }
        let ply = dir.join("shell.ply");
        common::write_coloured_ply(&ply, &points, Some(&normals));
        let ds = dir.join("shell.strata");
        // Radii beside the normals given, which surfels are sized by.
        common::run_ok(&[
            "convert",
            s(&ply),
            "-o",
            s(&ds),
            "--normals",
            "keep",
            "--quiet",
        ]);
        ds
    })
}

const SHELL_CAMERA: &str = "eye=0,-6,3;target=0,0,1;fov=40";

/// A cell's sample of the sparse shell often misses the near outer wall; the inner walls
/// behind it then put the side turned away in front, and the check once said "mixed"
/// (culling and back faces off in every pipeline). Behind a front of the side facing the eye
/// those cells say nothing.
#[test]
fn a_sparse_thin_shell_keeps_its_normals_as_stored() {
    let (st, _) = render_stats(
        sparse_shell(),
        "shell",
        &[
            "--size",
            "320x240",
            "--pipeline",
            "filters",
            "--camera",
            SHELL_CAMERA,
        ],
    );
    assert_eq!(
        st["frames"][0]["normal_sides"].as_str(),
        Some("as stored"),
        "{st}"
    );
}

/// The share of pixels in the middle of the shell's outer wall that show its inner wall.
fn inner_wall_share(pipeline: &str) -> f64 {
    let (_, image) = render_stats(
        sparse_shell(),
        &format!("shell-{pipeline}"),
        &[
            "--size",
            "320x240",
            "--pipeline",
            pipeline,
            "--camera",
            SHELL_CAMERA,
        ],
    );
    let (w, _, rgba) = read_png(&image);
    let (mut red, mut all) = (0, 0);
    for y in 110..170 {
        for x in 130..190 {
            let p = &rgba[4 * (y * w as usize + x)..][..3];
            all += 1;
            if p[0] > p[1].saturating_add(60) {
                red += 1;
            }
        }
    }
    red as f64 / all as f64
}

/// The pyramid culls back faces too: its hidden-point removal cannot part two sheets 1 % of
/// the radius apart, and showed the inner wall in red specks through the outer one's gaps
/// (a sixth of the wall's pixels). The surfels blended the inner wall's back faces, within z_o
/// of the outer wall, into its colour, and drew them where the outer wall's surfels left a
/// gap (a pinhole whose near side is about as deep).
#[test]
fn a_thin_shell_is_shown_from_outside() {
    for pipeline in ["pyramid", "surfels"] {
        let share = inner_wall_share(pipeline);
        assert!(
            share < 0.02,
            "{pipeline}: {share:.3} of the pixels show the inner wall"
        );
    }
}
