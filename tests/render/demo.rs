//! `strata demo` without a window: no display, or one that does not answer.

use super::*;

#[test]
fn demo_synthesizes_converts_and_renders_without_a_display() {
    let dir = super::fixtures().join("demo");
    let backend = std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "vulkan".into());
    let o = strata()
        .env("WGPU_BACKEND", backend)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .args(["demo", "--dir", s(&dir), "--points", "200k"])
        .output()
        .expect("demo runs");
    assert!(
        o.status.success(),
        "demo failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let (w, h, rgba) = read_png(&dir.join("city.png"));
    assert_eq!((w, h), (1280, 720));
    let drawn_px = rgba.chunks_exact(4).filter(|p| super::drawn(p)).count();
    assert!(
        drawn_px > 50_000,
        "the demo image shows {drawn_px} drawn pixels"
    );
    assert!(String::from_utf8_lossy(&o.stdout).contains("points drawn"));
}

#[test]
fn demo_shows_a_picture_where_the_display_does_not_answer() {
    let dir = super::fixtures().join("demo-stale-display");
    let backend = std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "vulkan".into());
    // A DISPLAY left over from an ssh session whose X server is gone.
    let o = strata()
        .env("WGPU_BACKEND", backend)
        .env("DISPLAY", ":7391")
        .env_remove("WAYLAND_DISPLAY")
        .args(["demo", "--dir", s(&dir), "--points", "20k"])
        .output()
        .expect("demo runs");
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "demo failed: {said}");
    // One sentence naming the display, without the place in winit's source it was raised.
    assert!(
        said.contains("cannot open a window: ") && said.contains("(DISPLAY=:7391)"),
        "{said}"
    );
    assert!(!said.contains(".rs:"), "{said}");
    let (w, h, _) = read_png(&dir.join("city.png"));
    assert_eq!((w, h), (1280, 720));
    assert!(String::from_utf8_lossy(&o.stdout).contains("rendering"));
}
