use super::{LIT_STREAM, streams};
use crate::pipelines::params::ParamValues;
use crate::pipelines::{PointStream, filters, pyramid};

#[test]
fn a_pipeline_holds_the_shadow_streams_only_while_it_casts_shadows() {
    let mut values = ParamValues::default();
    assert_eq!(
        streams(&pyramid::INFO, &values),
        [PointStream::Normals],
        "pyramid without shadows holds only the normals it culls by"
    );
    values
        .set_text(&pyramid::INFO, "shadows", "1")
        .expect("pyramid takes shadows");
    assert_eq!(
        streams(&pyramid::INFO, &values),
        [PointStream::Normals, LIT_STREAM]
    );
    // The filters' own streams hold those (and the radii they size points by), with shadows
    // or without.
    assert_eq!(
        streams(&filters::INFO, &ParamValues::default()),
        [PointStream::Normals, PointStream::Radius, LIT_STREAM]
    );
}

#[test]
fn every_pipeline_that_casts_shadows_takes_the_same_parameters() {
    for info in [&pyramid::INFO, &filters::INFO] {
        for spec in &super::PARAMS {
            let own = info.param(spec.name).expect("the parameter is listed");
            assert_eq!(
                (own.default, own.min, own.max),
                (spec.default, spec.min, spec.max),
                "{} {}",
                info.name,
                spec.name
            );
        }
    }
}
