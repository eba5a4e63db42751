//! The transparency reference of the quality harness peels what it should: two squares facing
//! the eye, the near one red and the far one blue, peeled and blended at half opacity give the
//! front-to-back blend at the centre, and one opaque layer gives the plain reference.

use glam::{DVec3, Vec3};
use strata_bench::quality::reference::ReferenceRenderer;
use strata_bench::quality::shapes::plane;
use strata_viewer::gpu::{GpuContext, ProjectionPath};

#[test]
fn two_squares_peel_and_blend_front_to_back() {
    let ctx = GpuContext::new(ProjectionPath::Auto).expect("GPU adapter");
    let (red, blue) = (Vec3::new(0.6, 0.1, 0.1), Vec3::new(0.1, 0.1, 0.6));
    let mut mesh = plane(
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::X * 2.0,
        Vec3::Y * 2.0,
        2,
        red,
    );
    mesh.append(&plane(
        Vec3::new(-1.0, -1.0, -1.0),
        Vec3::X * 2.0,
        Vec3::Y * 2.0,
        2,
        blue,
    ));
    let renderer = ReferenceRenderer::new(&ctx, &mesh, DVec3::ZERO);
    let view = glam::camera::rh::view::look_at_mat4(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, Vec3::Y);
    let projection = glam::camera::rh::proj::directx::perspective(0.5, 1.0, 0.1, 10.0);
    let (w, h, background) = (64u32, 64u32, [20u8, 30, 40]);
    let centre = 4 * (32 * w as usize + 32);
    let plain = renderer
        .render(&ctx, view, projection, w, h, background)
        .expect("reference");
    let opaque = renderer
        .render_peeled(&ctx, view, projection, w, h, background, 1, 1.0)
        .expect("one layer");
    assert_eq!(&opaque[centre..centre + 3], &plain.rgba[centre..centre + 3]);
    // Head-on under the headlight: albedo + the specular 0.25, per channel.
    let lit = |c: Vec3| (c + Vec3::splat(0.25)).min(Vec3::ONE) * 255.0;
    let want =
        lit(red) * 0.5 + lit(blue) * 0.25 + Vec3::from_array(background.map(f32::from)) * 0.25;
    let blended = renderer
        .render_peeled(&ctx, view, projection, w, h, background, 6, 0.5)
        .expect("six layers");
    for (k, w) in want.to_array().iter().enumerate() {
        let got = blended[centre + k] as f32;
        assert!((got - w).abs() < 3.0, "channel {k}: {got}, want {w}");
    }
}
