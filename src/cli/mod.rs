mod camera_args;
mod convert;
mod demo;
mod export;
mod info;
mod info_input;
mod info_potree2;
mod measure;
mod pick;
mod pipelines;
mod profile;
mod render;
mod serve;
mod synth;
mod token;
mod verify;
mod view;
mod view_args;

use anyhow::Context;
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use strata_format::DatasetFile;

/// Strata: billion-point laser scans on ordinary hardware.
#[derive(Debug, Parser)]
#[command(name = "strata", version, about, propagate_version = true)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Build a dataset from LAS, LAZ, PLY and E57 files.
    Convert(convert::Args),
    /// Print a dataset's summary: points, nodes, depth, bounds, attributes, sizes.
    Info(info::Args),
    /// Check a dataset's structure and every checksum; exit 1 on any fault.
    Verify(verify::Args),
    /// Write every point of a dataset back out as LAS, LAZ, COPC, PLY or Potree 2.0.
    Export(export::Args),
    /// Write a deterministic procedural scene of any size as LAS, LAZ or PLY.
    Synth(synth::Args),
    /// Serve a directory of datasets over HTTP (read-only, byte ranges, optional token).
    Serve(serve::Args),
    /// Open a dataset in a window: stream it under a point budget, orbit and fly.
    View(view::Args),
    /// Render a dataset headless to PNG (one image or a fly-through), with statistics.
    Render(render::Args),
    /// Print the stored point under a pixel of a view, with every attribute.
    Pick(pick::Args),
    /// Measure a distance, area, height or angle between the stored points under pixels.
    Measure(measure::Args),
    /// Write the points within a corridor around a polyline as a height profile (CSV, LAS).
    Profile(profile::Args),
    /// List the render pipelines with their parameters.
    Pipelines(pipelines::Args),
    /// Synthesize a scene, convert it and show it.
    Demo(demo::Args),
}

impl Cli {
    /// The command reads local files and prints text, and opens no socket: a closed pipe may
    /// end it quietly (a server or an HTTP client must not die of a peer that went away).
    pub fn prints_local_text(&self) -> bool {
        let local = |dataset: &str| !strata_viewer::dataset::is_remote(dataset);
        match &self.command {
            Command::Info(_)
            | Command::Pipelines(_)
            | Command::Verify(_)
            | Command::Export(_)
            | Command::Convert(_)
            | Command::Synth(_) => true,
            Command::Pick(a) => local(&a.at.dataset),
            Command::Measure(a) => local(&a.at.dataset),
            Command::Profile(a) => local(a.dataset()),
            Command::Serve(_) | Command::View(_) | Command::Render(_) | Command::Demo(_) => false,
        }
    }
}

pub fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Command::Convert(a) => convert::run(a),
        Command::Info(a) => info::run(a),
        Command::Verify(a) => verify::run(a),
        Command::Export(a) => export::run(a),
        Command::Synth(a) => synth::run(a),
        Command::Serve(a) => serve::run_serve(a),
        Command::View(a) => view::run(a),
        Command::Render(a) => render::run(a),
        Command::Pick(a) => pick::run(a),
        Command::Measure(a) => measure::run(a),
        Command::Profile(a) => profile::run(a),
        Command::Pipelines(a) => pipelines::run(a),
        Command::Demo(a) => demo::run(a),
    }
}

/// Refuses a `--stats` file that cannot be written before the work rather than after
/// it, by opening it to append (and removing it again if it was not there), or that would be
/// written over what the command reads or writes: one of the `taken` files (its inputs, its
/// image), anything inside the `owned` folders (a plan, removed at its finish), or one of the
/// dataset's own files inside the `output`. Any other file inside the output (a dataset),
/// which exists only once the conversion is done, is left to then.
pub(crate) fn check_stats_path(
    stats: &Option<PathBuf>,
    output: Option<&Path>,
    taken: &[PathBuf],
    owned: &[&Path],
) -> anyhow::Result<()> {
    let Some(path) = stats else {
        return Ok(());
    };
    let absolute = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let inside = |dir: &Path| absolute(path).starts_with(absolute(dir));
    let refuse = |what: &str| {
        anyhow::bail!(
            "{}: the --stats file would be written over {what}; give --stats another name",
            path.display()
        )
    };
    if let Some(t) = taken.iter().find(|t| same_file(path, t)) {
        return refuse(&format!(
            "{}, which this command reads or writes",
            t.display()
        ));
    }
    if let Some(dir) = owned.iter().find(|d| inside(d)) {
        return refuse(&format!(
            "the plan folder {} (removed once the dataset is finished)",
            dir.display()
        ));
    }
    if let Some(out) = output
        && inside(out)
    {
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default();
        let dataset_files = [
            DatasetFile::Metadata,
            DatasetFile::Hierarchy,
            DatasetFile::Octree,
        ];
        if absolute(path) == absolute(out) || dataset_files.iter().any(|f| f.name() == name) {
            return refuse(&format!(
                "the output {} or one of its own files",
                out.display()
            ));
        }
        return Ok(());
    }
    let existed = std::fs::symlink_metadata(path).is_ok();
    std::fs::OpenOptions::new()
        .append(true)
        .create(true)
        .open(path)
        .with_context(|| format!("{}: cannot write the --stats file", path.display()))?;
    if !existed {
        let _ = std::fs::remove_file(path);
    }
    Ok(())
}

/// Whether `a` and `b` name the same file: the same path, or (both existing) the same inode
/// through links.
fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    if std::path::absolute(a).ok() == std::path::absolute(b).ok() {
        return true;
    }
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
        _ => false,
    }
}

/// Writes `bytes` to `path` through a temporary name, so that a failed write (a full disk)
/// leaves no file under the name that looks whole.
pub(crate) fn write_whole(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    let mut part = path.as_os_str().to_owned();
    part.push(".part");
    let part = PathBuf::from(part);
    let written = std::fs::write(&part, bytes).and_then(|()| std::fs::rename(&part, path));
    if let Err(e) = written {
        let _ = std::fs::remove_file(&part);
        return Err(e).with_context(|| format!("cannot write {}", path.display()));
    }
    Ok(())
}
