//! A leaf holding more surface than its cube's face, at a density its level does not tell: an
//! open box of five walls and three partitions behind its front wall, 32 square units in a
//! cube about 3.4 units wide, scattered at random in one node and stored without radii. What is
//! sized by the points' spacing takes the spacing measured from them: the triangulation's
//! reach, and the discs of the points, which cover the front wall instead of showing the
//! partitions through it.

use super::*;
use strata_viewer::pipelines::triangulate::CONNECTION_SPACINGS;

/// The walls' colours: the front one, and every wall behind or beside it.
const FRONT: [u8; 3] = [40, 200, 60];
const BEHIND: [u8; 3] = [150, 150, 150];
const POINTS: usize = 12_000;
/// Eight walls of 2 x 2 units.
const AREA: f64 = 32.0;
const CAMERA: &str = "eye=0,-5,1;target=0,0,1;fov=30";

fn open_box() -> &'static Path {
    static CELL: OnceLock<PathBuf> = OnceLock::new();
    CELL.get_or_init(|| {
        let dir = common::fresh_dir("render-leaf-density");
        let ply = dir.join("box.ply");
        let mut random = common::unit_randoms(5);
        let points: Vec<([f64; 3], [u8; 3])> = (0..POINTS)
            .map(|i| {
                let (u, v) = (random() * 2.0 - 1.0, random() * 2.0);
                match i % 8 {
                    0 => ([u, -1.0, v], FRONT),
                    1 => ([u, 1.0, v], BEHIND),
                    2 => ([u, v - 1.0, 0.0], BEHIND),
                    3 => ([-1.0, u, v], BEHIND),
                    4 => ([1.0, u, v], BEHIND),
                    k => ([u, (k as f64 - 6.0) * 0.5, v], BEHIND),
                }
            })
            .collect();
        common::write_coloured_ply(&ply, &points, None);
        let dataset = dir.join("box.strata");
        common::run_ok(&["convert", s(&ply), "-o", s(&dataset), "--quiet"]);
        let ds = StreamDataset::open_path(&dataset).expect("dataset opens");
        let nodes = ds.root_hierarchy_page().nodes().count();
        assert_eq!(nodes, 1, "the box is one leaf");
        dataset
    })
}

/// Renders the box from in front at 160 x 120 with `args`; the image and the frame's stats.
fn render(tag: &str, args: &[&str]) -> (Vec<u8>, serde_json::Value) {
    let dir = common::fresh_dir(&format!("render-leaf-density-{tag}"));
    let (png, json) = (dir.join("box.png"), dir.join("stats.json"));
    let mut all = vec![
        "render",
        s(open_box()),
        "-o",
        s(&png),
        "--size",
        "160x120",
        "--camera",
        CAMERA,
        "--stats",
        s(&json),
    ];
    all.extend_from_slice(args);
    gpu_ok(&all);
    let (_, _, rgba) = read_png(&png);
    let report = stats(&json);
    let frame = report["frames"]
        .as_array()
        .and_then(|f| f.last())
        .cloned()
        .expect("a frame");
    (rgba, frame)
}

/// Of the pixels in the middle of the front wall's image, the share that is not its green.
fn not_front(rgba: &[u8]) -> f64 {
    let (w, h) = (160usize, 120usize);
    let (mut n, mut other) = (0, 0);
    for y in h * 3 / 10..h * 7 / 10 {
        for x in w * 35 / 100..w * 65 / 100 {
            let p = &rgba[(y * w + x) * 4..];
            let (r, g, b) = (p[0] as i32, p[1] as i32, p[2] as i32);
            n += 1;
            other += usize::from(!(g > r + 40 && g > b + 40));
        }
    }
    other as f64 / n as f64
}

#[test]
fn the_triangulation_reaches_as_far_as_the_points_lie() {
    let spacing = (AREA / POINTS as f64).sqrt();
    let (_, frame) = render("triangulate", &["--pipeline", "triangulate"]);
    let reach = frame["params"]["max_connection"]
        .as_f64()
        .expect("max_connection");
    // Five spacings of the points drawn; the count over the cube's face took them for 0.03
    // apart where they lie 0.04.
    let want = CONNECTION_SPACINGS as f64 * spacing;
    assert!(
        (reach / want - 1.0).abs() < 0.15,
        "max_connection {reach}, four spacings {want}"
    );
    let holes = frame["measures"]["hole_rate"].as_f64().expect("hole rate");
    assert!(holes < 0.005, "{frame}");
}

#[test]
fn points_without_radii_cover_the_front_wall_of_a_leaf() {
    // Discs two spacings wide: the leaf's level spacing (0.026) left a third of the wall
    // showing the partitions behind it.
    let (rgba, _) = render(
        "points",
        &["--pipeline", "points", "--attenuate", "--point-size", "2"],
    );
    let through = not_front(&rgba);
    assert!(
        through < 0.03,
        "{through:.3} of the front wall shows what lies behind it"
    );
}
