//! Accuracy of `strata convert --normals` against ground truth: the bunny and spot meshes (and
//! any given with `--mesh`) sampled uniformly over their area, without noise and at the quality harness's two noise
//! levels, each point carrying the normal of the triangle it came from. The points go
//! through the real conversion; the normals are read back from the dataset.
//!
//! Options: `USAGE` below, or `--help`. Speed is measured by `convert-bench --normals`.

use anyhow::{Context, bail};
use glam::Vec3;
use std::io::Write;
use std::path::{Path, PathBuf};
use strata_bench::quality::cli::UserMesh;
use strata_bench::quality::mesh::{Mesh, triangle_area};
use strata_bench::quality::scenes::{bunny_mesh, load_user_mesh, spot_mesh};
use strata_converter::synth::Rng;
use strata_converter::{ConvertOptions, NormalOptions, NormalStep, Orient, Sampling, convert_with};
use strata_format::{AttrType, LocalDataset, oct16_decode};

const USAGE: &str = "cargo run --release -p strata-bench --bin normals-bench -- [--points 200000]\n    \
       [--k 16] [--data ../shared/data] [--dir DIR] [--csv FILE] [--mesh FILE.ply|FILE.obj ...]\n    \
       [--y-up] [--only-meshes]";

/// The quality harness's noise levels, as a share of the bounding diagonal.
const NOISES: [f64; 3] = [0.0, 0.002, 0.005];

struct Sampled {
    positions: Vec<Vec3>,
    /// The unit normal of each point's triangle: exact for the surface the points lie on (a
    /// mesh of flat triangles), so the error is the estimate's own, mostly where a
    /// neighbourhood straddles an edge between triangles.
    truth: Vec<Vec3>,
}

fn sample(mesh: &Mesh, n: usize, sigma: f32, seed: u64) -> Sampled {
    let mut cdf = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0f64;
    for t in &mesh.triangles {
        total += triangle_area(mesh.corners(*t)) as f64;
        cdf.push(total);
    }
    let mut rng = Rng::new(seed, 0x9e37, n as u64);
    let mut out = Sampled {
        positions: Vec::with_capacity(n),
        truth: Vec::with_capacity(n),
    };
    while out.positions.len() < n {
        let pick = rng.unit() * total;
        let ti = cdf.partition_point(|&c| c <= pick).min(cdf.len() - 1);
        let t = mesh.triangles[ti];
        let [a, b, c] = mesh.corners(t);
        let (mut u, mut v) = (rng.unit() as f32, rng.unit() as f32);
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let normal = (b - a).cross(c - a).normalize_or_zero();
        if normal == Vec3::ZERO {
            continue;
        }
        let mut p = a * (1.0 - u - v) + b * u + c * v;
        if sigma > 0.0 {
            let g = [rng.gaussian(), rng.gaussian(), rng.gaussian()];
            p += Vec3::new(g[0] as f32, g[1] as f32, g[2] as f32) * sigma;
        }
        out.positions.push(p);
        out.truth.push(normal);
    }
    out
}

/// Binary PLY: x y z and the true normal as `true_nx true_ny true_nz` (extra attributes the
/// converter carries through; `nx ny nz` would be taken as input normals).
fn write_ply(path: &Path, s: &Sampled) -> anyhow::Result<()> {
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float true_nx\nproperty float true_ny\nproperty float true_nz\nend_header\n",
        s.positions.len()
    )
    .into_bytes();
    for (p, n) in s.positions.iter().zip(&s.truth) {
        for v in [p.x, p.y, p.z, n.x, n.y, n.z] {
            bytes.extend(v.to_le_bytes());
        }
    }
    std::fs::File::create(path)
        .and_then(|mut f| f.write_all(&bytes))
        .with_context(|| format!("cannot write {}", path.display()))
}

/// (estimated, true) normal of every point of a dataset.
fn read_back(dir: &Path) -> anyhow::Result<Vec<([f64; 3], [f64; 3])>> {
    let ds = LocalDataset::open(dir)?;
    let layout = ds.layout().clone();
    let index = |n: &str| layout.index_of(n).with_context(|| format!("no {n}"));
    let n_at = index("normal")?;
    let t_at = [index("true_nx")?, index("true_ny")?, index("true_nz")?];
    let mut out = Vec::new();
    for node in ds.all_nodes()? {
        if node.point_count == 0 {
            continue;
        }
        let cols = ds.read_node(&node)?;
        let nc = cols.attribute(&layout, n_at);
        let tc = t_at.map(|a| cols.attribute(&layout, a));
        for i in 0..node.point_count as usize {
            let raw = [
                u16::from_le_bytes([nc[4 * i], nc[4 * i + 1]]),
                u16::from_le_bytes([nc[4 * i + 2], nc[4 * i + 3]]),
            ];
            let n = oct16_decode(raw).context("a point without a normal")?;
            let t = tc.map(|c| AttrType::F32.read_f64(&c[4 * i..]));
            out.push((n, t));
        }
    }
    Ok(out)
}

fn angle(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d: f64 = (0..3).map(|i| a[i] * b[i]).sum();
    d.clamp(-1.0, 1.0).acos().to_degrees()
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn convert(input: &Path, output: &Path, orient: Orient, k: usize) -> anyhow::Result<()> {
    let step = NormalStep::new(NormalOptions {
        k,
        orient,
        ..NormalOptions::default()
    })?;
    convert_with(
        &ConvertOptions {
            inputs: vec![input.to_path_buf()],
            output: output.to_path_buf(),
            memory_limit: 1 << 30,
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
            sampling: Sampling::Poisson,
            overwrite: true,
            resume: false,
            quiet: true,
            temp_dir: None,
        },
        &step,
    )?;
    Ok(())
}

fn main() -> anyhow::Result<()> {
    if strata_bench::answered_help(USAGE) {
        return Ok(());
    }
    let mut points = 200_000usize;
    let mut k = 16usize;
    let mut data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data");
    let mut dir = PathBuf::from("target/bench-data/normals");
    let mut csv = None;
    let (mut meshes, mut y_up, mut only_meshes) = (Vec::new(), false, false);
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--y-up" => {
                y_up = true;
                continue;
            }
            "--only-meshes" => {
                only_meshes = true;
                continue;
            }
            _ => {}
        }
        let v = it.next().with_context(|| format!("{a} needs a value"))?;
        match a.as_str() {
            "--mesh" => meshes.push(PathBuf::from(v)),
            "--points" => points = strata_bench::parse_count(v)? as usize,
            "--k" => k = v.parse().context("--k needs a count")?,
            "--data" => data = PathBuf::from(v),
            "--dir" => dir = PathBuf::from(v),
            "--csv" => csv = Some(PathBuf::from(v)),
            _ => bail!("unknown option {a}"),
        }
    }
    std::fs::create_dir_all(&dir)?;
    println!("conditions: {points} points per mesh sampled uniformly over its area, k = {k}");
    println!(
        "| mesh | noise (x diagonal) | median error | 95th percentile | share facing against the outward normal, --orient up |"
    );
    println!("|---|---|---|---|---|");
    let mut table = String::from("mesh,noise,median_deg,p95_deg,wrong_side_up\n");
    let mut all = Vec::new();
    if !only_meshes {
        all.push(("bunny".to_string(), bunny_mesh(&data)?));
        all.push(("spot".to_string(), spot_mesh(&data)?));
    }
    for path in meshes {
        let name = path
            .file_stem()
            .and_then(|s| s.to_str())
            .context("--mesh: the file needs a name")?
            .to_string();
        let m = UserMesh {
            path,
            texture: None,
            y_up,
        };
        all.push((name, load_user_mesh(&m)?));
    }
    for (name, mesh) in all {
        let (lo, hi) = mesh.bounds();
        let diagonal = (hi - lo).length();
        for noise in NOISES {
            let set = sample(&mesh, points, noise as f32 * diagonal, 11);
            let ply = dir.join(format!("{name}_{noise}.ply"));
            write_ply(&ply, &set)?;
            let out = dir.join(format!("{name}_{noise}_none"));
            convert(&ply, &out, Orient::None, k)?;
            let mut errors: Vec<f64> = read_back(&out)?
                .into_iter()
                .map(|(n, t)| angle(n, t).min(180.0 - angle(n, t)))
                .collect();
            errors.sort_by(f64::total_cmp);
            let out_up = dir.join(format!("{name}_{noise}_up"));
            convert(&ply, &out_up, Orient::Up, k)?;
            let up = read_back(&out_up)?;
            let wrong =
                up.iter().filter(|(n, t)| angle(*n, *t) > 90.0).count() as f64 / up.len() as f64;
            let (median, p95) = (percentile(&errors, 0.5), percentile(&errors, 0.95));
            println!(
                "| {name} | {noise} | {median:.2}° | {p95:.2}° | {:.1}% |",
                wrong * 100.0
            );
            table.push_str(&format!("{name},{noise},{median},{p95},{wrong}\n"));
            for d in [out, out_up] {
                let _ = std::fs::remove_dir_all(d);
            }
            let _ = std::fs::remove_file(ply);
        }
    }
    if let Some(path) = csv {
        std::fs::write(&path, table).with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(())
}
