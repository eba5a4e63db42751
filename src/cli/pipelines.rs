//! `strata pipelines`: every registered render pipeline with its parameters.

use std::process::ExitCode;
use strata_viewer::pipelines::params::Scale;
use strata_viewer::pipelines::{PointStream, REGISTRY};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

fn scale_name(s: Scale) -> &'static str {
    match s {
        Scale::Linear => "linear",
        Scale::Log => "log",
        Scale::Integer => "integer",
        Scale::Toggle => "toggle",
        Scale::Choice(_) => "choice",
    }
}

fn stream_name(s: &PointStream) -> String {
    match s {
        PointStream::Normals => "normals".into(),
        PointStream::Radius => "radius".into(),
        PointStream::Kept { name, bytes } => format!("kept {name} ({bytes} bytes)"),
    }
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    if a.json {
        let list: Vec<serde_json::Value> = REGISTRY
            .iter()
            .map(|p| {
                let params: Vec<serde_json::Value> = p
                    .params
                    .iter()
                    .map(|s| {
                        let choices = match s.scale {
                            Scale::Choice(names) => names.to_vec(),
                            _ => Vec::new(),
                        };
                        serde_json::json!({
                            "name": s.name,
                            "help": s.help,
                            "default": if s.auto.is_some() {
                                serde_json::json!("auto")
                            } else {
                                serde_json::json!(s.default)
                            },
                            "min": s.min,
                            "max": s.max,
                            "scale": scale_name(s.scale),
                            "choices": choices,
                        })
                    })
                    .collect();
                serde_json::json!({
                    "name": p.name,
                    "description": p.description,
                    "paper": p.paper,
                    "lighting": p.lighting.name(),
                    "params": params,
                    "streams": p.streams.iter().map(stream_name).collect::<Vec<_>>(),
                    "passes": p.passes,
                    "previous_frame": p.previous_frame,
                    "reads_colour_plane": p.reads_colour_plane,
                    "reads_planes": p.reads_planes,
                    "uses_point_size": p.uses_point_size,
                    "guard_band": p.guard.describe(),
                })
            })
            .collect();
        println!("{}", serde_json::to_string_pretty(&list)?);
        return Ok(ExitCode::SUCCESS);
    }
    for p in REGISTRY {
        println!("{}: {}", p.name, p.description);
        if let Some(paper) = p.paper {
            println!("  paper: {paper}");
        }
        println!("  lighting: {}", p.lighting.name());
        if !p.streams.is_empty() {
            let streams: Vec<String> = p.streams.iter().map(stream_name).collect();
            println!("  per-point data: {}", streams.join(", "));
        }
        println!("  passes: {}", p.passes.join(", "));
        if p.previous_frame {
            println!("  keeps the previous frame's view and depth");
        }
        if let Some(band) = p.guard.describe() {
            println!("  {band}");
        }
        if !p.uses_point_size {
            println!("  --point-size does not change its picture");
        }
        for s in p.params {
            println!("  --set {}=VALUE  {} ({})", s.name, s.help, s.describe());
        }
    }
    Ok(ExitCode::SUCCESS)
}
