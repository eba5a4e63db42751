//! The quality harness's command line.

use anyhow::{Context, bail};
use std::path::{Path, PathBuf};

/// A ground-truth mesh given on the command line: a PLY (one colour) or an OBJ (textured by
/// `texture`, white without one), with y up where `y_up` (turned to the harness's z up).
#[derive(Debug, Clone)]
pub struct UserMesh {
    pub path: PathBuf,
    pub texture: Option<PathBuf>,
    pub y_up: bool,
}

pub struct Args {
    pub out: PathBuf,
    pub quick: bool,
    pub width: u32,
    pub height: u32,
    pub data: PathBuf,
    /// Only the scenes of these names; all when empty.
    pub scenes: Vec<String>,
    /// The noise levels of the sampled scenes (fractions of the bounding diagonal) in place of
    /// the run's own, for a sweep of noise alone.
    pub noises: Option<Vec<f64>>,
    /// Meshes of the user's own, each a scene sampled like the bunny and Spot.
    pub meshes: Vec<UserMesh>,
}

pub fn parse_args() -> anyhow::Result<Args> {
    let mut out = None;
    let mut quick = false;
    let mut size = None;
    let mut only = Vec::new();
    let mut noises = None;
    let mut meshes = Vec::new();
    let mut y_up = false;
    let mut data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data");
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--out" => out = it.next().map(PathBuf::from),
            "--quick" => quick = true,
            "--size" => size = it.next(),
            "--scenes" => {
                let list = it.next().context("--scenes needs a comma-separated list")?;
                only = list.split(',').map(str::to_owned).collect();
            }
            "--noises" => {
                let list = it.next().context("--noises needs a comma-separated list")?;
                let levels: Result<Vec<f64>, _> = list.split(',').map(str::parse).collect();
                let levels = levels.with_context(|| format!("--noises {list}: not numbers"))?;
                if levels.iter().any(|n| !(0.0..=0.1).contains(n)) {
                    bail!("--noises {list}: each level is a fraction of the diagonal, 0 to 0.1");
                }
                noises = Some(levels);
            }
            "--mesh" => {
                let spec = it.next().context("--mesh needs a PLY or OBJ file")?;
                let (path, texture) = match spec.split_once(',') {
                    Some((p, t)) => (PathBuf::from(p), Some(PathBuf::from(t))),
                    None => (PathBuf::from(&spec), None),
                };
                meshes.push(UserMesh {
                    path,
                    texture,
                    y_up: false,
                });
            }
            "--y-up" => y_up = true,
            "--data" => {
                data = it
                    .next()
                    .map(PathBuf::from)
                    .context("--data needs a directory")?
            }
            other => bail!("unknown argument {other:?}; usage: {USAGE}"),
        }
    }
    let out = out.context("--out DIR is required")?;
    let (width, height) = match size {
        Some(s) => {
            let (w, h) = s.split_once('x').context("--size is WxH")?;
            (
                w.parse().context("--size width")?,
                h.parse().context("--size height")?,
            )
        }
        None if quick => (320, 240),
        None => (960, 720),
    };
    if !(16..=4096).contains(&width) || !(16..=4096).contains(&height) {
        bail!("--size {width}x{height} is outside 16 to 4096 pixels");
    }
    Ok(Args {
        out,
        quick,
        width,
        height,
        data,
        scenes: only,
        noises,
        meshes: meshes.into_iter().map(|m| UserMesh { y_up, ..m }).collect(),
    })
}

pub const USAGE: &str = "cargo run --release -p strata-bench --bin quality -- --out DIR [--quick] [--size WxH]\n    \
       [--scenes NAME,NAME] [--noises 0,0.002,0.005] [--data DIR]\n    \
       [--mesh FILE.ply|FILE.obj[,TEXTURE.png] ...] [--y-up]";
