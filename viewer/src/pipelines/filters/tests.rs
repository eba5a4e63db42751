//! The filters' Rust structs and constants against their WGSL, the counters' reading, the
//! parameter table and the uniforms made from it.

use super::passes::{
    ARGS_BACKGROUND, ARGS_LAYER, ARGS_OCCLUDED, COUNTERS, LIST_HEADER, LISTS, list_of,
};
use super::shade::ShadeVariant;
use super::targets::{LayerCounts, counts_from};
use super::{
    CLASSES, DTILDE_SPACINGS, FiltersUniforms, INFO, MAX_ITERATIONS, MAX_LAYERS, Step,
    shade_variant, uniforms,
};
use crate::pipelines::ViewFrame;
use crate::pipelines::params::{ParamValues, ResolvedParams};
use crate::pipelines::shader_tests::{
    module_named, most_storage_buffers, parse_and_validate, rust_layout, wgsl_const, wgsl_layout,
};

#[test]
fn uniforms_steps_and_constants_match_their_wgsl() {
    for label in ["filters shade", "fill background", "filters resolve"] {
        let m = module_named(label);
        assert_eq!(
            wgsl_layout(&m, "Filters"),
            rust_layout!(FiltersUniforms {
                eye,
                forward,
                right,
                up,
                light,
                class_opacity,
                dtilde,
                normals,
                opacity,
                lit_scale,
                pad0,
                pad1,
                pad2,
                pad3
            }),
            "FiltersUniforms against Filters (uniforms.wgsl) in {label}"
        );
        assert_eq!(
            wgsl_layout(&m, "Step"),
            rust_layout!(Step {
                layer,
                iteration,
                kind,
                complemented
            }),
            "Step against uniforms.wgsl in {label}"
        );
    }
    let m = module_named("filters args");
    assert_eq!(wgsl_const(&m, "MAX_LAYERS"), MAX_LAYERS as u64);
    assert_eq!(wgsl_const(&m, "MAX_ITERATIONS"), MAX_ITERATIONS as u64);
    assert_eq!(wgsl_const(&m, "COUNTERS"), COUNTERS);
    assert_eq!(wgsl_const(&m, "CLASSES"), CLASSES as u64);
    assert_eq!(wgsl_const(&m, "ARGS_LAYER"), ARGS_LAYER as u64);
    assert_eq!(wgsl_const(&m, "ARGS_BACKGROUND"), ARGS_BACKGROUND as u64);
    assert_eq!(wgsl_const(&m, "ARGS_OCCLUDED"), ARGS_OCCLUDED as u64);
    assert_eq!(wgsl_const(&m, "LIST_HEADER"), LIST_HEADER);
    assert_eq!(wgsl_const(&m, "LISTS"), LISTS);
    // Every kind's every iteration has a list of its own.
    assert_eq!(list_of(ARGS_OCCLUDED, MAX_ITERATIONS - 1), LISTS - 1);
    assert_eq!(
        list_of(ARGS_BACKGROUND, MAX_ITERATIONS - 1) + 1,
        list_of(ARGS_OCCLUDED, 0)
    );
}

/// The word `changed_slot(layer, kind, iteration)` of uniforms.wgsl writes.
fn changed_slot(layer: u32, kind: u32, iteration: u32) -> usize {
    (MAX_LAYERS + (layer * 2 + kind - 1) * MAX_ITERATIONS + iteration) as usize
}

#[test]
fn counters_give_layers_used_and_the_longest_fill() {
    let mut words = vec![0u32; COUNTERS as usize];
    words[0] = 1;
    words[1] = 1;
    words[3] = 1;
    // Layer 1's occluded fill changed pixels in its first five iterations.
    for i in 0..5 {
        words[changed_slot(1, ARGS_OCCLUDED, i)] = 1;
    }
    words[changed_slot(0, ARGS_BACKGROUND, 0)] = 1;
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    assert_eq!(
        counts_from(&bytes),
        Some(LayerCounts {
            layers_used: 3,
            background_iterations: 1,
            occluded_iterations: 5
        })
    );
    assert_eq!(counts_from(&bytes[..100]), None);
    assert_eq!(
        changed_slot(MAX_LAYERS - 1, ARGS_OCCLUDED, MAX_ITERATIONS - 1),
        COUNTERS as usize - 1
    );
}

fn view() -> ViewFrame {
    let view = glam::camera::rh::view::look_at_mat4(
        glam::Vec3::new(0.0, -3.0, 0.0),
        glam::Vec3::ZERO,
        glam::Vec3::Z,
    );
    let proj = glam::camera::rh::proj::directx::perspective(1.0, 1.5, 0.1, 10.0);
    ViewFrame {
        view,
        view_proj: proj * view,
        fov_y: 1.0,
        near: 0.1,
        far: 10.0,
        focal_px: 500.0,
        aspect: 1.5,
    }
}

fn resolved(set: &[(&str, &str)]) -> ResolvedParams {
    let mut values = ParamValues::default();
    for (name, text) in set {
        values.set_text(&INFO, name, text).expect("a valid setting");
    }
    ResolvedParams::resolve(&values, &INFO, || Some(0.25))
}

#[test]
fn uniforms_take_the_light_the_class_opacities_and_the_drawn_spacing() {
    let u = uniforms(&view(), &resolved(&[]), true);
    assert_eq!(u.light, [0.0; 4], "the headlight by default");
    assert_eq!(
        u.dtilde,
        0.25 * DTILDE_SPACINGS as f32,
        "d~ follows the drawn spacing"
    );
    assert_eq!(
        shade_variant(&resolved(&[]), &u),
        ShadeVariant::default(),
        "the default shade: silhouettes anti-aliased, normals carried, the headlight"
    );
    assert!(
        (glam::Vec3::from_slice(&u.eye[..3]) - glam::Vec3::new(0.0, -3.0, 0.0)).length() < 1e-5
    );
    assert!((glam::Vec3::from_slice(&u.forward[..3]) - glam::Vec3::Y).length() < 1e-5);

    let u = uniforms(
        &view(),
        &resolved(&[
            ("light", "0,0,2"),
            ("opacity.6", "0.25"),
            ("opacity", "0.5"),
            ("dtilde", "0.1"),
        ]),
        false,
    );
    assert_eq!(u.light, [0.0, 0.0, 1.0, 1.0], "a direction, normalised");
    assert_eq!(u.class_opacity[1][2], 0.25, "class 6 (building)");
    assert_eq!(u.class_opacity[0][2], 1.0, "class 2 keeps its factor");
    assert_eq!(u.opacity, 0.5);
    assert_eq!(u.dtilde, 0.1);
    assert_eq!(u.normals, 0);
    let params = resolved(&[("light", "0,0,2"), ("antialias", "2")]);
    assert_eq!(
        shade_variant(&params, &u),
        ShadeVariant {
            antialias: 2,
            estimate_normals: true,
            phong: true
        }
    );
    let mut shadowed = uniforms(&view(), &resolved(&[]), true);
    shadowed.lit_scale = 1.0 / 16.0;
    assert!(
        shade_variant(&resolved(&[]), &shadowed).phong,
        "shadows under the headlight need each texel's lit share"
    );
}

/// Every shade variant validates and names only overrides shade.wgsl declares.
#[test]
fn every_shade_variant_validates() {
    for antialias in 0..=2 {
        for estimate_normals in [false, true] {
            for phong in [false, true] {
                let s = ShadeVariant {
                    antialias,
                    estimate_normals,
                    phong,
                }
                .source();
                parse_and_validate(&s);
                assert_eq!(s.constants.len(), 3, "{:?}", s.constants);
            }
        }
    }
}

#[test]
fn the_parameter_table_names_every_class_once() {
    let names: Vec<&str> = INFO.params.iter().map(|p| p.name).collect();
    let mut unique = names.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), names.len(), "{names:?}");
    for c in 0..CLASSES {
        assert!(
            names.contains(&format!("opacity.{c}").as_str()),
            "opacity.{c}"
        );
    }
    let mut values = ParamValues::default();
    assert!(
        values.set_text(&INFO, "opacity.19", "0.5").is_err(),
        "classes beyond 18 have none"
    );
    assert!(values.set_text(&INFO, "layers", "9").is_err());
    assert!(
        values.set_text(&INFO, "light", "1,2").is_err(),
        "a light takes three numbers"
    );
    // A direction of any finite length, however short or long, is normalised.
    for (text, x) in [("1e-20,0,0", 1.0), ("-1e-20,0,0", -1.0), ("1e20,0,0", 1.0)] {
        let u = uniforms(&view(), &resolved(&[("light", text)]), true);
        assert_eq!(u.light[..3], [x, 0.0, 0.0], "light={text}");
    }
    let u = uniforms(&view(), &resolved(&[("light", "1e-30,0,1e-30")]), true);
    assert!((u.light[0] - 0.5f32.sqrt()).abs() < 1e-6, "{:?}", u.light);
}

/// The adapter check in `FiltersPasses::new` names the most storage buffers any filters module
/// binds in one pass.
#[test]
fn the_storage_buffer_check_counts_the_largest_pass() {
    let mut shaders = super::passes::shaders(true);
    shaders.extend(super::passes::shaders(false));
    assert_eq!(
        most_storage_buffers(&shaders),
        Some(super::passes::STORAGE_BUFFERS)
    );
}
