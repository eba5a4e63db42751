use std::path::PathBuf;
use std::process::ExitCode;
use strata_converter::synth::{Scene, synth};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Number of points (accepts 1e9 and 10M style values).
    #[arg(long, value_parser = parse_count)]
    points: u64,
    /// The file to write (.las, .laz or .ply).
    #[arg(short, long)]
    output: PathBuf,
    /// The scene: city (buildings, trees, streets) or terrain.
    #[arg(long, default_value = "city", value_parser = ["city", "terrain"])]
    scene: String,
    /// Seed: the same seed and arguments always give the same points (and, with
    /// SOURCE_DATE_EPOCH set, the same file: a LAS header dates itself to the day it is
    /// written).
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    seed: u64,
    /// Gaussian noise added to every coordinate, as a deviation in metres (a scanner's
    /// ranging noise; 0 leaves the scene exact).
    // Negative numbers reach the check that says what is wrong, not clap's "unexpected
    // argument '-1'".
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    noise: f64,
    /// Replace the output if it exists.
    #[arg(long)]
    overwrite: bool,
}

/// Parses `1000000`, `1e9`, `10M`, `2.5k`.
/// The largest count accepted: 2^53, the last whole number every f64 holds.
const MAX_COUNT: u64 = 1 << 53;

pub fn parse_count(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let (num, mult) = match t.chars().last() {
        Some('k' | 'K') => (&t[..t.len() - 1], 1e3),
        Some('m' | 'M') => (&t[..t.len() - 1], 1e6),
        Some('g' | 'G' | 'b' | 'B') => (&t[..t.len() - 1], 1e9),
        _ => (t, 1.0),
    };
    let v: f64 = num
        .parse()
        .map_err(|_| format!("\"{s}\" is not a count (examples: 1000000, 10M, 1e9)"))?;
    if !(v >= 0.0 && v.is_finite()) {
        return Err(format!("\"{s}\" is not a count"));
    }
    let n = v * mult;
    if n.fract() != 0.0 {
        return Err(format!("\"{s}\" is not a whole count"));
    }
    // Beyond 2^53 a count is no longer exact in the f64 it was parsed as; no run is that big.
    if n > MAX_COUNT as f64 {
        return Err(format!("\"{s}\" is more than {MAX_COUNT}"));
    }
    Ok(n as u64)
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    let scene = Scene::parse(&a.scene).unwrap_or(Scene::City);
    let start = std::time::Instant::now();
    synth(&a.output, a.points, scene, a.seed, a.noise, a.overwrite)?;
    let s = start.elapsed().as_secs_f64();
    println!(
        "wrote {} points ({} scene, seed {}) -> {} in {s:.2} s ({:.2} M points/s)",
        a.points,
        a.scene,
        a.seed,
        a.output.display(),
        a.points as f64 / s / 1e6
    );
    Ok(ExitCode::SUCCESS)
}
