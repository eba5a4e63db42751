//! `strata measure`: a distance, area, height or angle between stored points picked at pixels
//! of a view (as the window's measuring tools pick them), printed and added to a GeoJSON file.

use super::pick::{PickView, parse_pixel};
use std::path::PathBuf;
use std::process::ExitCode;
use strata_viewer::headless::pick_all;
use strata_viewer::measure::{MeasureKind, Measurement, Measurements};

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub(crate) at: PickView,
    /// What to measure: distance (a polyline), area (a polygon), height (of the second point
    /// above the first) or angle (at the second of three points).
    #[arg(long, default_value = "distance")]
    kind: String,
    /// A pixel X,Y whose point is a vertex, in order (repeatable).
    #[arg(long = "pixel", required = true)]
    pixels: Vec<String>,
    /// The measurement's name (default: KIND N).
    #[arg(long)]
    name: Option<String>,
    /// Add the measurement to this GeoJSON file (created if absent; the window reads
    /// DATASET/measurements.geojson).
    #[arg(short, long, value_name = "FILE.geojson")]
    output: Option<PathBuf>,
    /// Print the measurement as a GeoJSON Feature instead of text.
    #[arg(long)]
    json: bool,
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let kind = MeasureKind::parse(&a.kind)?;
    let pixels: Vec<(u32, u32)> = a
        .pixels
        .iter()
        .map(|p| parse_pixel(p))
        .collect::<anyhow::Result<_>>()?;
    let mut all = match &a.output {
        Some(f) => Measurements::load(f)?,
        None => Measurements::default(),
    };
    let probe = Measurement {
        kind,
        name: String::new(),
        points: vec![[0.0; 3]; pixels.len()],
        source: None,
    };
    if !probe.is_complete() {
        anyhow::bail!(
            "{} needs {} --pixel, {} given",
            kind.a_name(),
            match kind.fixed_points() {
                Some(n) => n.to_string(),
                None => format!("at least {}", kind.min_points()),
            },
            pixels.len()
        );
    }
    let opts = a.at.options()?;
    let picked = pick_all(&a.at.dataset, &opts, &pixels, a.at.radius)?;
    let mut points = Vec::with_capacity(picked.len());
    let mut step = f64::INFINITY;
    for (p, (x, y)) in picked.into_iter().zip(&pixels) {
        let Some(p) = p else {
            eprintln!("no point within {} pixels of {x},{y}", a.at.radius);
            return Ok(ExitCode::from(3));
        };
        points.push(p.position);
        step = step.min(p.step);
    }
    let m = Measurement {
        kind,
        name: a.name.unwrap_or_else(|| all.next_name(kind)),
        points,
        source: None,
    };
    // Points that coincide measure no angle: said, not saved as a measurement without a value.
    if m.values().is_empty() {
        anyhow::bail!(
            "the picked points {} measure no {}: they coincide where the measure needs them apart",
            pixels
                .iter()
                .map(|(x, y)| format!("{x},{y}"))
                .collect::<Vec<_>>()
                .join(" "),
            kind.name()
        );
    }
    if a.json {
        let one = Measurements {
            items: vec![m.clone()],
            ..Measurements::default()
        };
        println!(
            "{}",
            serde_json::to_string_pretty(&one.to_geojson()["features"][0])?
        );
    } else {
        for line in m.lines(step) {
            println!("{line}");
        }
    }
    if let Some(f) = &a.output {
        all.items.push(m);
        all.save(f)?;
    }
    Ok(ExitCode::SUCCESS)
}
