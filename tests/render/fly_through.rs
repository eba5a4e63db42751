//! A camera path rendered as numbered frames, and the files those frames may replace.

use super::*;

#[test]
fn fly_through_writes_numbered_frames_with_stats() {
    let dataset = fixtures().join("city.strata");
    let ds = StreamDataset::open_path(&dataset).expect("opens");
    let a = ds.anchor();
    let (min, max) = ds.bounds();
    let c = (min + max) * 0.5;
    let r = (max - min).length();
    let key = |dx: f32, dy: f32| {
        serde_json::json!({
            "eye": [a.x + (c.x + dx * r) as f64, a.y + (c.y + dy * r) as f64, a.z + (c.z + 0.5 * r) as f64],
            "target": [a.x + c.x as f64, a.y + c.y as f64, a.z + c.z as f64],
            "fov": 60.0
        })
    };
    let dir = fixtures().join("fly");
    std::fs::create_dir_all(&dir).expect("dir");
    let path = dir.join("path.json");
    let json = serde_json::json!({"keyframes": [key(1.0, 0.0), key(0.0, 1.0), key(-1.0, 0.0)]});
    std::fs::write(&path, json.to_string()).expect("write path");
    let st = dir.join("fly.json");
    let out = dir.join("fly.png");
    let fly = |extra: &[&str]| -> Vec<String> {
        let mut args = vec!["render", s(&dataset), "-o", s(&out), "--path", s(&path)];
        args.extend_from_slice(&["--frames", "4", "--size", "160x120"]);
        args.extend_from_slice(extra);
        args.into_iter().map(String::from).collect()
    };
    let args = fly(&["--stats", s(&st), "--wait-complete"]);
    gpu_ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let v = stats(&st);
    assert_eq!(v["frames"].as_array().map(Vec::len), Some(4));
    let mut images = Vec::new();
    for i in 0..4 {
        let (w, h, rgba) = read_png(&dir.join(format!("fly_{i:04}.png")));
        assert_eq!((w, h), (160, 120));
        images.push(rgba);
    }
    assert_ne!(
        images[0], images[3],
        "the camera moved but the image did not change"
    );
    // A frame's name taken by something that is not an image: refused before any frame is
    // drawn, and the file left as it was.
    let taken = dir.join("fly_0002.png");
    std::fs::write(&taken, b"field notes").expect("write");
    let args = fly(&[]);
    let o = gpu_run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        !o.status.success(),
        "a frame replaced a file that is not a PNG"
    );
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("not a PNG image"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(std::fs::read(&taken).expect("read"), b"field notes");
    std::fs::remove_file(&taken).expect("remove");
    // A frame that cannot be written part way (as on a full disk): the frames written before
    // it, and those left from the run before, are removed: no sequence is left that looks
    // complete.
    let blocked = dir.join("fly_0002.png.part");
    std::fs::create_dir_all(&blocked).expect("dir");
    let o = gpu_run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("fly_0002.png: cannot write"), "{err}");
    for i in 0..4 {
        assert!(
            !dir.join(format!("fly_{i:04}.png")).exists(),
            "frame {i} left"
        );
    }
    std::fs::remove_dir(&blocked).expect("remove");
}

/// Keyframes whose eye and target swap: halfway the eye stands on the target, where the view
/// has no direction (a frame there drew nothing and said nothing). Refused, naming the
/// keyframes, before any frame is written.
#[test]
fn a_path_through_its_own_target_is_refused() {
    let dataset = fixtures().join("city.strata");
    let ds = StreamDataset::open_path(&dataset).expect("opens");
    let a = ds.anchor();
    let (min, max) = ds.bounds();
    let (lo, hi) = (a + min.as_dvec3(), a + max.as_dvec3());
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("swap.json");
    let key = |eye: glam::DVec3, target: glam::DVec3| serde_json::json!({"eye": eye.to_array(), "target": target.to_array()});
    let json = serde_json::json!({"keyframes": [key(lo, hi), key(hi, lo)]});
    std::fs::write(&path, json.to_string()).expect("write path");
    let out = dir.path().join("f.png");
    let o = gpu_run(&[
        "render",
        s(&dataset),
        "-o",
        s(&out),
        "--path",
        s(&path),
        "--frames",
        "5",
        "--size",
        "64x48",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("between keyframes 1 and 2 the eye passes through the target"),
        "{err}"
    );
    let written: Vec<_> = std::fs::read_dir(dir.path())
        .expect("list")
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().ends_with(".png"))
        .collect();
    assert!(written.is_empty(), "frames were written");
}
