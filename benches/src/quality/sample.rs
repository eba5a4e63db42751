//! Point sets for the harness: a mesh sampled at a density given in points per screen pixel,
//! with optional Gaussian noise, and the real bunny scans; written as binary PLY for `convert`.

use super::mesh::Mesh;
use anyhow::{Context, bail};
use glam::Vec3;
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Property};
use std::io::Write;
use std::path::Path;
use strata_converter::synth::Rng;

pub struct PointSet {
    pub positions: Vec<Vec3>,
    /// Albedo, 0..1.
    pub colours: Vec<Vec3>,
    /// Unit normals, as a scanner that records them gives them (empty: none; the
    /// conversion estimates them).
    pub normals: Vec<Vec3>,
}

/// Samples `mesh` uniformly in screen space as seen from `eye` (focal length `focal_px`):
/// `density` points per pixel of a surface facing the eye, so a triangle gets points in
/// proportion to its area over its squared distance. Noise is isotropic Gaussian with standard
/// deviation `sigma`. At most `max_points`.
pub fn sample_mesh(
    mesh: &Mesh,
    eye: Vec3,
    focal_px: f32,
    density: f64,
    sigma: f32,
    seed: u64,
    max_points: usize,
) -> PointSet {
    let mut cdf = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0f64;
    for t in &mesh.triangles {
        let c = mesh.corners(*t);
        let centroid = (c[0] + c[1] + c[2]) / 3.0;
        let px_per_unit = focal_px as f64 / (centroid - eye).length().max(1e-6) as f64;
        total += super::mesh::triangle_area(c) as f64 * px_per_unit * px_per_unit;
        cdf.push(total);
    }
    let n = ((density * total).round() as usize).clamp(1, max_points);
    let vertex_normals = mesh.vertex_normals();
    let mut rng = Rng::new(seed, 0x5a3e, n as u64);
    let mut out = PointSet {
        positions: Vec::with_capacity(n),
        colours: Vec::with_capacity(n),
        normals: Vec::with_capacity(n),
    };
    for _ in 0..n {
        let pick = rng.unit() * total;
        let ti = cdf.partition_point(|&c| c <= pick).min(cdf.len() - 1);
        let t = mesh.triangles[ti];
        let (mut u, mut v) = (rng.unit() as f32, rng.unit() as f32);
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        let w = Vec3::new(1.0 - u - v, u, v);
        let [a, b, c] = mesh.corners(t);
        let mut p = a * w.x + b * w.y + c * w.z;
        if sigma > 0.0 {
            let (x, y, z) = (rng.gaussian(), rng.gaussian(), rng.gaussian());
            p += Vec3::new(x as f32, y as f32, z as f32) * sigma;
        }
        out.positions.push(p);
        out.colours.push(mesh.albedo(t, w));
        // The vertex normals interpolated as the reference shades the mesh (the face's own
        // normal differs from the reference's by 4 to 5° on average on the bunny and Spot),
        // else the face's, by its winding (outward on the harness's meshes).
        let [na, nb, nc] = t.map(|i| vertex_normals[i as usize]);
        let face = (b - a).cross(c - a).normalize_or_zero();
        out.normals
            .push((na * w.x + nb * w.y + nc * w.z).normalize_or(face));
    }
    out
}

/// Keeps each point with probability `ratio`^-t, t running from 0 at the set's smallest x to 1
/// at its largest: the density falls smoothly by `ratio` across the object (paper 001's stated
/// limitation, holes where sampling is uneven).
pub fn thin_along_x(set: PointSet, ratio: f64, seed: u64) -> PointSet {
    let (lo, hi) = set
        .positions
        .iter()
        .fold((f32::MAX, f32::MIN), |(lo, hi), p| {
            (lo.min(p.x), hi.max(p.x))
        });
    let span = (hi - lo).max(1e-9) as f64;
    let mut rng = Rng::new(seed, 0x7b1d, set.positions.len() as u64);
    let mut out = PointSet {
        positions: Vec::new(),
        colours: Vec::new(),
        normals: Vec::new(),
    };
    for i in 0..set.positions.len() {
        let t = (set.positions[i].x - lo) as f64 / span;
        if rng.unit() < ratio.powf(-t) {
            out.positions.push(set.positions[i]);
            out.colours.push(set.colours[i]);
            if let Some(n) = set.normals.get(i) {
                out.normals.push(*n);
            }
        }
    }
    out
}

/// The x, y, z of a PLY point cloud, mapped by `map`, all in one colour.
pub fn load_scan(
    path: &Path,
    map: impl Fn(Vec3) -> Vec3,
    colour: Vec3,
) -> anyhow::Result<PointSet> {
    let mut file = std::fs::File::open(path).with_context(|| format!("{}", path.display()))?;
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut file)
        .with_context(|| format!("{}: not a readable PLY", path.display()))?;
    let scalar = |p: Option<&Property>| match p {
        Some(Property::Float(v)) => Some(*v),
        Some(Property::Double(v)) => Some(*v as f32),
        _ => None,
    };
    let mut positions = Vec::new();
    for v in ply.payload.get("vertex").into_iter().flatten() {
        let (Some(x), Some(y), Some(z)) =
            (scalar(v.get("x")), scalar(v.get("y")), scalar(v.get("z")))
        else {
            bail!("{}: a vertex lacks float x, y, z", path.display());
        };
        positions.push(map(Vec3::new(x, y, z)));
    }
    let colours = vec![colour; positions.len()];
    Ok(PointSet {
        positions,
        colours,
        normals: Vec::new(),
    })
}

/// Binary little-endian PLY: x, y, z as float, red, green, blue as uchar, then nx, ny, nz as
/// float where the set has normals.
pub fn write_ply(path: &Path, points: &PointSet) -> anyhow::Result<()> {
    let file = std::fs::File::create(path).with_context(|| format!("{}", path.display()))?;
    let mut w = std::io::BufWriter::new(file);
    let with_normals = points.normals.len() == points.positions.len();
    write!(
        w,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n{}end_header\n",
        points.positions.len(),
        if with_normals {
            "property float nx\nproperty float ny\nproperty float nz\n"
        } else {
            ""
        }
    )?;
    for (i, (p, c)) in points.positions.iter().zip(&points.colours).enumerate() {
        for v in p.to_array() {
            w.write_all(&v.to_le_bytes())?;
        }
        let rgb = (*c * 255.0).round().clamp(Vec3::ZERO, Vec3::splat(255.0));
        w.write_all(&[rgb.x as u8, rgb.y as u8, rgb.z as u8])?;
        if with_normals {
            for v in points.normals[i].to_array() {
                w.write_all(&v.to_le_bytes())?;
            }
        }
    }
    w.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    #[test]
    fn sampled_normals_are_the_interpolated_vertex_normals() {
        // A tent of two triangles folded by 90° along their shared edge (x = 0): the vertex
        // normals on the edge are the faces' mean, so a point's normal turns from its face's
        // towards the other's as it nears the edge, as the reference shades it.
        let mut mesh = Mesh::new();
        for p in [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(-1.0, 0.5, -1.0),
            Vec3::new(1.0, 0.5, -1.0),
        ] {
            mesh.push_vertex(p, Vec2::ZERO, Vec3::ONE);
        }
        mesh.triangles = vec![[0, 2, 1], [0, 1, 3]];
        let set = sample_mesh(&mesh, Vec3::new(0.0, 0.5, 5.0), 100.0, 1.0, 0.0, 3, 2000);
        let faces = mesh
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = mesh.corners(*t);
                (b - a).cross(c - a).normalize()
            })
            .collect::<Vec<_>>();
        let mut turned = 0;
        for (p, n) in set.positions.iter().zip(&set.normals) {
            assert!((n.length() - 1.0).abs() < 1e-5);
            let face = if p.x < 0.0 { faces[0] } else { faces[1] };
            // Between its face's normal and the mean of both (45° apart).
            let from_face = n.dot(face).clamp(-1.0, 1.0).acos().to_degrees();
            assert!(from_face <= 45.01, "{from_face}° at {p:?}");
            turned += usize::from(from_face > 1.0);
        }
        assert!(turned > set.positions.len() / 2, "{turned}");
    }
}
