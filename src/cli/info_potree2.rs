//! `strata info` on a Potree 2.0 dataset (PotreeConverter 2, `strata export --format potree2`):
//! what its `metadata.json` says, as `info` says it of a Strata dataset.

use anyhow::{Context, bail};
use serde_json::Value;
use std::path::Path;
use std::process::ExitCode;
use strata_converter::sys::format_bytes;

/// The metadata of the Potree dataset in `dir`, where `dir/metadata.json` is one (a version
/// given as text, or a hierarchy without Strata's "format"); `None` for anything else, which
/// `info` then reads as a Strata dataset (and refuses as one: a pipe, a file too large to be
/// metadata, text that is not JSON).
pub fn metadata(dir: &Path) -> Option<Value> {
    let bytes = strata_format::read_metadata_file(&dir.join("metadata.json")).ok()?;
    let v: Value = serde_json::from_slice(&bytes).ok()?;
    let potree = v.get("version").is_some_and(Value::is_string)
        || (v.get("hierarchy").is_some() && v.get("format").is_none());
    potree.then_some(v)
}

/// The fields `info` prints, each checked: a field missing or of the wrong kind is named.
struct Potree2 {
    points: u64,
    depth: u64,
    step: u64,
    first_chunk: u64,
    scale: [f64; 3],
    offset: [f64; 3],
    spacing: f64,
    cube: [[f64; 3]; 2],
    encoding: String,
    projection: String,
    attributes: Vec<Attribute>,
}

/// An attribute's name, type and element count, with its min and max where given.
struct Attribute {
    name: String,
    ty: String,
    count: u64,
    range: Option<(Vec<f64>, Vec<f64>)>,
}

fn read(dir: &Path, v: &Value) -> anyhow::Result<Potree2> {
    let file = dir.join("metadata.json");
    let field = |path: &[&str]| -> anyhow::Result<&Value> {
        path.iter()
            .try_fold(v, |at, key| at.get(key))
            .with_context(|| format!("{}: no \"{}\"", file.display(), path.join(".")))
    };
    let whole = |path: &[&str]| -> anyhow::Result<u64> {
        field(path)?.as_u64().with_context(|| {
            format!(
                "{}: \"{}\" is not a whole number",
                file.display(),
                path.join(".")
            )
        })
    };
    let numbers = |value: &Value, name: &str| -> anyhow::Result<Vec<f64>> {
        value
            .as_array()
            .and_then(|a| a.iter().map(Value::as_f64).collect::<Option<Vec<f64>>>())
            .with_context(|| format!("{}: \"{name}\" is not a list of numbers", file.display()))
    };
    let triple = |path: &[&str]| -> anyhow::Result<[f64; 3]> {
        let name = path.join(".");
        let n = numbers(field(path)?, &name)?;
        <[f64; 3]>::try_from(n.as_slice())
            .ok()
            .with_context(|| format!("{}: \"{name}\" is not three numbers", file.display()))
    };
    // Text where given; `absent` where the field is not there.
    let text = |name: &str, absent: &str| -> anyhow::Result<String> {
        match v.get(name) {
            None => Ok(absent.to_string()),
            Some(t) => t
                .as_str()
                .map(str::to_string)
                .with_context(|| format!("{}: \"{name}\" is not text", file.display())),
        }
    };
    let version = text("version", "")?;
    if version != "2.0" {
        bail!(
            "{}: \"version\" is {version:?}: strata info reads Potree 2.0 datasets (and Strata's)",
            file.display()
        );
    }
    let mut attributes = Vec::new();
    let list = field(&["attributes"])?
        .as_array()
        .with_context(|| format!("{}: \"attributes\" is not a list", file.display()))?;
    for (i, a) in list.iter().enumerate() {
        let name = a
            .get("name")
            .and_then(Value::as_str)
            .with_context(|| format!("{}: attribute {i} has no \"name\"", file.display()))?;
        let ty = a.get("type").and_then(Value::as_str).unwrap_or("undefined");
        let count = a.get("numElements").and_then(Value::as_u64).unwrap_or(1);
        // Only the position's range is shown (the points' bounds): three numbers each.
        let range = match (name, a.get("min"), a.get("max")) {
            ("position", Some(lo), Some(hi)) => {
                let lo = numbers(lo, "position.min")?;
                let hi = numbers(hi, "position.max")?;
                if lo.len() != 3 || hi.len() != 3 {
                    bail!(
                        "{}: the position's \"min\" and \"max\" are not three numbers each",
                        file.display()
                    );
                }
                Some((lo, hi))
            }
            _ => None,
        };
        attributes.push(Attribute {
            name: name.to_string(),
            ty: ty.to_string(),
            count,
            range,
        });
    }
    let spacing = field(&["spacing"])?
        .as_f64()
        .with_context(|| format!("{}: \"spacing\" is not a number", file.display()))?;
    let points = whole(&["points"])?;
    if !spacing.is_finite() || spacing < 0.0 {
        bail!("{}: \"spacing\" is {spacing}", file.display());
    }
    Ok(Potree2 {
        points,
        depth: whole(&["hierarchy", "depth"])?,
        step: whole(&["hierarchy", "stepSize"])?,
        first_chunk: whole(&["hierarchy", "firstChunkSize"])?,
        scale: triple(&["scale"])?,
        offset: triple(&["offset"])?,
        spacing,
        cube: [
            triple(&["boundingBox", "min"])?,
            triple(&["boundingBox", "max"])?,
        ],
        // Potree takes a dataset without one as uncompressed.
        encoding: text("encoding", "DEFAULT")?,
        projection: text("projection", "")?,
        attributes,
    })
}

/// Prints what the Potree 2.0 dataset in `dir` holds (`v`: its metadata).
pub fn describe(dir: &Path, v: &Value, json: bool) -> anyhow::Result<ExitCode> {
    let p = read(dir, v)?;
    let size = |name: &str| std::fs::metadata(dir.join(name)).ok().map(|m| m.len());
    let missing: Vec<&str> = ["hierarchy.bin", "octree.bin"]
        .into_iter()
        .filter(|f| size(f).is_none())
        .collect();
    let bytes = size("hierarchy.bin").unwrap_or(0) + size("octree.bin").unwrap_or(0);
    // The points' own bounds: the position attribute's range (the bounding box is the cube).
    let tight = p
        .attributes
        .iter()
        .find(|a| a.name == "position")
        .and_then(|a| a.range.clone());
    if json {
        let attributes: Vec<Value> = p
            .attributes
            .iter()
            .map(|a| serde_json::json!({"name": a.name, "type": a.ty, "count": a.count}))
            .collect();
        let out = serde_json::json!({
            "format": "potree 2.0",
            "points": p.points,
            "depth": p.depth,
            "cube": {"min": p.cube[0], "max": p.cube[1]},
            "bounds": tight.as_ref().map(|(lo, hi)| serde_json::json!({"min": lo, "max": hi})),
            "scale": p.scale,
            "offset": p.offset,
            "spacing": p.spacing,
            "encoding": p.encoding,
            "attributes": attributes,
            "bytes": bytes,
            "projection": p.projection,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(ExitCode::SUCCESS);
    }
    // Coordinates to the decimals of the finest scale (a millimetre scale: three).
    let finest = p.scale.iter().fold(f64::INFINITY, |m, &s| m.min(s.abs()));
    let decimals = (-finest.log10()).ceil().clamp(0.0, 12.0) as usize;
    let xyz = |v: &[f64]| {
        v.iter()
            .map(|c| format!("{c:.decimals$}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    println!("dataset   {}", dir.display());
    println!(
        "format    Potree 2.0, {} encoding",
        p.encoding.escape_debug()
    );
    println!("points    {}", p.points);
    println!(
        "depth     {} (hierarchy chunks of {} levels, the first {} bytes)",
        p.depth, p.step, p.first_chunk
    );
    if let Some((lo, hi)) = &tight {
        println!("bounds    min {}\n          max {}", xyz(lo), xyz(hi));
    }
    println!(
        "cube      min {}\n          max {}",
        xyz(&p.cube[0]),
        xyz(&p.cube[1])
    );
    println!("scale     {:?}\noffset    {:?}", p.scale, p.offset);
    println!("spacing   {:.6} at the root", p.spacing);
    if missing.is_empty() {
        println!(
            "size      {} in hierarchy.bin and octree.bin ({:.1} bytes/point, {})",
            format_bytes(bytes),
            bytes as f64 / p.points.max(1) as f64,
            if p.encoding == "DEFAULT" {
                "uncompressed"
            } else {
                "compressed"
            }
        );
    } else {
        println!("size      {} missing", missing.join(" and "));
    }
    println!("attributes:");
    for a in &p.attributes {
        let shape = if a.count > 1 {
            format!("{} x {}", a.count, a.ty)
        } else {
            a.ty.clone()
        };
        println!(
            "  {:<30} {}",
            a.name.escape_debug().to_string(),
            shape.escape_debug()
        );
    }
    if !p.projection.is_empty() {
        println!("crs       {}", p.projection.escape_debug());
    }
    println!("served    by `strata serve` as it is (Potree, potree-core)");
    Ok(ExitCode::SUCCESS)
}
