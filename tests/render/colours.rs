//! Colouring by normal and by curvature (surface variation) for datasets converted with
//! `--normals`: what the images show, the refusal where the dataset lacks the attribute, and the
//! nodes loaded again when the window switches to colouring by normal.

use super::*;
use std::collections::HashSet;
use std::sync::Arc;
use strata_viewer::gpu::{GpuContext, ProjectionPath};
use strata_viewer::{Camera, ColourMode, Renderer, Settings};

/// A small synthetic city converted with `--normals` (oriented up), once per test binary.
fn normals_city() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = common::fresh_dir("render-normals");
        let las = dir.join("city.las");
        common::run_ok(&["synth", "--points", "50000", "-o", s(&las), "--seed", "3"]);
        let ds = dir.join("city.strata");
        common::run_ok(&["convert", s(&las), "-o", s(&ds), "--quiet", "--normals"]);
        ds
    })
}

/// A camera looking down on the whole dataset (tilted a little, so that "up" is defined).
fn top_down(dataset: &Path) -> String {
    let ds = StreamDataset::open_path(dataset).expect("dataset opens");
    let b = &ds.metadata().bounds;
    let c = [0, 1].map(|a| (b.min[a] + b.max[a]) / 2.0);
    let extent = (b.max[0] - b.min[0]).max(b.max[1] - b.min[1]);
    format!(
        "eye={},{},{};target={},{},{};fov=50",
        c[0],
        c[1] - extent * 0.05,
        b.max[2] + extent * 1.2,
        c[0],
        c[1],
        b.min[2]
    )
}

/// Of the drawn pixels: how many, the share that is bluish (blue well above red and green, as
/// an upward normal is), and how many distinct colours there are.
fn describe(rgba: &[u8]) -> (usize, f64, usize) {
    let px: Vec<&[u8]> = rgba.chunks_exact(4).filter(|p| drawn(p)).collect();
    let bluish = px
        .iter()
        .filter(|p| p[2] as i32 > p[0] as i32 + 40 && p[2] as i32 > p[1] as i32 + 40)
        .count();
    let distinct: HashSet<[u8; 3]> = px.iter().map(|p| [p[0], p[1], p[2]]).collect();
    (
        px.len(),
        bluish as f64 / px.len().max(1) as f64,
        distinct.len(),
    )
}

fn render_colour(mode: &str) -> Vec<u8> {
    let dataset = normals_city();
    let out = dataset.with_file_name(format!("colour-{mode}.png"));
    let camera = top_down(dataset);
    gpu_ok(&[
        "render",
        s(dataset),
        "-o",
        s(&out),
        "--size",
        "320x240",
        "--pipeline",
        "points",
        "--camera",
        &camera,
        "--colour",
        mode,
        "--wait-complete",
    ]);
    read_png(&out).2
}

#[test]
fn colouring_by_normal_shows_upward_surfaces_blue_and_curvature_varies() {
    let normal = render_colour("normal");
    let (drawn_px, bluish, distinct) = describe(&normal);
    assert!(drawn_px > 10_000, "only {drawn_px} pixels drawn");
    // Seen from above, ground and roofs face up: (0, 0, 1) is (128, 128, 255).
    assert!(
        bluish > 0.6,
        "only {:.0}% of the pixels are bluish",
        bluish * 100.0
    );
    assert!(distinct > 50, "{distinct} colours: the normals do not vary");

    let rgb = render_colour("rgb");
    let (_, rgb_bluish, _) = describe(&rgb);
    assert!(
        rgb_bluish < bluish,
        "the stored colours are as blue as the normals"
    );

    let curvature = render_colour("curvature");
    let (curved_px, _, distinct) = describe(&curvature);
    assert_eq!(curved_px, drawn_px, "the same points are drawn");
    assert!(distinct > 20, "{distinct} colours: curvature is uniform");
    // The ramp's low end (68, 1, 84) on the planes, its greens and yellows on edges and trees.
    let px: Vec<&[u8]> = curvature.chunks_exact(4).filter(|p| drawn(p)).collect();
    let low = px.iter().filter(|p| p[1] < 80).count() as f64 / px.len() as f64;
    let high = px.iter().filter(|p| p[1] > 150).count() as f64 / px.len() as f64;
    assert!(low > 0.5, "only {:.0}% of the pixels are flat", low * 100.0);
    assert!(
        high > 0.002,
        "only {:.2}% of the pixels are curved",
        high * 100.0
    );
    assert_ne!(curvature, normal);
}

#[test]
fn colouring_by_an_attribute_the_dataset_lacks_is_refused() {
    let city = fixtures().join("city.strata");
    let out = city.with_file_name("no-normals.png");
    for (flag, mode, attribute) in [
        ("--colour", "normal", "\"normal\""),
        ("--color", "curvature", "\"surface_variation\""),
    ] {
        let o = gpu_run(&["render", s(&city), "-o", s(&out), flag, mode]);
        assert!(!o.status.success(), "{mode} rendered without {attribute}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains(attribute) && err.contains("--normals") && err.lines().count() == 1,
            "{err}"
        );
        assert!(!out.exists());
    }
}

#[test]
fn switching_to_normal_colours_loads_the_nodes_again_with_their_normals() {
    let dataset = normals_city();
    let ds = Arc::new(StreamDataset::open_path(dataset).expect("dataset opens"));
    let ctx = Arc::new(GpuContext::new(ProjectionPath::Auto).expect("GPU adapter"));
    let mut r = Renderer::new(ctx, ds.clone(), 1 << 30, 2).expect("renderer");
    let (w, h) = (320, 240);
    let camera =
        Camera::parse(&top_down(dataset), ds.anchor(), default_camera(&ds, w, h)).expect("camera");
    let mut settings = Settings::default();
    settings.set_pipeline("points").expect("points pipeline");
    let mut image = |settings: &Settings| {
        paths::frame_until_complete(&mut r, &camera, w, h, settings);
        r.frame(&camera, w, h, settings).expect("frame");
        r.wait_gpu().expect("GPU");
        r.read_image().expect("image").2
    };
    let rgb = image(&settings);
    settings.colour = ColourMode::Normal;
    let normal = image(&settings);
    settings.colour = ColourMode::Elevation;
    let elevation = image(&settings);
    let (_, rgb_bluish, _) = describe(&rgb);
    let (_, normal_bluish, _) = describe(&normal);
    assert!(
        normal_bluish > 0.6 && rgb_bluish < normal_bluish,
        "after the switch {:.0}% of the pixels are bluish (stored colours: {:.0}%)",
        normal_bluish * 100.0,
        rgb_bluish * 100.0
    );
    // Elevation colours from the stored colour word again: the nodes are loaded once more, and
    // rgb after it shows the stored colours as before.
    assert_ne!(elevation, normal);
    settings.colour = ColourMode::Rgb;
    let (_, again, _) = describe(&image(&settings));
    assert!(
        (again - rgb_bluish).abs() < 0.02,
        "rgb after normal: {:.1}% bluish, before: {:.1}%",
        again * 100.0,
        rgb_bluish * 100.0
    );
}
