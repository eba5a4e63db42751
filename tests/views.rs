//! Camera bookmarks headless: `--camera-file` and `--bookmark` view from a saved view exactly as
//! `--camera` does, and `--path` flies through the same file.

mod common;

use common::{gpu_ok, gpu_run, read_png, s};

#[test]
fn a_bookmark_renders_what_its_camera_renders_and_the_file_is_a_path() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = common::converted("views-fixture", "autzen_trim.laz", "autzen");
    let close = "eye=636480,849100,520;target=636600,849230,440;fov=40";
    // The file the window writes beside the dataset.
    let marks = serde_json::json!({"keyframes": [
        {"name": "overview", "eye": [636590.0, 848700.0, 900.0], "target": [636590.0, 849216.0, 440.0], "fov": 50.0},
        {"name": "close", "eye": [636480.0, 849100.0, 520.0], "target": [636600.0, 849230.0, 440.0], "fov": 40.0}
    ]});
    std::fs::write(dataset.join("bookmarks.json"), marks.to_string()).expect("bookmarks");
    let render = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut args = vec![
            "render",
            s(&dataset),
            "-o",
            s(&out),
            "--size",
            "160x120",
            "--wait-complete",
            "--loaders",
            "1",
        ];
        args.extend_from_slice(extra);
        gpu_ok(&args);
        read_png(&out).2
    };
    let by_spec = render("spec.png", &["--camera", close]);
    let by_name = render("name.png", &["--bookmark", "close"]);
    let by_file = render(
        "file.png",
        &[
            "--camera-file",
            s(&dataset.join("bookmarks.json")),
            "--bookmark",
            "close",
        ],
    );
    assert!(
        by_spec == by_name && by_spec == by_file,
        "the bookmark's view differs"
    );
    let first = render(
        "first.png",
        &["--camera-file", s(&dataset.join("bookmarks.json"))],
    );
    assert!(
        first != by_spec,
        "without --bookmark the first view is used"
    );
    // The same file is a fly-through path.
    let o = gpu_ok(&[
        "render",
        s(&dataset),
        "-o",
        s(&dir.path().join("fly.png")),
        "--size",
        "64x48",
        "--path",
        s(&dataset.join("bookmarks.json")),
        "--frames",
        "3",
    ]);
    assert!(String::from_utf8_lossy(&o.stdout).starts_with("3 image(s)"));
    // An unknown name is refused in one sentence that lists the names there are.
    let o = gpu_run(&["render", s(&dataset), "-o", "x.png", "--bookmark", "bridge"]);
    let t = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && t.contains("bridge") && t.contains("overview, close"),
        "{t}"
    );
    assert_eq!(t.trim().lines().count(), 1, "{t}");
    // A fly-through's keyframes are its views: a camera beside them was silently ignored.
    let o = gpu_run(&[
        "render",
        s(&dataset),
        "-o",
        "x.png",
        "--path",
        s(&dataset.join("bookmarks.json")),
        "--bookmark",
        "close",
    ]);
    let t = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && t.contains("'--path <PATH>' cannot be used with '--bookmark"),
        "{t}"
    );
    // A --camera-file that does not exist is said to be missing, not to hold no bookmark.
    let missing = dir.path().join("nope.json");
    let o = gpu_run(&[
        "render",
        s(&dataset),
        "-o",
        "x.png",
        "--camera-file",
        s(&missing),
    ]);
    let t = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && t.contains("nope.json: cannot read the --camera-file: no such file"),
        "{t}"
    );
}

#[test]
fn a_fly_through_reaches_each_view_at_its_seconds() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = common::converted("views-fixture", "autzen_trim.laz", "autzen");
    let views = [
        (
            "overview",
            [636590.0, 848700.0, 900.0],
            [636590.0, 849216.0, 440.0],
        ),
        (
            "close",
            [636480.0, 849100.0, 520.0],
            [636600.0, 849230.0, 440.0],
        ),
        (
            "side",
            [637300.0, 849216.0, 600.0],
            [636590.0, 849216.0, 440.0],
        ),
    ];
    // The second view 1 s after the first, the third 3 s after that.
    let keyframes: Vec<serde_json::Value> = views
        .iter()
        .zip([None, Some(1.0), Some(3.0)])
        .map(|((name, eye, target), seconds)| {
            let mut k =
                serde_json::json!({"name": name, "eye": eye, "target": target, "fov": 50.0});
            if let Some(s) = seconds {
                k["seconds"] = serde_json::json!(s);
            }
            k
        })
        .collect();
    let file = dir.path().join("path.json");
    std::fs::write(
        &file,
        serde_json::json!({ "keyframes": keyframes }).to_string(),
    )
    .expect("path");
    // Without --frames: one frame each half second of the 4 s, both ends included.
    let o = gpu_ok(&[
        "render",
        s(&dataset),
        "-o",
        s(&dir.path().join("fly.png")),
        "--size",
        "96x72",
        "--path",
        s(&file),
        "--fps",
        "2",
        "--wait-complete",
        "--loaders",
        "1",
    ]);
    assert!(
        String::from_utf8_lossy(&o.stdout).starts_with("9 image(s)"),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    // Frame 2 (1 s) is the second view, frame 8 (4 s) the third.
    for (frame, (name, ..)) in [(2, views[1]), (8, views[2])] {
        let at = dir.path().join(format!("{name}.png"));
        gpu_ok(&[
            "render",
            s(&dataset),
            "-o",
            s(&at),
            "--size",
            "96x72",
            "--camera-file",
            s(&file),
            "--bookmark",
            name,
            "--wait-complete",
            "--loaders",
            "1",
        ]);
        let flown = read_png(&dir.path().join(format!("fly_{frame:04}.png"))).2;
        assert!(
            read_png(&at).2 == flown,
            "frame {frame} is not the view {name}"
        );
    }
}
