//! The pyramid pipeline end to end: holes filled on sparse points, pass times, the measured
//! depth noise, and the window's non-blocking readbacks.

use super::*;
use crate::paths::frame_until_complete;

/// Drawn pixels inside and outside the dataset's projected bounds (with `slack` pixels).
fn drawn_in_and_out(dataset: &Path, png: &Path, slack: f32) -> (u64, u64) {
    let (w, h, rgba) = read_png(png);
    let (x0, y0, x1, y1) = projected_bounds(dataset, w, h);
    let (mut inside, mut outside) = (0u64, 0u64);
    for y in 0..h {
        for x in 0..w {
            let px = &rgba[((y * w + x) * 4) as usize..][..4];
            let (fx, fy) = (x as f32 + 0.5, y as f32 + 0.5);
            let within =
                fx >= x0 - slack && fx <= x1 + slack && fy >= y0 - slack && fy <= y1 + slack;
            if drawn(px) {
                if within {
                    inside += 1;
                } else {
                    outside += 1;
                }
            }
        }
    }
    (inside, outside)
}

#[test]
fn pyramid_fills_the_holes_of_sparse_points_and_times_its_passes() {
    let dataset = fixtures().join("autzen.strata");
    let size = ["--size", "640x480"];
    let (_, points_png) = render_stats(
        &dataset,
        "pyramid-vs-points",
        &[
            size[0],
            size[1],
            "--pipeline",
            "points",
            "--point-size",
            "1",
        ],
    );
    let (st, pyramid_png) = render_stats(
        &dataset,
        "pyramid",
        &[size[0], size[1], "--pipeline", "pyramid"],
    );
    let (points_in, _) = drawn_in_and_out(&dataset, &points_png, 2.0);
    let (pyramid_in, pyramid_out) = drawn_in_and_out(&dataset, &pyramid_png, 4.0);
    // One-pixel points leave gaps between scan lines and under the trees; the pull-push
    // fills them (about 1.27 times the pixels on lavapipe).
    assert!(
        pyramid_in as f64 >= points_in as f64 * 1.15,
        "pyramid drew {pyramid_in} pixels, points {points_in}"
    );
    assert_eq!(pyramid_out, 0, "the fill spread outside the dataset");
    let frame = &st["frames"][0];
    let s0 = frame["params"]["s0"].as_f64().expect("s0 in the stats");
    // Autzen's points are a few feet apart.
    assert!(s0.is_finite() && s0 > 0.1 && s0 < 50.0, "s0 {s0}");
    let passes = frame["passes"].as_object().expect("passes");
    if !passes.is_empty() {
        for name in [
            "project",
            "pyramid",
            "hpr",
            "pull",
            "push",
            "normals",
            "pyramid shade",
        ] {
            let ms = passes.get(name).and_then(|v| v.as_f64());
            assert!(
                ms.is_some_and(|v| v.is_finite() && v >= 0.0),
                "pass {name}: {ms:?} in {passes:?}"
            );
        }
    }
    // By the wall clock every pass is timed, and the passes, run one after another inside
    // the frame, take no longer than the frame.
    let (st, _) = render_stats(
        &dataset,
        "pyramid-wall",
        &[
            size[0],
            size[1],
            "--pipeline",
            "pyramid",
            "--pass-clock",
            "wall",
        ],
    );
    let frame = &st["frames"][0];
    assert_eq!(frame["pass_clock"], "wall");
    let passes = frame["passes"].as_object().expect("passes");
    for name in [
        "clear", "project", "resolve", "pyramid", "hpr", "noise", "pull", "push", "normals",
    ] {
        let ms = passes.get(name).and_then(|v| v.as_f64());
        assert!(
            ms.is_some_and(|v| v.is_finite() && v > 0.0),
            "pass {name}: {ms:?} in {passes:?}"
        );
    }
    let sum: f64 = passes.values().filter_map(|v| v.as_f64()).sum();
    let frame_ms = frame["frame_ms"].as_f64().expect("frame_ms");
    assert!(
        sum <= frame_ms,
        "passes {sum} ms in a frame of {frame_ms} ms"
    );
    // A given s0 is used as given, and a tenfold larger one changes the picture.
    let (st, big_png) = render_stats(
        &dataset,
        "pyramid-s0",
        &[size[0], size[1], "--pipeline", "pyramid", "--s0", "30"],
    );
    assert_eq!(st["frames"][0]["params"]["s0"].as_f64(), Some(30.0));
    assert_ne!(read_png(&big_png).2, read_png(&pyramid_png).2);
}

/// Mean absolute luminance step between neighbouring drawn pixels: how rough the shading is.
fn shading_roughness(rgba: &[u8], width: usize) -> f64 {
    let luma = |p: &[u8]| 0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64;
    let (mut sum, mut count) = (0.0, 0usize);
    for row in rgba.chunks_exact(4 * width) {
        for x in 1..width {
            let (a, b) = (&row[4 * x - 4..4 * x], &row[4 * x..4 * x + 4]);
            if drawn(a) && drawn(b) {
                sum += (luma(a) - luma(b)).abs();
                count += 1;
            }
        }
    }
    sum / count.max(1) as f64
}

#[test]
fn pyramid_measures_depth_noise_and_shades_noisy_points_smoothly() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut results = Vec::new();
    for noise in ["0", "0.4", "1"] {
        let las = dir.path().join(format!("terrain-{noise}.las"));
        common::run_ok(&[
            "synth",
            "--scene",
            "terrain",
            "--points",
            "100k",
            "--noise",
            noise,
            "-o",
            s(&las),
        ]);
        let dataset = dir.path().join(format!("terrain-{noise}.strata"));
        common::run_ok(&["convert", s(&las), "-o", s(&dataset), "--quiet"]);
        let (st, png) = render_stats(
            &dataset,
            &format!("terrain-{noise}"),
            &[
                "--size",
                "320x240",
                "--pipeline",
                "pyramid",
                "--colour",
                "classification",
            ],
        );
        let measured = st["frames"][0]["measures"]["depth_noise"]
            .as_f64()
            .expect("depth_noise in the pyramid's stats");
        let (w, _, rgba) = read_png(&png);
        results.push((measured, shading_roughness(&rgba, w as usize)));
    }
    let [(clean, clean_rough), (some, _), (much, much_rough)] = results[..] else {
        unreachable!()
    };
    // What the normals see: the nearest of a pixel's points, after hidden-point removal, so
    // below the synthetic deviation; the terrain's own relief reads as a little noise.
    assert!(
        clean < some && some < much && much > 2.5 * clean,
        "depth noise measured {clean}, {some}, {much} for 0, 0.4 and 1 m"
    );
    // Flat colours by class, so that what varies is the shading. With normals at the
    // spacing's scale alone the noisiest terrain shades 2.8 times as rough as the clean one
    // (lavapipe); by the noise, 1.5 times.
    assert!(
        much_rough < 2.0 * clean_rough,
        "noisy shading roughness {much_rough}, clean {clean_rough}"
    );
    window_readbacks_deliver(&dir.path().join("terrain-1.strata"));
}

/// What the window shows without ever waiting for the GPU, the timestamped pass times and the
/// depth noise, arrives through the non-blocking readbacks: once the GPU has caught up, the
/// next frame's stats carry this view's depth noise, as the blocking readback gives it.
fn window_readbacks_deliver(dataset: &Path) {
    use std::sync::Arc;
    use strata_viewer::gpu::{GpuContext, ProjectionPath};
    use strata_viewer::pipelines::find;
    use strata_viewer::settings::PassClock;
    use strata_viewer::{Renderer, Settings};
    let ds = Arc::new(StreamDataset::open_path(dataset).expect("dataset opens"));
    let ctx = Arc::new(GpuContext::new(ProjectionPath::Auto).expect("GPU adapter"));
    let timestamps = ctx.timestamps;
    let mut r = Renderer::new(ctx, ds.clone(), 1 << 30, 4).expect("renderer");
    let (w, h) = (320, 240);
    let camera = default_camera(&ds, w, h);
    let settings = Settings {
        pipeline: find("pyramid").expect("registered"),
        pass_clock: PassClock::Timestamps,
        ..Settings::default()
    };
    frame_until_complete(&mut r, &camera, w, h, &settings);
    // The readback may have been busy with an earlier, incomplete frame when the complete one
    // was drawn: one more frame, whose copy the wait brings back.
    r.wait_gpu().expect("GPU");
    r.frame(&camera, w, h, &settings).expect("frame");
    r.wait_gpu().expect("GPU");
    let stats = r.frame(&camera, w, h, &settings).expect("frame");
    r.wait_gpu().expect("GPU");
    let exact = r
        .read_measures()
        .expect("readback")
        .get("depth_noise")
        .copied();
    assert!(exact.is_some_and(|n| n > 0.0), "depth noise {exact:?}");
    assert_eq!(
        stats.measures.get("depth_noise").copied(),
        exact,
        "the window's depth noise"
    );
    if timestamps {
        let passes = r.pass_times();
        for name in ["project", "hpr", "pull", "push", "normals"] {
            let ms = passes.get(name);
            assert!(
                ms.is_some_and(|v| v.is_finite() && v >= 0.0),
                "timestamped pass {name}: {ms:?} in {passes:?}"
            );
        }
    }
    let points = Settings {
        pipeline: find("points").expect("registered"),
        ..settings
    };
    let stats = r.frame(&camera, w, h, &points).expect("frame");
    assert!(stats.measures.is_empty(), "{:?}", stats.measures);
}
