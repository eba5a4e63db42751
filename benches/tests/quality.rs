//! The quality harness end to end in its quick mode on the software adapter: every output is
//! written, every number is finite, on the bunny the pyramid, the surfels, the filters and the
//! triangulation fill what one-pixel points leave open, c-surfels pull the outline in (and
//! stay flat on a plane), and the triangulation converges within 8 frames of a camera jump.

use std::collections::HashMap;
mod common;
use std::process::Command;

#[test]
fn quick_run_writes_the_table_the_charts_and_the_images() {
    let out = tempfile::tempdir().expect("temp dir");
    let backend = std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "vulkan".into());
    let run = Command::new(env!("CARGO_BIN_EXE_quality"))
        .env("WGPU_BACKEND", backend)
        .args(["--quick", "--out"])
        .arg(out.path())
        .output()
        .expect("quality runs");
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "quality failed:\n{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");

    let csv = std::fs::read_to_string(out.path().join("quality.csv")).expect("quality.csv");
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some(
            "scene,pipeline,setting,lighting,density,noise,psnr,ssim,psnr_albedo,ssim_albedo,depth_err,normal_err_deg,hole_rate,leak_rate,gpu_ms,silhouette_px"
        )
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert!(rows.len() >= 30, "only {} rows", rows.len());
    for r in &rows {
        assert_eq!(r.len(), 16, "{r:?}");
        for v in &r[4..] {
            let x: f64 = v.parse().unwrap_or(f64::NAN);
            assert!(x.is_finite(), "{r:?}");
        }
    }
    for scene in [
        "bunny_scans",
        "bunny",
        "spot",
        "grazing",
        "thin",
        "near_far",
        "nested",
        "gradient",
        "layers",
        "shadow",
    ] {
        assert!(
            rows.iter().any(|r| r[0].starts_with(scene)),
            "no rows for {scene}"
        );
    }
    // Per (scene, density): hole rate of points 1px and pyramid on the sampled bunny.
    let mut holes: HashMap<(String, String), (f64, f64)> = HashMap::new();
    for r in rows.iter().filter(|r| r[0].starts_with("bunny/")) {
        let e = holes.entry((r[0].into(), r[4].into())).or_default();
        let rate: f64 = r[12].parse().unwrap_or(f64::NAN);
        match (r[1], r[2]) {
            ("points", "1px") => e.0 = rate,
            ("pyramid", "1px") => e.1 = rate,
            _ => {}
        }
    }
    assert!(!holes.is_empty());
    for ((scene, density), (points, pyramid)) in holes {
        assert!(
            pyramid <= points * 0.5 + 1e-9,
            "{scene} at density {density}: pyramid holes {pyramid}, points {points}"
        );
        // Absolute too: at one point per ten pixels the gaps span several pixels, and the
        // removal must see the surface around each of them (2.6 % left open on lavapipe; a
        // removal that took such gaps for open background left 11 %).
        assert!(
            pyramid < 0.05,
            "{scene} at density {density}: pyramid leaves {pyramid} of the surface open"
        );
    }
    // The surfels close what one-pixel points leave open, and on the sampled bunny (the mesh's
    // own outward normals) c-surfels pull the outline in: all-curved clearly, hybrid (curved
    // at the silhouette only) at least as well as planar. Means over the bunny's frames.
    let bunny = |pipeline: &str, setting: &str, column: usize| {
        let v: Vec<f64> = rows
            .iter()
            .filter(|r| r[0].starts_with("bunny/") && r[1] == pipeline && r[2] == setting)
            .filter_map(|r| r[column].parse().ok())
            .collect();
        assert!(!v.is_empty(), "no bunny rows for {pipeline} {setting}");
        v.iter().sum::<f64>() / v.len() as f64
    };
    let (surfel_holes, point_holes) = (bunny("surfels", "1px", 12), bunny("points", "1px", 12));
    assert!(
        surfel_holes <= 0.5 * point_holes && surfel_holes < 0.02,
        "surfels leave {surfel_holes} of the bunny open, points {point_holes}"
    );
    let outline = |setting: &str| bunny("surfels", setting, 15);
    let (planar, hybrid, curved) = (
        outline("mode=planar"),
        outline("1px"),
        outline("mode=curved"),
    );
    assert!(
        curved < 0.8 * planar && hybrid <= planar,
        "silhouette error: planar {planar} px, hybrid {hybrid}, curved {curved}"
    );
    // Over every frame, hybrid's outline beats planar's (issue #20); the paper's c-surfels,
    // bent alike everywhere, hang below a plane seen grazing and widen its outline, where
    // c-surfels bent by the curvature stay flat.
    let mean_outline = |setting: &str| {
        let v: Vec<f64> = rows
            .iter()
            .filter(|r| r[1] == "surfels" && r[2] == setting)
            .filter_map(|r| r[15].parse().ok())
            .collect();
        v.iter().sum::<f64>() / v.len().max(1) as f64
    };
    let (all_planar, all_hybrid) = (mean_outline("mode=planar"), mean_outline("1px"));
    assert!(
        all_hybrid < all_planar,
        "mean silhouette error: hybrid {all_hybrid} px, planar {all_planar}"
    );
    let grazing = |setting: &str| {
        rows.iter()
            .find(|r| r[0].starts_with("grazing") && r[1] == "surfels" && r[2] == setting)
            .and_then(|r| r[15].parse::<f64>().ok())
            .unwrap_or(f64::NAN)
    };
    let (flat, bent, plane) = (
        grazing("1px"),
        grazing("curvature=0"),
        grazing("mode=planar"),
    );
    assert!(
        flat <= plane + 0.05 && bent > flat + 0.25,
        "a plane seen grazing: hybrid {flat} px, the paper's c-surfels {bent}, planar {plane}"
    );
    // The hidden-point removal: through the gaps of the sampled outer sphere, points show the
    // inner one and the pull-push would spread it. The pyramid leaks 1.4 % of the outer
    // sphere's pixels on lavapipe, `edl` 2px 10 %, one-pixel points 37 %.
    let leak = |pipeline: &str, setting: &str| {
        rows.iter()
            .find(|r| r[0].starts_with("nested/") && r[1] == pipeline && r[2] == setting)
            .and_then(|r| r[13].parse::<f64>().ok())
            .unwrap_or(f64::NAN)
    };
    let (pyramid_leak, edl_leak) = (leak("pyramid", "1px"), leak("edl", "2px"));
    assert!(
        pyramid_leak < 0.05 && pyramid_leak < edl_leak * 0.5,
        "nested spheres: pyramid leaks {pyramid_leak}, edl 2px {edl_leak}"
    );
    // The filters close what one-pixel points leave open where there is about a point per
    // pixel (their 3x3 masks cannot tell a gap several pixels wide from the outside, so at one
    // point per ten pixels they do not), fill more faithfully than eye-dome lighting there, and do
    // not let the inner sphere through the outer one's gaps.
    let at = |scene: &str, pipeline: &str, setting: &str, column: usize| {
        rows.iter()
            .find(|r| {
                r[0].starts_with(scene) && r[1] == pipeline && r[2] == setting && r[4] == "1.0000"
            })
            .and_then(|r| r[column].parse::<f64>().ok())
            .unwrap_or(f64::NAN)
    };
    for scene in ["bunny/", "spot/"] {
        let (filters, points) = (
            at(scene, "filters", "1px", 12),
            at(scene, "points", "1px", 12),
        );
        assert!(
            filters <= 0.5 * points && filters < 0.02,
            "{scene}: filters leave {filters} open, points {points}"
        );
        // Albedo SSIM: each shaded image is scored against its own lighting (eye-dome
        // darkening against a headlight), so their shaded SSIMs do not compare.
        let ssim = at(scene, "filters", "1px", 9);
        let edl = at(scene, "edl", "1px", 9).max(at(scene, "edl", "2px", 9));
        assert!(ssim > edl, "{scene}: filters albedo SSIM {ssim}, edl {edl}");
    }
    let filters_leak = leak("filters", "1px");
    assert!(
        filters_leak < 0.05 && filters_leak < edl_leak * 0.5,
        "nested spheres: filters leak {filters_leak}, edl 2px {edl_leak}"
    );
    // Each pipeline is scored against the light it uses: points are unlit, so their shaded
    // image is scored against the mesh's albedo, exactly as their albedo is.
    // Shadowed configurations are lit from their light, with the mesh's shadows.
    let lighting: HashMap<&str, &str> = rows
        .iter()
        .filter(|r| !r[2].starts_with("shadows="))
        .map(|r| (r[1], r[3]))
        .collect();
    assert!(
        rows.iter()
            .filter(|r| r[2].starts_with("shadows="))
            .all(|r| r[3] == "directional Blinn-Phong with shadows")
    );
    assert_eq!(lighting.get("points"), Some(&"none"));
    assert_eq!(lighting.get("edl"), Some(&"eye-dome"));
    assert_eq!(lighting.get("pyramid"), Some(&"headlight Blinn-Phong"));
    assert_eq!(lighting.get("filters"), Some(&"headlight Blinn-Phong"));
    for r in rows.iter().filter(|r| r[1] == "points") {
        assert_eq!((r[6], r[7]), (r[8], r[9]), "{r:?}");
    }
    for chart in [
        "quality_vs_time.png",
        "quality_vs_density.png",
        "quality_vs_noise.png",
    ] {
        let bytes = std::fs::read(out.path().join(chart)).expect("chart written");
        assert!(
            bytes.starts_with(b"\x89PNG") && bytes.len() > 10_000,
            "{chart}"
        );
    }
    let summary = std::fs::read_to_string(out.path().join("summary.md")).expect("summary.md");
    assert!(
        summary.contains("| bunny_scans | pyramid | 1px | headlight Blinn-Phong |"),
        "{summary}"
    );
    // Paper 004's transparency and shadows against the mesh peeled and shadowed the same way:
    // six layers at half opacity at least 25 dB; the lit or shadowed state right for at least
    // 95 % of the pixels, and since most pixels are lit (a frame without shadows scores the lit share),
    // the shadows' intersection over union at least 0.6 (38.7 dB, 99.5 % and 0.78 on lavapipe).
    // Rows of that table: scene, density, pipeline, setting, PSNR, SSIM, state, IoU, speckle,
    // GPU ms.
    let cells = |scene: &str, pipeline: &str, setting: &str| -> Vec<String> {
        summary
            .lines()
            .map(|l| {
                l.split('|')
                    .map(|c| c.trim().to_string())
                    .collect::<Vec<_>>()
            })
            .find(|c| {
                c.len() > 8
                    && c[1] == scene
                    && c[2].parse::<f64>().is_ok()
                    && c[3] == pipeline
                    && c[4].starts_with(setting)
            })
            .unwrap_or_else(|| {
                panic!("no {scene} {pipeline} {setting} row in the summary:\n{summary}")
            })
    };
    let number = |c: &str| -> f64 { c.trim_end_matches(" %").parse().unwrap_or(f64::NAN) };
    let layers = cells("layers", "filters", "layers=6 opacity=0.5");
    assert!(number(&layers[5]) >= 25.0, "transparency: {layers:?}");
    let shadow = cells("shadow", "filters", "shadows=1 2px");
    assert!(
        number(&shadow[7]) >= 95.0 && number(&shadow[8]) >= 0.6,
        "shadows: {shadow:?}"
    );
    // The same shadows carried through the pyramid's pull-push.
    let pulled = cells("shadow", "pyramid", "shadows=1");
    assert!(
        number(&pulled[7]) >= 95.0 && number(&pulled[8]) >= 0.6,
        "pyramid's shadows: {pulled:?}"
    );
    // A light grazing the floor (0.77), and soft shadows whose penumbra has no speckle
    // (0.66 %).
    let grazing = cells("shadow", "filters", "shadows=1 grazing");
    assert!(
        number(&grazing[7]) >= 90.0 && number(&grazing[8]) >= 0.6,
        "grazing light: {grazing:?}"
    );
    let soft = cells("shadow", "filters", "shadows=2");
    assert!(number(&soft[9]) < 1.0, "soft shadows' speckle: {soft:?}");
    // Paper 002's triangulation after its warm-up: its targets met on every frame where
    // points leave holes, and back within 8 frames of a camera jump on every view (at most 4
    // on lavapipe).
    let met = summary
        .lines()
        .find(|l| l.starts_with("triangulate: "))
        .unwrap_or_else(|| panic!("no triangulate targets line:\n{summary}"));
    let counts: Vec<u32> = met
        .split_whitespace()
        .filter_map(|w| w.parse().ok())
        .take(2)
        .collect();
    assert!(
        counts.len() == 2 && counts[0] == counts[1] && counts[1] > 0,
        "{met}"
    );
    let jumps: Vec<f64> = summary
        .lines()
        .map(|l| l.split('|').map(str::trim).collect::<Vec<_>>())
        .filter(|c| c.len() > 5 && c[3] == "triangulate")
        .map(|c| number(c[4]))
        .collect();
    assert!(!jumps.is_empty(), "no frames-over-time rows:\n{summary}");
    assert!(
        jumps.iter().all(|&j| (1.0..=8.0).contains(&j)),
        "frames after a jump: {jumps:?}"
    );
    let images = std::fs::read_dir(out.path().join("images"))
        .expect("images")
        .count();
    assert!(images >= 5, "{images} side-by-side images");
}

/// A mesh of the user's own (`--mesh`) is a scene like the bunny: sampled, converted, rendered
/// through every pipeline and scored; a file that is no mesh is refused, naming it.
#[test]
fn a_users_mesh_is_a_scene_of_its_own() {
    let out = tempfile::tempdir().expect("temp dir");
    // A closed octahedron, read as y up.
    let ply = out.path().join("octa.ply");
    common::write_octahedron(&ply);
    let backend = std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "vulkan".into());
    let quality = |args: &[&std::ffi::OsStr]| {
        Command::new(env!("CARGO_BIN_EXE_quality"))
            .env("WGPU_BACKEND", &backend)
            .args(args)
            .output()
            .expect("quality runs")
    };
    let dir = out.path().join("run");
    let run = quality(&[
        "--quick".as_ref(),
        "--size".as_ref(),
        "96x72".as_ref(),
        "--out".as_ref(),
        dir.as_os_str(),
        "--mesh".as_ref(),
        ply.as_os_str(),
        "--y-up".as_ref(),
        "--scenes".as_ref(),
        "octa".as_ref(),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "quality failed:\n{stderr}");
    let csv = std::fs::read_to_string(dir.join("quality.csv")).expect("quality.csv");
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert!(
        !rows.is_empty() && rows.iter().all(|r| r.starts_with("octa")),
        "{csv}"
    );
    // Points drawn over the sampled octahedron: its surface is seen, not all holes.
    let holes: Vec<f64> = rows
        .iter()
        .filter(|r| r.contains(",pyramid,"))
        .filter_map(|r| r.split(',').nth(12)?.parse().ok())
        .collect();
    assert!(!holes.is_empty() && holes.iter().all(|h| *h < 0.5), "{csv}");
    let bad = out.path().join("octa.stl");
    std::fs::write(&bad, "solid").expect("write");
    let run = quality(&[
        "--out".as_ref(),
        dir.as_os_str(),
        "--mesh".as_ref(),
        bad.as_os_str(),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        !run.status.success() && stderr.contains("octa.stl: not a .ply or .obj file"),
        "{stderr}"
    );
}
