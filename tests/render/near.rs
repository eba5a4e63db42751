//! The near plane and the eye: every point in view is drawn however far off the view axis the
//! nearest ones lie, and a surfel that reaches behind the eye is still drawn.

use super::*;

/// An ASCII PLY of `points` (x y z), converted, in a folder of its own.
pub(super) fn converted_points(name: &str, points: &[[f64; 3]], normals: bool) -> PathBuf {
    let dir = common::fresh_dir(&format!("render-near-{name}"));
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty double x\nproperty double y\n\
         property double z\nend_header\n",
        points.len()
    );
    for p in points {
        ply.push_str(&format!("{} {} {}\n", p[0], p[1], p[2]));
    }
    let input = dir.join("in.ply");
    std::fs::write(&input, ply).expect("ply");
    let out = dir.join("ds");
    let mut args = vec!["convert", s(&input), "-o", s(&out), "--quiet"];
    if normals {
        args.push("--normals=compute");
    }
    common::run_ok(&args);
    out
}

/// `dataset` rendered at 320x240 with `args`, as RGBA.
pub(super) fn rendered_320x240(dataset: &Path, args: &[&str]) -> Vec<u8> {
    let out = dataset.with_extension("png");
    let mut all = vec!["render", s(dataset), "-o", s(&out), "--size", "320x240"];
    all.extend_from_slice(args);
    gpu_ok(&all);
    read_png(&out).2
}

#[test]
fn points_far_off_the_view_axis_next_to_the_eye_are_drawn() {
    // A line seen from beside its end: the nearest points lie far from the view axis, nearer
    // along it than their distance (the near plane took the distance and cut them off).
    let line: Vec<[f64; 3]> = (0..=50).map(|i| [i as f64, 0.0, 0.0]).collect();
    let dataset = converted_points("line", &line, false);
    let (w, h) = (320u32, 240u32);
    let rgba = rendered_320x240(&dataset, &["--pipeline", "points", "--point-size", "3"]);
    let ds = StreamDataset::open_path(&dataset).expect("dataset opens");
    let camera = default_camera(&ds, w, h);
    let vp = camera.projection(w as f32 / h as f32, 0.01, 1e4) * camera.view();
    let mut missing = Vec::new();
    for p in &line {
        let rel = (glam::DVec3::from_array(*p) - ds.anchor()).as_vec3();
        let q = vp.project_point3(rel);
        let (x, y) = ((q.x * 0.5 + 0.5) * w as f32, (0.5 - q.y * 0.5) * h as f32);
        // Drawn within a pixel of where it projects.
        let near_drawn = (-1..=1).any(|dy| {
            (-1..=1).any(|dx| {
                let (px, py) = (x as i64 + dx, y as i64 + dy);
                (0..w as i64).contains(&px)
                    && (0..h as i64).contains(&py)
                    && drawn(&rgba[((py as u32 * w + px as u32) * 4) as usize..][..4])
            })
        });
        if !near_drawn {
            missing.push(p[0]);
        }
    }
    assert!(missing.is_empty(), "points at x = {missing:?} not drawn");
}

#[test]
fn a_surfel_reaching_behind_the_eye_is_drawn() {
    // A grid of 1-unit spacing, its normals computed, seen from 0.8 above: the surfels under
    // the eye reach past it (they were dropped whole, leaving an empty picture).
    let grid: Vec<[f64; 3]> = (0..100)
        .map(|i| [(i % 10) as f64, (i / 10) as f64, 0.0])
        .collect();
    let dataset = converted_points("grid", &grid, true);
    let camera = "eye=4.5,4.5,0.8;target=4.5,4.5,0;fov=120";
    let rgba = rendered_320x240(&dataset, &["--pipeline", "surfels", "--camera", camera]);
    let covered = rgba.chunks_exact(4).filter(|px| drawn(px)).count();
    // The eight points under the eye, each a disc of at least 16 pixels' radius.
    assert!(covered > 8 * 500, "{covered} pixels drawn");
}

/// A scan 20 km long, seen along its length from inside one end, with a patch a few
/// centimetres across 0.1 m in front of the eye, below the view's axis: the near plane took a
/// hundred-thousandth of the far one (0.2 m here) and cut the patch off. The patch is drawn,
/// and so is the point at the far end, on the axis at 99 % of the far plane (the far plane of
/// the f32 matrix is noise at this ratio: `Frustum::of_view`, `in_depth_range`).
#[test]
fn a_surface_a_hand_away_in_a_scan_kilometres_long_is_drawn_with_its_far_end() {
    // The box's corners, off the axis; the far end on it.
    let mut points: Vec<[f64; 3]> = vec![
        [0.0, -300.0, -300.0],
        [20_000.0, 300.0, 300.0],
        [20_000.0, 0.0, 0.0],
    ];
    // In the plane x = 5.1, facing the eye at x = 5, from 1 to 5 cm below the axis, 2 mm apart.
    for j in 0..=50 {
        for k in 0..=20 {
            points.push([5.1, -0.05 + j as f64 * 0.002, -0.05 + k as f64 * 0.002]);
        }
    }
    let dataset = converted_points("deep", &points, false);
    let camera = "eye=5,0,0;target=6,0,0;fov=30";
    let rgba = rendered_320x240(
        &dataset,
        &[
            "--pipeline",
            "points",
            "--point-size",
            "4",
            "--camera",
            camera,
        ],
    );
    let (w, h) = (320usize, 240usize);
    let at = |x: usize, y: usize| drawn(&rgba[(y * w + x) * 4..][..4]);
    // The lower rows show the patch: about 27 x 13 of its points, 9 pixels apart, each a disc
    // of 4 pixels across (12 pixels).
    let patch = (h / 2 + 50..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| at(x, y))
        .count();
    assert!(patch > 27 * 13 * 8, "{patch} pixels of the patch drawn");
    // The far end, at the centre of the image.
    let centre = (h / 2 - 2..h / 2 + 2).any(|y| (w / 2 - 2..w / 2 + 2).any(|x| at(x, y)));
    assert!(centre, "the far end is not drawn");
}
