//! Equivalent paths give identical images on one renderer: the 64-bit and 32-bit projections,
//! and the fused and separate finish passes.

use super::*;

/// Draws frames until every node the view calls for is resident (a minute at most).
pub(crate) fn frame_until_complete(
    r: &mut strata_viewer::Renderer,
    camera: &strata_viewer::Camera,
    w: u32,
    h: u32,
    settings: &strata_viewer::Settings,
) {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while !r.frame(camera, w, h, settings).expect("frame").complete {
        assert!(
            std::time::Instant::now() < deadline,
            "the view never completed"
        );
        r.wait_for_loads(std::time::Duration::from_millis(20));
    }
}

/// Renders `dataset` until complete on one renderer, then the same frame with `a` and with `b`
/// applied to the settings: the same resident nodes in the same GPU placement, so equivalent
/// paths must give identical images (an exact depth tie resolves by placement, which differs
/// between processes). `None` where the adapter has no 64-bit atomics.
fn same_frame_two_ways(
    dataset: &Path,
    base: strata_viewer::Settings,
    a: fn(&mut strata_viewer::Settings),
    b: fn(&mut strata_viewer::Settings),
) -> Option<(Vec<u8>, Vec<u8>)> {
    use std::sync::Arc;
    use strata_viewer::gpu::{GpuContext, ProjectionPath};
    use strata_viewer::{Renderer, Settings};
    let ds = Arc::new(StreamDataset::open_path(dataset).expect("dataset opens"));
    let ctx = Arc::new(GpuContext::new(ProjectionPath::Auto).expect("GPU adapter"));
    if !ctx.int64_atomics {
        eprintln!(
            "skipping the in-process comparison: {} has no 64-bit atomics",
            ctx.adapter_name
        );
        return None;
    }
    let mut r = Renderer::new(ctx, ds.clone(), 1 << 30, 4).expect("renderer");
    let (w, h) = (400, 300);
    let camera = default_camera(&ds, w, h);
    let settings = Settings { ..base };
    frame_until_complete(&mut r, &camera, w, h, &settings);
    let mut image = |settings: &Settings| {
        r.frame(&camera, w, h, settings).expect("frame");
        r.wait_gpu().expect("GPU");
        r.read_image().expect("image").2
    };
    let (mut sa, mut sb) = (settings.clone(), settings);
    a(&mut sa);
    b(&mut sb);
    Some((image(&sa), image(&sb)))
}

#[test]
fn int64_and_int32_projection_give_identical_images() {
    for name in ["autzen.strata", "city.strata"] {
        let dataset = fixtures().join(name);
        let base = strata_viewer::Settings {
            point_size: 3.0,
            ..Default::default()
        };
        if let Some((a, b)) = same_frame_two_ways(&dataset, base, |_| {}, |s| s.force_int32 = true)
        {
            let differing = a
                .chunks_exact(4)
                .zip(b.chunks_exact(4))
                .filter(|(x, y)| x != y)
                .count();
            assert_eq!(
                differing, 0,
                "{name}: {differing} pixels differ between int64 and int32"
            );
            assert!(a.chunks_exact(4).filter(|p| drawn(p)).count() > 1000);
        }
        // The 32-bit path on a device created without 64-bit atomics, end to end: the same
        // picture up to exact depth ties.
        let drawn_px: Vec<usize> = ["int64", "int32"]
            .iter()
            .map(|path| {
                let (st, png) = render_stats(
                    &dataset,
                    &format!("{name}-{path}"),
                    &[
                        "--projection",
                        path,
                        "--size",
                        "400x300",
                        "--point-size",
                        "3",
                    ],
                );
                assert_eq!(st["projection"], *path);
                read_png(&png)
                    .2
                    .chunks_exact(4)
                    .filter(|p| drawn(p))
                    .count()
            })
            .collect();
        assert_eq!(
            drawn_px[0], drawn_px[1],
            "{name}: the paths cover different pixels"
        );
    }
}

#[test]
fn fused_and_separate_finish_passes_give_identical_images() {
    use strata_viewer::{ColourMode, Settings};
    let dataset = fixtures().join("city.strata");
    for (int32, colour) in [
        (false, ColourMode::Rgb),
        (true, ColourMode::Elevation),
        (false, ColourMode::Classification),
    ] {
        let base = Settings {
            colour,
            force_int32: int32,
            ..Settings::default()
        };
        let Some((fused, separate)) =
            same_frame_two_ways(&dataset, base, |_| {}, |s| s.fused_finish = false)
        else {
            return;
        };
        assert!(
            fused == separate,
            "int32={int32} {colour:?}: fused and separate passes differ"
        );
        assert!(fused.chunks_exact(4).filter(|p| drawn(p)).count() > 1000);
    }
    // And end to end: --separate-passes runs no fused pass.
    let (st, _) = render_stats(
        &dataset,
        "separate-cli",
        &["--separate-passes", "--size", "160x120"],
    );
    let passes = st["frames"][0]["passes"].to_string();
    assert!(
        !passes.contains("finish"),
        "separate passes ran the fused one: {passes}"
    );
}
