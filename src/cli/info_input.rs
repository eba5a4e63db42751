//! `strata info` on a PLY or E57 file: what `convert` would read of it (points, attributes,
//! scans and where their scanners stood, the CRS it states), from its header alone.

use std::path::Path;
use std::process::ExitCode;

/// Whether `info` describes `path` as an input (by its extension, as `convert` reads it).
pub fn is_read_as_input(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("ply") || e.eq_ignore_ascii_case("e57"))
}

pub fn input_file(path: &Path, json: bool) -> anyhow::Result<ExitCode> {
    let source = strata_converter::input::open_source(path)?;
    let info = source.info();
    let kind = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or_default()
        .to_ascii_uppercase();
    if json {
        let attributes: Vec<serde_json::Value> = info
            .attributes
            .iter()
            .map(|at| serde_json::json!({"name": at.name, "type": at.ty.name(), "count": at.count}))
            .collect();
        let v = serde_json::json!({
            "file": path,
            "kind": kind,
            "points": info.points,
            "attributes": attributes,
            "scanners": info.scanners,
            "crs": info.crs,
            "warnings": info.warnings,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(ExitCode::SUCCESS);
    }
    println!("file      {}", path.display());
    println!("kind      {kind}");
    if kind == "E57" {
        // The scans' record counts: convert skips the points the file marks invalid.
        println!("points    {} records", info.points);
    } else {
        println!("points    {}", info.points);
    }
    println!("attributes:");
    for at in &info.attributes {
        println!("  {:<30} {} x {}", at.name, at.count, at.ty.name());
    }
    if let Some(crs) = &info.crs {
        println!("crs       {}", super::info::crs_stated(crs));
    }
    if !info.scanners.is_empty() {
        println!(
            "scanners ({}, where the file says they stood):",
            info.scanners.len()
        );
        for (i, [x, y, z]) in info.scanners.iter().enumerate() {
            println!("  {i:>3} {x:.3} {y:.3} {z:.3}");
        }
    }
    for w in &info.warnings {
        println!("warning   {w}");
    }
    println!(
        "          `strata convert {}` makes a dataset of it",
        path.display()
    );
    Ok(ExitCode::SUCCESS)
}
