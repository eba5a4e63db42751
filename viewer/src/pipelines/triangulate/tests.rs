//! The triangulation's Rust structs and constants against its WGSL, its counters' reading, and
//! the warm-up a still waits for.

use super::passes::{
    RADIUS_STREAM, STORAGE_BUFFERS, TriangulateUniforms, shaders_for, sided_shaders,
};
use super::targets::{COUNT_WORDS, Counts, SECTORS, SUM_WORDS, SUM64_BYTES, counts_from};
use super::{INFO, uniforms};
use crate::pipelines::params::{ParamValues, ResolvedParams};
use crate::pipelines::shader_tests::{
    module_named, most_storage_buffers, parse, parse_and_validate, parse_and_validate_with,
    rust_layout, wgsl_const, wgsl_layout,
};
use naga::valid::{Capabilities, ValidationFlags, Validator};
use crate::pipelines::{PointStream, ViewFrame};

#[test]
fn uniforms_and_constants_match_their_wgsl() {
    let expected = rust_layout!(TriangulateUniforms {
        eye,
        forward,
        right,
        up,
        prev_eye,
        prev_forward,
        prev_right,
        prev_up,
        max_connection,
        spacing_factor,
        previous,
        max_search_px,
        stored_normals,
        pad0,
        pad1,
        pad2
    });
    for label in [
        "triangulate reproject",
        "triangulate gather",
        "triangulate search",
        "triangulate search distances",
        "triangulate search ids",
        "triangulate normals",
        "triangulate raster",
        "triangulate radii",
        "triangulate shade",
    ] {
        assert_eq!(
            wgsl_layout(&module_named(label), "Triangulate"),
            expected,
            "TriangulateUniforms against Triangulate (uniforms.wgsl) in {label}"
        );
    }
    let raster = module_named("triangulate raster");
    assert_eq!(wgsl_const(&raster, "SECTORS"), SECTORS);
    assert_eq!(wgsl_const(&raster, "SUM_WORDS"), SUM_WORDS);
    assert_eq!(8 * wgsl_const(&raster, "SUM64_WORDS"), SUM64_BYTES);
    assert_eq!(wgsl_const(&raster, "COUNT_WORDS"), COUNT_WORDS);
    // The kept value per point is the radius and the last feedback: two f32.
    assert!(matches!(RADIUS_STREAM, PointStream::Kept { bytes: 8, .. }));
}

/// The 64-bit sums add with 64-bit atomics, which a device with 64-bit min/max alone (Metal)
/// lacks: their modules validate with all 64-bit atomic operations, and the raster's not
/// without, which is why the device's `int64_sums` chooses them and not `int64_atomics`.
#[test]
fn the_64_bit_sums_need_every_64_bit_atomic() {
    let min_max = Capabilities::default()
        | Capabilities::SHADER_INT64
        | Capabilities::SHADER_INT64_ATOMIC_MIN_MAX;
    let all = min_max | Capabilities::SHADER_INT64_ATOMIC_ALL_OPS;
    let modules = shaders_for(true, true);
    for s in &modules {
        parse_and_validate_with(s, all);
    }
    let raster = modules
        .iter()
        .find(|s| s.label == "triangulate raster")
        .expect("the raster module");
    assert!(
        Validator::new(ValidationFlags::all(), min_max)
            .validate(&parse(raster))
            .is_err()
    );
}

#[test]
fn the_hole_rate_is_holes_over_the_pixels_inside() {
    let words: Vec<u8> = [5u32, 70, 10, 90]
        .iter()
        .flat_map(|w| w.to_le_bytes())
        .collect();
    let c = counts_from(&words).expect("four words");
    assert_eq!(
        c,
        Counts {
            culled: 5,
            triangles: 70,
            holes: 10,
            covered: 90
        }
    );
    assert!((c.hole_rate() - 0.1).abs() < 1e-6);
    assert!(counts_from(&words[..12]).is_none(), "a short readback");
    let empty = Counts {
        culled: 0,
        triangles: 0,
        holes: 0,
        covered: 0,
    };
    assert_eq!(empty.hole_rate(), 0.0);
}

#[test]
fn a_still_waits_the_warmup_and_the_first_frame_reprojects_nothing() {
    let mut values = ParamValues::default();
    assert_eq!(INFO.warmup_frames(&values), 8);
    values.set_text(&INFO, "warmup", "3").expect("warmup");
    assert_eq!(INFO.warmup_frames(&values), 3);
    // A pipeline that keeps no previous frame waits for none.
    assert_eq!(
        crate::pipelines::find("pyramid")
            .expect("pyramid")
            .warmup_frames(&values),
        0
    );

    let view = ViewFrame {
        view: glam::Mat4::IDENTITY,
        view_proj: glam::Mat4::IDENTITY,
        fov_y: 1.0,
        near: 0.1,
        far: 10.0,
        focal_px: 500.0,
        aspect: 1.5,
    };
    let params = ResolvedParams::resolve(&ParamValues::default(), &INFO, || Some(0.3));
    let first = uniforms(&view, None, &params, true);
    assert_eq!(first.previous, 0);
    // The dataset's normals shade by default; a dataset without, or the paper's choice, the fans'.
    assert_eq!(first.stored_normals, 1);
    assert_eq!(uniforms(&view, None, &params, false).stored_normals, 0);
    let mut fans = ParamValues::default();
    fans.set_text(&INFO, "stored_normals", "0")
        .expect("stored_normals");
    let fans = ResolvedParams::resolve(&fans, &INFO, || Some(0.3));
    assert_eq!(uniforms(&view, None, &fans, true).stored_normals, 0);
    // max_connection left automatic: five drawn spacings, and two of each point's own node.
    let auto = super::CONNECTION_SPACINGS as f32 * 0.3;
    assert!((first.max_connection - auto).abs() < 1e-6);
    assert_eq!(first.spacing_factor, super::NODE_SPACINGS);
    let mut set = ParamValues::default();
    set.set_text(&INFO, "max_connection", "0.5")
        .expect("max_connection");
    let fixed = uniforms(
        &view,
        None,
        &ResolvedParams::resolve(&set, &INFO, || Some(0.3)),
        true,
    );
    assert_eq!((fixed.max_connection, fixed.spacing_factor), (0.5, 0.0));
    // A dataset of one point draws a spacing of nearly 0: the automatic value stays within
    // the parameter's range.
    let tiny = ResolvedParams::resolve(&ParamValues::default(), &INFO, || Some(2e-15));
    let spec = INFO.param("max_connection").expect("max_connection");
    assert_eq!(tiny.get("max_connection"), Some(spec.min));
    let mut moved = view;
    moved.view = glam::Mat4::from_translation(glam::Vec3::X);
    let next = uniforms(&view, Some(&moved), &params, true);
    assert_eq!(next.previous, 1);
    assert_eq!(next.prev_eye[0], -1.0, "the previous frame's eye");
    assert_eq!(next.eye[0], 0.0);
}

/// The check of the adapter's storage buffers before compiling counts the largest pass.
#[test]
fn the_storage_buffer_check_counts_the_largest_pass() {
    assert_eq!(
        most_storage_buffers(&shaders_for(true, true)),
        Some(STORAGE_BUFFERS)
    );
}

/// The gather, the searches, the raster and the shade compile telling the sides apart (the
/// registry's list holds them without): SIDES is an override of each, and each is given it.
#[test]
fn the_sided_modules_take_sides() {
    // On both search paths and both sums; the 64-bit sums need every 64-bit atomic.
    for (int64, sums64) in [(false, false), (true, false), (true, true)] {
        for s in sided_shaders(true, int64, sums64) {
            let sides: Vec<_> = s.constants.iter().filter(|c| c.0 == "SIDES").collect();
            assert_eq!(sides, [&("SIDES", 1.0)], "{}", s.label);
            if sums64 {
                parse_and_validate_with(&s, Capabilities::all());
            } else {
                parse_and_validate(&s);
            }
        }
    }
}
