//! Golden images: every registered pipeline renders fixed views of the shared autzen and bunny
//! scans headless (the bunny also converted with `--normals`), and each image is compared with the reference PNG committed under
//! `tests/golden/`. A pipeline gets its references by registering: the list comes from
//! `strata pipelines --json`.
//!
//! Regenerate the references (after a change that is meant to alter images) with
//! `STRATA_BLESS=1 WGPU_BACKEND=vulkan cargo test --release --test golden`.

mod common;

use common::{data, gpu_ok, read_png, s};
use std::path::{Path, PathBuf};

/// A pixel counts as changed when a channel moves by more than this (of 255): software and
/// hardware rasterizers round the last bit of shading differently.
const CHANNEL_TOLERANCE: u8 = 6;
/// At most this fraction of pixels may change: exact depth ties between points resolve by
/// their place in the GPU cache, which differs between drivers.
const CHANGED_FRACTION: f64 = 0.004;
const SIZE: &str = "256x192";

struct View {
    name: &'static str,
    dataset: &'static str,
    camera: Option<&'static str>,
}

/// The fixed views: each scan whole, and autzen close enough that its points fall apart into
/// pixels (where the pipelines differ most).
const VIEWS: [View; 4] = [
    View {
        name: "autzen",
        dataset: "autzen",
        camera: None,
    },
    View {
        name: "autzen_close",
        dataset: "autzen",
        camera: Some("eye=636480,849100,520;target=636600,849230,440;fov=40"),
    },
    View {
        name: "bunny",
        dataset: "bunny",
        camera: None,
    },
    // With normals: what the surfels orient and light by (the others draw it as the bunny).
    View {
        name: "bunny_normals",
        dataset: "bunny_normals",
        camera: None,
    },
];

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

/// The registered pipelines, as the binary lists them.
fn pipelines() -> Vec<String> {
    let o = gpu_ok(&["pipelines", "--json"]);
    let list: serde_json::Value = serde_json::from_slice(&o.stdout).expect("pipelines JSON");
    list.as_array()
        .expect("a list of pipelines")
        .iter()
        .map(|p| p["name"].as_str().expect("a pipeline name").to_string())
        .collect()
}

/// Pixels of `a` and `b` that differ by more than the tolerance, and the largest difference.
fn changed_pixels(a: &[u8], b: &[u8]) -> (usize, u8) {
    let mut changed = 0;
    let mut largest = 0;
    for (pa, pb) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        let d = pa
            .iter()
            .zip(pb)
            .map(|(x, y)| x.abs_diff(*y))
            .max()
            .unwrap_or(0);
        largest = largest.max(d);
        if d > CHANNEL_TOLERANCE {
            changed += 1;
        }
    }
    (changed, largest)
}

fn convert(input: &str, out: &Path, extra: &[&str]) {
    let input = data(input);
    let mut args = vec!["convert", s(&input), "-o", s(out), "--quiet"];
    args.extend_from_slice(extra);
    common::run_ok(&args);
}

#[test]
fn every_pipeline_matches_its_golden_images() {
    let dir = common::fresh_dir("golden");
    convert("autzen_trim.laz", &dir.join("autzen.strata"), &[]);
    convert(
        "bunny_range_scans_merged.ply",
        &dir.join("bunny.strata"),
        &[],
    );
    convert(
        "bunny_range_scans_merged.ply",
        &dir.join("bunny_normals.strata"),
        &["--normals"],
    );
    let bless = std::env::var_os("STRATA_BLESS").is_some();
    let mut failures = Vec::new();
    let names = pipelines();
    assert!(names.len() >= 3, "the registry lists {names:?}");
    for pipeline in &names {
        for view in &VIEWS {
            let file = format!("{pipeline}_{}.png", view.name);
            let out = dir.join(&file);
            let dataset = dir.join(format!("{}.strata", view.dataset));
            let mut args = vec![
                "render",
                s(&dataset),
                "-o",
                s(&out),
                "--size",
                SIZE,
                "--pipeline",
                pipeline,
                "--wait-complete",
                // One loader: nodes reach the GPU cache in the same order every run.
                "--loaders",
                "1",
            ];
            if let Some(camera) = view.camera {
                args.extend(["--camera", camera]);
            }
            gpu_ok(&args);
            let reference = golden_dir().join(&file);
            if bless {
                std::fs::create_dir_all(golden_dir()).expect("golden dir");
                std::fs::copy(&out, &reference).expect("reference written");
                continue;
            }
            let (w, h, got) = read_png(&out);
            assert!(
                reference.exists(),
                "{}: make it with STRATA_BLESS=1 cargo test --release --test golden",
                reference.display()
            );
            let (rw, rh, want) = read_png(&reference);
            assert_eq!((w, h), (rw, rh), "{file}: size");
            let (changed, largest) = changed_pixels(&got, &want);
            let fraction = changed as f64 / (w * h) as f64;
            eprintln!("{file}: {changed} pixels changed (largest channel difference {largest})");
            if fraction > CHANGED_FRACTION {
                failures.push(format!(
                    "{file}: {changed} of {} pixels differ by more than {CHANNEL_TOLERANCE} (see {})",
                    w * h,
                    out.display()
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn the_comparison_catches_a_changed_image() {
    let a = vec![100u8; 4 * 100];
    let mut b = a.clone();
    assert_eq!(changed_pixels(&a, &b), (0, 0));
    b[4 * 7] = 100 + CHANNEL_TOLERANCE + 1;
    b[4 * 9 + 2] = 100 + CHANNEL_TOLERANCE;
    assert_eq!(changed_pixels(&a, &b), (1, CHANNEL_TOLERANCE + 1));
}
