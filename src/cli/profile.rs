//! `strata profile`: the points within a corridor around a polyline, as distance along the line
//! against height, read from the dataset at the profile's own level of detail and written as
//! CSV (distance, offset, x, y, z, every attribute) or as LAS, LAZ or PLY.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use strata_viewer::profile::{Corridor, Profile, ProfileDetail, extract};
use strata_viewer::{HttpOptions, StreamDataset};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The dataset: a directory, or http://HOST:PORT/DATASET.
    dataset: String,
    /// The profile's polyline, "X,Y;X,Y[;...]" in the dataset's coordinates.
    #[arg(long)]
    line: String,
    /// The corridor's width, in dataset units (half on each side of the line).
    #[arg(long)]
    width: f64,
    /// Read levels until their point spacing is at most this (dataset units; 0: full detail).
    #[arg(long, default_value_t = 0.0)]
    spacing: f64,
    /// Do not start a level that would take the points read past this.
    #[arg(long, default_value = "20M", value_parser = super::synth::parse_count)]
    max_read: u64,
    /// The file to write: .csv, or .las, .laz, .ply with every attribute.
    #[arg(short, long)]
    output: PathBuf,
    /// Replace the output if it exists.
    #[arg(long)]
    overwrite: bool,
    /// Bearer token for a dataset served with `strata serve --token`.
    #[arg(long, conflicts_with = "token_file")]
    token: Option<String>,
    /// As --token, with the token read from FILE (kept out of `ps`).
    #[arg(long, value_name = "FILE")]
    token_file: Option<PathBuf>,
}

impl Args {
    pub fn dataset(&self) -> &str {
        &self.dataset
    }
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    if !(a.spacing.is_finite() && a.spacing >= 0.0) {
        anyhow::bail!("--spacing {} is not a distance of 0 or more", a.spacing);
    }
    let corridor = Corridor::parse(&a.line, a.width)?;
    let ext = a
        .output
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    if strata_converter::export::is_copc(&a.output) {
        anyhow::bail!(
            "{}: a profile is written as plain .las or .laz, not COPC; name it .laz",
            a.output.display()
        );
    }
    let csv = match ext.as_deref() {
        Some("csv") => true,
        Some("las" | "laz" | "ply") => false,
        _ => anyhow::bail!(
            "{}: the profile is written as .csv, .las, .laz or .ply",
            a.output.display()
        ),
    };
    if a.output.exists() && !a.overwrite {
        anyhow::bail!("{}: exists (use --overwrite)", a.output.display());
    }
    let http = HttpOptions {
        token: super::token::token(a.token.as_deref(), a.token_file.as_deref())?,
        ..HttpOptions::default()
    };
    let ds = StreamDataset::open(&a.dataset, http)?;
    let detail = ProfileDetail {
        spacing: a.spacing,
        max_points_read: a.max_read,
    };
    let profile = extract(&ds, &corridor, detail, |_| true)?;
    if csv {
        profile.write_csv(&a.output)?;
    } else {
        write_points(&ds, &profile, &a.output, a.overwrite)?;
    }
    let d = strata_format::step_decimals(strata_format::finest_step(ds.metadata().scale));
    println!(
        "{} points within {} of a {:.d$} long line (a corridor {} wide; levels 0 to {}, spacing {}, {} points read){} -> {}",
        profile.points.len(),
        strata_format::number(a.width / 2.0),
        corridor.length(),
        strata_format::number(a.width),
        profile.level,
        strata_format::number(profile.spacing),
        profile.points_read,
        if profile.complete {
            ""
        } else {
            "; stopped by --max-read before the spacing asked"
        },
        a.output.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// The profile's points with every attribute, as `strata export` writes a dataset's.
pub fn write_points(
    ds: &StreamDataset,
    profile: &Profile,
    output: &Path,
    overwrite: bool,
) -> anyhow::Result<()> {
    let m = ds.metadata();
    strata_converter::export::export_rows(
        output,
        &profile.layout,
        m.scale,
        m.offset,
        &profile.rows,
        overwrite,
        m.crs.as_ref(),
    )?;
    Ok(())
}
