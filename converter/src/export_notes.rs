//! What an export cannot state of a dataset, said before it is written: the coordinate
//! reference system, a time base, the scanners' positions.

use crate::error::Result;
use crate::export::{Target, high_classes, is_copc, widened};
use crate::las_export_names::las_export_renames;
use std::path::Path;
use strata_format::LocalDataset;

/// What an export to `output` cannot state of the dataset, to be said before it is written:
/// its coordinate reference system (`crs_loss`), and a time base it lacks (`time_base_claim`).
pub fn export_notes(dataset: &Path, output: &Path, potree2: bool) -> Result<Vec<String>> {
    let ds = LocalDataset::open(dataset)?;
    let ext = output
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let kind = match ext.as_deref() {
        _ if potree2 => Output::Potree2,
        _ if is_copc(output) => Output::Copc,
        Some("las" | "laz") => Output::Las,
        Some("ply") => Output::Ply,
        _ => Output::Other,
    };
    let said = |what: String| format!("{}: {what}", output.display());
    let renamed = matches!(kind, Output::Las | Output::Copc)
        .then(|| las_export_renames(&ds.metadata().attributes))
        .unwrap_or_default()
        .into_iter()
        .map(|(i, new, why)| {
            format!(
                "attribute \"{}\" is written as \"{new}\": {why}",
                ds.metadata().attributes[i].name
            )
        });
    let facts = [
        crs_loss(&ds, kind),
        time_base_claim(&ds, kind),
        time_base_loss(&ds, kind),
        scanners_loss(&ds, kind),
    ];
    Ok(facts
        .into_iter()
        .flatten()
        .chain(renamed)
        .map(said)
        .collect())
}

/// What an export writes.
#[derive(Clone, Copy, PartialEq)]
enum Output {
    Las,
    Copc,
    Ply,
    Potree2,
    Other,
}

/// Time stamps of no base going to LAS or COPC: LAS has no "unknown", and global encoding
/// bit 0 clear states GPS week time.
fn time_base_claim(ds: &LocalDataset, kind: Output) -> Option<String> {
    let unknown = ds
        .metadata()
        .attributes
        .iter()
        .any(|a| a.name == "gps_time" && a.time_base.is_none());
    (unknown && matches!(kind, Output::Las | Output::Copc)).then(|| {
        "the dataset's gps_time states no time base (its inputs gave none), and LAS has no \
         place for \"unknown\": the output states GPS week time (global encoding bit 0 clear)"
            .to_string()
    })
}

/// A time base PLY and Potree 2.0 have no place for: their readers get the times without it.
fn time_base_loss(ds: &LocalDataset, kind: Output) -> Option<String> {
    let format = match kind {
        Output::Ply => "PLY",
        Output::Potree2 => "Potree 2.0",
        _ => return None,
    };
    let a = ds
        .metadata()
        .attributes
        .iter()
        .find(|a| a.time_base.is_some())?;
    let base = a.time_base?.name();
    Some(format!(
        "{format} has no place for what \"{}\" counts from ({base}); the output keeps the \
         times, not their base",
        a.name
    ))
}

/// Where the scanners stood (E57 poses): no export format has a place for them. Each point's
/// `scanner` index goes out as an attribute.
fn scanners_loss(ds: &LocalDataset, kind: Output) -> Option<String> {
    let n = ds.metadata().scanners.len();
    (n > 0 && kind != Output::Other).then(|| {
        format!(
            "the output has no place for where the dataset's {n} scanner(s) stood (metadata.json \
             \"scanners\"); it keeps each point's scanner index, not the positions"
        )
    })
}

/// The dataset's coordinate reference system where the output cannot state it: any in PLY,
/// which has no place for one; one given as GeoTIFF keys only, where the output states a CRS
/// as WKT alone (COPC, Potree 2.0, LAS point formats 6 to 10). Strata does not translate
/// GeoTIFF keys into WKT.
fn crs_loss(ds: &LocalDataset, kind: Output) -> Option<String> {
    let crs = ds.metadata().crs.as_ref()?;
    if kind == Output::Ply {
        return Some(
            "PLY has no place for the dataset's coordinate reference system; the output states \
             none (LAS, COPC and Potree 2.0 do)"
                .into(),
        );
    }
    if crs.wkt.is_some() || crs.geotiff.is_none() {
        return None;
    }
    let lost = match kind {
        Output::Potree2 => "Potree 2.0 states one as WKT, so the output states none".to_string(),
        Output::Copc => "COPC states one as WKT, so the output states none".to_string(),
        Output::Las => {
            let layout = widened(ds.layout(), Target::Las).layout;
            let format = crate::writers::las_format_for(&layout, high_classes(ds.metadata()));
            if format < 6 {
                return None;
            }
            format!(
                "point format {format} states one as WKT; the output carries the GeoTIFF keys, \
                 which readers that follow the format ignore"
            )
        }
        Output::Ply | Output::Other => return None,
    };
    Some(format!(
        "the dataset's coordinate reference system is given as GeoTIFF keys only, and {lost} \
         (strata does not translate GeoTIFF keys into WKT)"
    ))
}
