//! `quantize::choose` against inputs of every kind of grid: one step on every axis, grids kept
//! where a common step fits, and the reason said where positions are rounded.

use super::*;

fn las(scale: f64, offset: f64, min: f64, max: f64) -> SourceExtent {
    SourceExtent {
        precision: Precision::Scaled {
            scale: [scale; 3],
            offset: [offset; 3],
        },
        min: [min; 3],
        max: [max; 3],
    }
}

#[test]
fn shared_las_grid_is_kept_exactly() {
    let q = choose(
        &[las(0.01, 600000.0, 636000.0, 640000.0)],
        [636000.0; 3],
        [640000.0; 3],
    )
    .expect("fits");
    assert_eq!(q.scale, [0.01; 3]);
    assert_eq!(q.offset, [600000.0; 3]);
    let p = [636123.45, 636123.45, 636123.45];
    let back = q.offset[0] + q.scale[0] * q.quantize(&p)[0] as f64;
    assert!((back - p[0]).abs() < 1e-9);
}

#[test]
fn mixed_scales_take_the_finest() {
    let q = choose(
        &[las(0.01, 0.0, 0.0, 100.0), las(0.001, 0.0, 0.0, 100.0)],
        [0.0; 3],
        [100.0; 3],
    )
    .expect("fits");
    assert_eq!(q.scale, [0.001; 3]);
    assert!(!q.coarsened);
}

#[test]
fn a_far_float_outlier_is_said() {
    let cloud = |max: f64| SourceExtent {
        precision: Precision::Float32,
        min: [0.0; 3],
        max: [max, 100.0, 100.0],
    };
    let q = choose(&[cloud(100.0)], [0.0; 3], [100.0; 3]).expect("fits");
    assert_eq!(q.coarse_floats, None);
    let q = choose(&[cloud(1e30)], [0.0; 3], [1e30, 100.0, 100.0]).expect("fits");
    let note = q.coarse_floats.expect("said");
    assert!(
        note.starts_with("floating-point coordinates stored in steps of 1e21 ")
            && note.contains("x 0e0 to 1e30"),
        "{note}"
    );
    assert!(note.contains("outlier"), "{note}");
    // A scaled input chose its own step: nothing to say.
    let q = choose(&[las(10.0, 0.0, 0.0, 1e6)], [0.0; 3], [1e6; 3]).expect("fits");
    assert_eq!(q.coarse_floats, None);
}

#[test]
fn float32_scale_is_below_one_ulp() {
    let s = SourceExtent {
        precision: Precision::Float32,
        min: [-0.1; 3],
        max: [0.2; 3],
    };
    let q = choose(&[s], [-0.1; 3], [0.2; 3]).expect("fits");
    let ulp = 0.2f32.next_up() as f64 - 0.2f32 as f64;
    assert!(
        q.scale[0] <= ulp && q.scale[0] * 10.0 > ulp,
        "{:?}",
        q.scale
    );
}

#[test]
fn a_resolution_is_the_scale_on_no_grid() {
    // E57 scaled integers after a pose: their step, with an offset taken from the points.
    let s = SourceExtent {
        precision: Precision::Resolution([1e-4; 3]),
        min: [-12.34567; 3],
        max: [20.0; 3],
    };
    let q = choose(&[s], [-12.34567; 3], [20.0; 3]).expect("fits");
    assert_eq!(q.scale, [1e-4; 3]);
    assert!(!q.coarsened && q.offset[0] <= -12.34567);
}

#[test]
fn points_that_would_all_become_one_position_are_refused() {
    let tiny = SourceExtent {
        precision: Precision::Float64,
        min: [1e-300; 3],
        max: [9e-300; 3],
    };
    let err = choose(std::slice::from_ref(&tiny), tiny.min, tiny.max).expect_err("one position");
    assert!(err.contains("would all become one position"), "{err}");
    // One point, or points that are truly the same, are kept as they are.
    let same = SourceExtent {
        max: tiny.min,
        ..tiny
    };
    assert!(choose(std::slice::from_ref(&same), same.min, same.max).is_ok());
}

#[test]
fn an_axis_whose_whole_extent_a_coarsened_step_swallows_is_refused() {
    // x in steps of 1e300 (an E57 field's scale), y and z in tenths of a millimetre over 10 cm:
    // 32-bit positions hold x only in steps far beyond y's and z's whole extent.
    let wide = SourceExtent {
        precision: Precision::Scaled {
            scale: [1e300, 1e-4, 1e-4],
            offset: [0.0; 3],
        },
        min: [-1e306, 0.0, 0.0],
        max: [1e306, 0.1, 0.1],
    };
    let err = choose(std::slice::from_ref(&wide), wide.min, wide.max).expect_err("y is lost");
    assert!(
        err.contains("span 2e306, which 32-bit positions hold only in steps of 1e297, more than twice the whole 0.1 the y coordinates span"),
        "{err}"
    );
}

#[test]
fn huge_extents_coarsen_rather_than_overflow() {
    let q = choose(&[las(0.0001, 0.0, -1e7, 1e7)], [-1e7; 3], [1e7; 3]).expect("fits");
    assert!(q.coarsened);
    assert!(((1e7 - q.offset[0]) / q.scale[0]) <= i32::MAX as f64);
}

#[test]
fn extreme_scales_and_offsets_end_in_an_answer() {
    // These looped for ever: a step count of infinity made the offset NaN.
    let tiny = las(5e-324, 0.0, 0.0, 1000.0);
    assert!(choose(&[tiny], [0.0; 3], [1000.0; 3]).is_ok_and(|q| q.scale[0].is_normal()));
    let far = las(0.01, -1e308, 0.0, 0.0);
    let q = choose(&[far], [0.0; 3], [0.0; 3]).expect("fits");
    assert!(q.offset[0].is_finite());
    let wide = SourceExtent {
        precision: Precision::Float64,
        min: [-1.7e308; 3],
        max: [1.7e308; 3],
    };
    // Coarsened to a finite scale; whether the cube is storable is prepare's check.
    let q = choose(&[wide], [-1.7e308; 3], [1.7e308; 3]).expect("coarsened");
    assert!(q.scale[0].is_normal() && q.offset[0].is_finite());
    assert!(q.coarse_floats.is_some(), "a step over one unit is said");
}

#[test]
fn a_coarsened_step_keeps_an_input_on_that_step_exactly() {
    // Centimetres near 0 and millimetres near 10^7: millimetres do not fit 32 bits over
    // the span, centimetres do, and the centimetre input must keep its positions.
    let near = las(0.01, 0.0, 100.0, 200.0);
    let far = las(0.001, 1e7, 1e7, 1e7 + 1.003);
    let (min, max) = ([100.0; 3], [1e7 + 1.003; 3]);
    let q = choose(&[near, far], min, max).expect("fits");
    assert!(q.coarsened);
    assert_eq!(q.scale, [0.01; 3]);
    for i in [10_000i64, 12_345, 19_999] {
        let p = i as f64 * 0.01;
        let back = q.offset[0] + q.scale[0] * q.quantize(&[p; 3])[0] as f64;
        assert!((back - p).abs() < 1e-6, "{p} comes back as {back}");
    }
}

#[test]
fn floats_are_stored_on_a_decimal_step_without_a_coarsening_warning() {
    let doubles = |min: [f64; 3], max: [f64; 3]| SourceExtent {
        precision: Precision::Float64,
        min,
        max,
    };
    // Three points 2 m apart, on the x axis only: a double's own resolution does not
    // fit 32 bits, which says nothing of the data; y and z, zero everywhere, take x's step
    // rather than one that single precision holds as 0.
    let (min, max) = ([0.0; 3], [2.0, 0.0, 0.0]);
    let q = choose(&[doubles(min, max)], min, max).expect("fits");
    assert!(!q.coarsened && q.coarse_floats.is_none(), "{q:?}");
    assert_eq!(q.scale, [1e-9; 3], "a tenfold of 1e-16 rounded once");
    // A declared step that must grow is said, and is an exact decimal.
    let q = choose(&[las(1e-9, 0.0, -1e3, 1e3)], [-1e3; 3], [1e3; 3]).expect("fits");
    assert!(q.coarsened);
    assert_eq!(q.scale, [1e-6; 3]);
}

#[test]
fn every_axis_takes_one_step() {
    // Floats of magnitude 1.0 and 0.12 ask 1e-7 and 1e-8: both axes are stored in 1e-8, or
    // the octree's cubes would be boxes ten times longer along x.
    let floats = SourceExtent {
        precision: Precision::Float32,
        min: [-1.0, -0.125, -0.75],
        max: [1.0, 0.125, 0.75],
    };
    let q = choose(std::slice::from_ref(&floats), floats.min, floats.max).expect("fits");
    assert_eq!(q.scale, [1e-8; 3]);
    assert!(!q.coarsened && q.coarse_floats.is_none(), "{q:?}");
    // A LAS grid of centimetres across and millimetres up: millimetres on every axis, the
    // input's offset kept, so each of its positions is stored exactly.
    let las = SourceExtent {
        precision: Precision::Scaled {
            scale: [0.01, 0.01, 0.001],
            offset: [500000.0, 4000000.0, 0.0],
        },
        min: [500100.0, 4000100.0, 10.0],
        max: [501100.0, 4001100.0, 90.0],
    };
    let q = choose(std::slice::from_ref(&las), las.min, las.max).expect("fits");
    assert_eq!(q.scale, [0.001; 3]);
    assert_eq!(q.offset, [500000.0, 4000000.0, 0.0]);
    assert!(!q.coarsened);
    let p = [500123.45, 4000678.91, 12.345];
    let i = q.quantize(&p);
    for a in 0..3 {
        assert!((q.offset[a] + q.scale[a] * i[a] as f64 - p[a]).abs() < 1e-9);
    }
    // Where the finest step does not fit the widest axis, every axis coarsens with it.
    let wide = SourceExtent {
        precision: Precision::Float64,
        min: [0.0, 0.0, 0.0],
        max: [1000.0, 1.0, 0.001],
    };
    let q = choose(std::slice::from_ref(&wide), wide.min, wide.max).expect("fits");
    // Doubles ask 1e-13 (x) and 1e-19 (z); 1000 units fit 32 bits from 1e-6 up.
    assert_eq!(q.scale, [1e-6; 3]);
    assert!(!q.coarsened);
}

#[test]
fn inputs_on_grids_of_other_steps_keep_their_positions() {
    let scaled = |scale: [f64; 3], offset: [f64; 3]| SourceExtent {
        precision: Precision::Scaled { scale, offset },
        min: [0.0; 3],
        max: [100.0; 3],
    };
    let exact = |q: &Quantization, p: [f64; 3]| {
        let i = q.quantize(&p);
        (0..3).all(|a| (q.offset[a] + q.scale[a] * i[a] as f64 - p[a]).abs() < 1e-9)
    };
    // Steps of 0.0025 and 0.003 on one file: both grids are grids of 0.0005.
    let one = scaled([0.0025, 0.0025, 0.003], [0.0; 3]);
    let q = choose(std::slice::from_ref(&one), one.min, one.max).expect("fits");
    assert_eq!(q.scale, [0.0005; 3]);
    assert!(exact(&q, [0.0025 * 7.0, 0.0025 * 9.0, 0.003 * 11.0]));
    // Millimetres from 1000 and centimetres from 0: one grid.
    let (a, b) = (scaled([0.001; 3], [1000.0; 3]), scaled([0.01; 3], [0.0; 3]));
    let q = choose(&[a, b], [0.0; 3], [100.0; 3]).expect("fits");
    assert_eq!(q.scale, [0.001; 3]);
    assert!(exact(&q, [0.002, 12.001, 99.999]) && exact(&q, [0.01, 12.34, 99.99]));
    // A LAS beside a float input keeps its grid (floats have none to keep).
    let las = SourceExtent {
        min: [636000.0; 3],
        max: [640000.0; 3],
        ..scaled([0.01; 3], [0.0; 3])
    };
    let floats = SourceExtent {
        precision: Precision::Float32,
        min: [-0.11, 0.02, -0.07],
        max: [0.06, 0.19, 0.06],
    };
    let q = choose(&[las, floats], [-0.11, 0.02, -0.07], [640000.0; 3]).expect("fits");
    assert_eq!(q.offset, [0.0; 3]);
    assert!(exact(&q, [637179.22, 636000.01, 639999.99]), "{q:?}");
}

#[test]
fn every_input_keeps_its_grid_where_a_step_fits() {
    let las = |scale: f64, offset: f64, max: f64| SourceExtent {
        precision: Precision::Scaled {
            scale: [scale; 3],
            offset: [offset; 3],
        },
        min: [0.0; 3],
        max: [max; 3],
    };
    // Two files of 0.002 and 0.0025 on every axis: half millimetres, not 0.002.
    let q = choose(
        &[las(0.002, 0.0, 10.0), las(0.0025, 0.0, 10.0)],
        [0.0; 3],
        [10.0; 3],
    )
    .expect("fits");
    assert_eq!(q.scale, [0.0005; 3]);
    // Offsets 0.005 apart on centimetres: half centimetres keep both.
    let q = choose(
        &[las(0.01, 0.005, 10.0), las(0.01, 0.0, 10.0)],
        [0.0; 3],
        [10.0; 3],
    )
    .expect("fits");
    assert_eq!((q.scale, q.offset), ([0.005; 3], [0.005; 3]));
    // Quarter millimetres beside doubles over 50 km: the doubles' 1e-12 does not fit, and
    // neither does 1e-4 keep the quarters; 0.00025 does both.
    let doubles = SourceExtent {
        precision: Precision::Float64,
        min: [0.0; 3],
        max: [5e4; 3],
    };
    let q = choose(&[las(0.00025, 0.0, 5e4), doubles], [0.0; 3], [5e4; 3]).expect("fits");
    assert_eq!(q.scale, [0.00025; 3]);
    assert!(!q.coarsened);
    // A scale rounded through single precision is no decimal: kept as it is.
    let odd = 0.01f32 as f64;
    let q = choose(&[las(odd, 0.0, 100.0)], [0.0; 3], [100.0; 3]).expect("fits");
    assert_eq!(q.scale, [odd; 3]);
    // Where nothing keeps every grid, the step that fits is said to lose some.
    let q = choose(&[las(0.00025, 0.0, 2e6)], [0.0; 3], [2e6; 3]).expect("fits");
    assert!(q.coarsened && q.scale[0] > 0.00025, "{q:?}");
}

#[test]
fn grids_that_share_no_step_are_said_apart_from_a_wide_span() {
    let las = |offset: f64| SourceExtent {
        precision: Precision::Scaled {
            scale: [0.01; 3],
            offset: [offset; 3],
        },
        min: [0.0; 3],
        max: [100.0; 3],
    };
    let q = choose(&[las(0.0), las(0.123456789012345)], [0.0; 3], [100.0; 3]).expect("fits");
    assert_eq!(q.scale, [0.01; 3]);
    let said = q.coarse_grids.expect("said");
    assert!(said.contains("share no decimal step"), "{said}");
    let wide = SourceExtent {
        min: [0.0; 3],
        max: [1e8; 3],
        ..las(0.0)
    };
    let q = choose(std::slice::from_ref(&wide), wide.min, wide.max).expect("fits");
    let said = q.coarse_grids.expect("said");
    assert!(
        said.contains("span too far") && said.contains("1e-1"),
        "{said}"
    );
    assert_eq!(
        choose(&[las(0.0), las(5.0)], [0.0; 3], [100.0; 3]).map(|q| q.coarse_grids),
        Ok(None)
    );
}
