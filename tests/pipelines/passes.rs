//! Every pipeline's declared passes run, in the order the stats list them, and the
//! projection's optional ones (unpacking the keys, resolving the colour plane) only for a
//! pipeline that reads what they make.

use super::*;

/// The projection's passes, in the order they can run.
use strata_viewer::pipelines::projection::PASSES as PROJECTION_PASSES;

fn frame_passes(args: &[&str], stats: &Path) -> Vec<String> {
    let o = gpu_run(args);
    assert!(o.status.success(), "{args:?}: {}", text(&o));
    // Read from the text: serde_json's own map would sort the keys.
    let text = std::fs::read_to_string(stats).expect("stats");
    let at = text.find("\"passes\": {").expect("passes in the stats") + 11;
    let body = &text[at..at + text[at..].find('}').expect("the passes close")];
    body.split(',')
        .filter_map(|entry| entry.split('"').nth(1).map(str::to_string))
        .collect()
}

/// A fly-through of two views of `ds` (from `strata info`'s bounds), written beside it.
fn moving_path(ds: &Path) -> PathBuf {
    let o = common::run_ok(&["info", s(ds)]);
    let info = String::from_utf8_lossy(&o.stdout).to_string();
    let corner = |label: &str| -> Vec<f64> {
        let line = info
            .lines()
            .find(|l| {
                l.contains(label) && (l.starts_with("bounds") || l.trim_start().starts_with(label))
            })
            .unwrap_or_else(|| panic!("no {label} bounds in {info}"));
        let words: Vec<&str> = line.split_whitespace().collect();
        let at = words.iter().position(|w| *w == label).expect("label") + 1;
        words[at..at + 3]
            .iter()
            .map(|w| w.parse().expect("a number"))
            .collect()
    };
    let (lo, hi) = (corner("min"), corner("max"));
    let c: Vec<f64> = (0..3).map(|k| (lo[k] + hi[k]) / 2.0).collect();
    let r = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let key = |dx: f64| serde_json::json!({"eye": [c[0] + dx * r, c[1] - r, c[2] + r], "target": c, "fov": 50.0});
    let path = ds.with_file_name("moving.json");
    let json = serde_json::json!({"keyframes": [key(-0.5), key(0.5)]});
    std::fs::write(&path, json.to_string()).expect("path written");
    path
}

#[test]
fn every_declared_pass_runs_and_the_stats_list_them_in_run_order() {
    let ds = &dataset();
    let dir = ds.parent().expect("parent");
    let stats = dir.join("passes.json");
    let out = dir.join("passes.png");
    let path = moving_path(ds);
    let normals_ds = common::converted_with(
        "pipelines-normals-fixture",
        "autzen_trim.laz",
        "autzen",
        &["--normals"],
    );
    for p in registry() {
        let name = p["name"].as_str().expect("name");
        let declared: Vec<&str> = p["passes"]
            .as_array()
            .expect("passes")
            .iter()
            .filter_map(|v| v.as_str())
            .collect();
        let order: Vec<&str> = PROJECTION_PASSES
            .iter()
            .copied()
            .chain(declared.iter().copied())
            .collect();
        let mut seen = std::collections::BTreeSet::new();
        // Passes that run only where a parameter asks: a depth-peeling pipeline's peel from
        // the second layer on, its shadows where they are on.
        let has = |param: &str| {
            p["params"]
                .as_array()
                .is_some_and(|a| a.iter().any(|s| s["name"] == param))
        };
        // The 32-bit path too: passes that replace a 64-bit one there (the triangulation's
        // two search passes) run only on it.
        // A filter adds the count of the points it lets through.
        let mut runs: Vec<(&Path, &[&str])> = vec![
            (ds, &[]),
            (ds, &["--separate-passes"]),
            (ds, &["--projection", "int32"]),
            (ds, &["--hide-classes", "7"]),
        ];
        if has("layers") {
            runs.push((ds, &["--set", "layers=2"]));
        }
        // The dataset's own normals, carried through a pipeline where it has them.
        if has("stored_normals") {
            runs.push((&normals_ds, &[]));
        }
        // Shadows are computed when the view or what is drawn changes: a moving camera, one
        // light sample a frame.
        let moving = ["--set", "shadows=2", "--path", s(&path), "--frames", "2"];
        if has("shadows") {
            runs.push((ds, &moving));
        }
        for (ds, extra) in runs {
            let mut args = vec![
                "render",
                s(ds),
                "-o",
                s(&out),
                "--size",
                "96x64",
                "--pipeline",
                name,
                "--pass-clock",
                "wall",
                "--stats",
                s(&stats),
            ];
            args.extend_from_slice(extra);
            let passes = frame_passes(&args, &stats);
            // The projection unpacks its 64-bit keys into depth and index planes only for a
            // pipeline that reads them (the 32-bit path writes the planes themselves).
            let unpacks = passes.iter().any(|n| n == "unpack");
            let planes = p["reads_planes"] == true
                || p["reads_colour_plane"] == true
                || p["previous_frame"] == true;
            if !planes {
                assert!(!unpacks, "{name} {extra:?} reads no planes: {passes:?}");
            } else if extra == ["--separate-passes"] {
                assert!(unpacks, "{name} {extra:?} reads the planes: {passes:?}");
            }
            // The projection resolves its colour plane only for a pipeline that reads it.
            let resolves = passes.iter().any(|n| n == "resolve");
            if p["reads_colour_plane"] == false {
                assert!(
                    !resolves,
                    "{name} {extra:?} reads no colour plane: {passes:?}"
                );
            } else if extra == ["--separate-passes"] {
                assert!(
                    resolves,
                    "{name} {extra:?} reads the colour plane: {passes:?}"
                );
            }
            let at: Vec<usize> = passes
                .iter()
                .map(|n| {
                    order
                        .iter()
                        .position(|o| o == n)
                        .unwrap_or_else(|| panic!("{name}: pass {n} is not declared ({order:?})"))
                })
                .collect();
            assert!(
                at.windows(2).all(|w| w[0] < w[1]),
                "{name} {extra:?}: {passes:?}"
            );
            seen.extend(passes);
        }
        for d in &declared {
            assert!(
                seen.contains(*d),
                "{name}: declared pass {d} never ran ({seen:?})"
            );
        }
    }
}
