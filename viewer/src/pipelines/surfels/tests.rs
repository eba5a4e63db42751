//! The surfels' Rust structs and constants against their WGSL, and the pieces of their
//! geometry that do not need a GPU.

use super::passes::{
    LIST_HEADER, MODE_PLANAR, PLANE_WORDS, STORAGE_BUFFERS, SUM_WORDS, SurfelUniforms,
};
use crate::pipelines::projection::{GROUP_SIZE, GpuRange, range_table};
use crate::pipelines::shader_tests::{
    module_named, most_storage_buffers, parse_and_validate, rust_layout, wgsl_const, wgsl_layout,
};

#[test]
fn uniforms_and_ranges_match_their_wgsl() {
    for label in [
        "surfel depth planar",
        "surfel depth listing",
        "surfel depth curved",
        "surfel blend planar",
        "surfel blend curved",
    ] {
        let m = module_named(label);
        assert_eq!(
            wgsl_layout(&m, "Surfels"),
            rust_layout!(SurfelUniforms {
                eye,
                forward,
                right,
                up,
                back_faces,
                rings,
                mode,
                normals,
                sin_epsilon,
                h,
                falloff,
                depth_offset,
                curvature,
                flat_px,
                pad1,
                pad2,
                ring_phi
            }),
            "SurfelUniforms against Surfels (uniforms.wgsl) in {label}"
        );
    }
    assert_eq!(
        wgsl_const(&module_named("surfel blend planar"), "SUM_WORDS"),
        SUM_WORDS
    );
    for module in ["surfel depth planar", "surfel blend planar", "surfel shade"] {
        assert_eq!(
            wgsl_const(&module_named(module), "PLANE_WORDS"),
            PLANE_WORDS,
            "{module}"
        );
    }
    assert_eq!(
        wgsl_const(&module_named("surfel depth planar"), "MODE_PLANAR"),
        MODE_PLANAR as u64
    );
    assert_eq!(
        wgsl_const(&module_named("surfel depth listing"), "LIST_HEADER"),
        LIST_HEADER
    );
    assert_eq!(
        wgsl_layout(&module_named("surfel shade"), "Surfels"),
        wgsl_layout(&module_named("surfel depth planar"), "Surfels")
    );
}

#[test]
fn range_tables_carry_the_lod_beside_each_range_and_count_groups() {
    let range = |start, count, children| GpuRange {
        start,
        count,
        first_group: 0,
        spacing: 0.5,
        centre: [1.0, 2.0, 3.0],
        children,
    };
    // Given out of order: the rows come in the order of their starts (`range_holding`).
    let (table, groups) = range_table(
        3,
        &[range(1000, 5, 0), range(0, GROUP_SIZE + 1, 0b1000_0001)],
        GROUP_SIZE,
    );
    assert_eq!((table[0].start, table[0].count), (3, 2), "header");
    assert_eq!((table[1].start, table[2].start), (0, 1000));
    assert_eq!(table[1].first_group, 0);
    assert_eq!(table[2].first_group, 2, "the first range takes two groups");
    assert_eq!(groups, 3);
    assert_eq!(table[1].children, 0b1000_0001);
    assert_eq!(table[2].centre, [1.0, 2.0, 3.0]);
    assert_eq!(table[2].spacing, 0.5);
}

/// The check of the adapter's storage buffers before compiling counts the largest pass.
#[test]
fn the_storage_buffer_check_counts_the_largest_pass() {
    assert_eq!(
        most_storage_buffers(&super::passes::shaders(super::passes::DEFAULT_SIDES)),
        Some(STORAGE_BUFFERS)
    );
}

/// `sides` from the parameter's least to its most, odd and even, compiles: SIDES is an override
/// of the depth and blend modules, and each is given it.
#[test]
fn the_modules_take_every_number_of_sides() {
    for sides in [3, 5, 6, 32] {
        let shaders = super::passes::shaders(sides);
        for s in &shaders {
            parse_and_validate(s);
        }
        let given = shaders
            .iter()
            .filter(|s| s.constants == [("SIDES", sides as f64)])
            .count();
        assert_eq!(
            given, 5,
            "the depth and the blend modules, for {sides} sides"
        );
    }
}

/// The curved modules draw the surfels the listing depth module lists: the listing module and
/// the curved ones bind the list, the other planar modules do not.
#[test]
fn the_curved_list_is_bound_where_it_is_filled_and_read() {
    for (label, binds) in [
        ("surfel depth planar", false),
        ("surfel depth listing", true),
        ("surfel depth curved", true),
        ("surfel blend planar", false),
        ("surfel blend curved", true),
    ] {
        let found = module_named(label)
            .global_variables
            .iter()
            .any(|(_, g)| g.name.as_deref() == Some("curved_list"));
        assert_eq!(found, binds, "{label}");
    }
}
