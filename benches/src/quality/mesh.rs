//! Ground-truth meshes: the Stanford bunny (PLY), Spot with its texture (OBJ + PNG), and the
//! procedural shapes of the stability sweeps. Colour is per vertex, times the texture.

use anyhow::{Context, bail};
use glam::{Vec2, Vec3};
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Property};
use std::path::Path;

#[derive(Clone)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
}

impl Texture {
    pub fn white() -> Texture {
        Texture {
            width: 1,
            height: 1,
            rgba: vec![255; 4],
        }
    }

    pub fn load_png(path: &Path) -> anyhow::Result<Texture> {
        let file = std::fs::File::open(path).with_context(|| format!("{}", path.display()))?;
        let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
        decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
        let mut reader = decoder
            .read_info()
            .with_context(|| format!("{}: not a PNG", path.display()))?;
        let size = reader
            .output_buffer_size()
            .with_context(|| format!("{}: image too large", path.display()))?;
        let mut buf = vec![0; size];
        let info = reader
            .next_frame(&mut buf)
            .with_context(|| format!("{}: cannot decode", path.display()))?;
        let channels = info.color_type.samples();
        let rgba = buf[..info.buffer_size()]
            .chunks_exact(channels)
            .flat_map(|p| match channels {
                1 | 2 => [p[0], p[0], p[0], 255],
                _ => [p[0], p[1], p[2], 255],
            })
            .collect();
        Ok(Texture {
            width: info.width,
            height: info.height,
            rgba,
        })
    }

    /// Bilinear sample at `uv` (v up, as in OBJ), like the reference renderer's sampler.
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        let x = uv.x.rem_euclid(1.0) * self.width as f32 - 0.5;
        let y = (1.0 - uv.y).rem_euclid(1.0) * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (tx, ty) = (x - x0, y - y0);
        let texel = |xi: f32, yi: f32| {
            let xi = (xi as i64).clamp(0, self.width as i64 - 1) as usize;
            let yi = (yi as i64).clamp(0, self.height as i64 - 1) as usize;
            let o = (yi * self.width as usize + xi) * 4;
            Vec3::new(
                self.rgba[o] as f32,
                self.rgba[o + 1] as f32,
                self.rgba[o + 2] as f32,
            ) / 255.0
        };
        texel(x0, y0)
            .lerp(texel(x0 + 1.0, y0), tx)
            .lerp(texel(x0, y0 + 1.0).lerp(texel(x0 + 1.0, y0 + 1.0), tx), ty)
    }
}

#[derive(Clone)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    /// Albedo per vertex (0..1), multiplied by the texture.
    pub colours: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub texture: Texture,
}

impl Mesh {
    pub fn new() -> Mesh {
        Mesh {
            positions: Vec::new(),
            uvs: Vec::new(),
            colours: Vec::new(),
            triangles: Vec::new(),
            texture: Texture::white(),
        }
    }

    /// A PLY mesh (vertex x, y, z; face vertex_indices), in its vertex colours (red, green,
    /// blue: bytes, or floats in 0..1) where it has them, else in `colour`.
    pub fn load_ply(path: &Path, colour: Vec3) -> anyhow::Result<Mesh> {
        let mut file = std::fs::File::open(path).with_context(|| format!("{}", path.display()))?;
        let ply = Parser::<DefaultElement>::new()
            .read_ply(&mut file)
            .with_context(|| format!("{}: not a readable PLY mesh", path.display()))?;
        let scalar = |p: Option<&Property>| match p {
            Some(Property::Float(v)) => Some(*v),
            Some(Property::Double(v)) => Some(*v as f32),
            _ => None,
        };
        let mut mesh = Mesh::new();
        for v in ply.payload.get("vertex").into_iter().flatten() {
            let (Some(x), Some(y), Some(z)) =
                (scalar(v.get("x")), scalar(v.get("y")), scalar(v.get("z")))
            else {
                bail!("{}: a vertex lacks float x, y, z", path.display());
            };
            let channel = |name: &str| match v.get(name) {
                Some(Property::UChar(c)) => Some(f32::from(*c) / 255.0),
                Some(Property::UShort(c)) => Some(f32::from(*c) / 65535.0),
                p => scalar(p),
            };
            let rgb = match (channel("red"), channel("green"), channel("blue")) {
                (Some(r), Some(g), Some(b)) => Vec3::new(r, g, b).clamp(Vec3::ZERO, Vec3::ONE),
                _ => colour,
            };
            mesh.push_vertex(Vec3::new(x, y, z), Vec2::ZERO, rgb);
        }
        let n = mesh.positions.len() as u64;
        for f in ply.payload.get("face").into_iter().flatten() {
            let idx: Vec<u64> = match f.get("vertex_indices").or_else(|| f.get("vertex_index")) {
                Some(Property::ListInt(l)) => l.iter().map(|&i| i as u64).collect(),
                Some(Property::ListUInt(l)) => l.iter().map(|&i| i as u64).collect(),
                _ => bail!("{}: a face lacks integer vertex_indices", path.display()),
            };
            if idx.iter().any(|&i| i >= n) {
                bail!("{}: a face names a vertex past {n}", path.display());
            }
            for k in 1..idx.len().saturating_sub(1) {
                mesh.triangles
                    .push([idx[0] as u32, idx[k] as u32, idx[k + 1] as u32]);
            }
        }
        if mesh.triangles.is_empty() {
            bail!("{}: the mesh has no faces", path.display());
        }
        Ok(mesh)
    }

    /// An OBJ mesh with texture coordinates (v, vt, f with v/vt corners), textured by `texture`.
    pub fn load_obj(path: &Path, texture: Texture) -> anyhow::Result<Mesh> {
        let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
        let mut vs = Vec::new();
        let mut vts = Vec::new();
        let mut corners: std::collections::HashMap<(usize, usize), u32> = Default::default();
        let mut mesh = Mesh::new();
        for (line_no, line) in text.lines().enumerate() {
            let bad = || format!("{}: line {} is malformed", path.display(), line_no + 1);
            let mut parts = line.split_whitespace();
            let nums = |parts: std::str::SplitWhitespace| -> anyhow::Result<Vec<f32>> {
                parts.map(|p| p.parse::<f32>().with_context(bad)).collect()
            };
            match parts.next() {
                Some("v") => {
                    let n = nums(parts)?;
                    if n.len() < 3 {
                        bail!(bad());
                    }
                    vs.push(Vec3::new(n[0], n[1], n[2]));
                }
                Some("vt") => {
                    let n = nums(parts)?;
                    if n.len() < 2 {
                        bail!(bad());
                    }
                    vts.push(Vec2::new(n[0], n[1]));
                }
                Some("f") => {
                    let mut face = Vec::new();
                    for c in parts {
                        let mut it = c.split('/');
                        let v: usize = it.next().and_then(|s| s.parse().ok()).with_context(bad)?;
                        let t: usize = it.next().and_then(|s| s.parse().ok()).unwrap_or(0);
                        if v == 0 || v > vs.len() || t > vts.len() {
                            bail!(bad());
                        }
                        let id = *corners.entry((v, t)).or_insert_with(|| {
                            let uv = if t > 0 { vts[t - 1] } else { Vec2::ZERO };
                            mesh.push_vertex(vs[v - 1], uv, Vec3::ONE)
                        });
                        face.push(id);
                    }
                    for k in 1..face.len().saturating_sub(1) {
                        mesh.triangles.push([face[0], face[k], face[k + 1]]);
                    }
                }
                _ => {}
            }
        }
        if mesh.triangles.is_empty() {
            bail!("{}: the mesh has no faces", path.display());
        }
        mesh.texture = texture;
        Ok(mesh)
    }

    pub fn push_vertex(&mut self, p: Vec3, uv: Vec2, colour: Vec3) -> u32 {
        self.positions.push(p);
        self.uvs.push(uv);
        self.colours.push(colour);
        self.positions.len() as u32 - 1
    }

    /// Adds `other`'s triangles (its texture is dropped: join untextured parts only).
    pub fn append(&mut self, other: &Mesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.uvs.extend_from_slice(&other.uvs);
        self.colours.extend_from_slice(&other.colours);
        self.triangles
            .extend(other.triangles.iter().map(|t| t.map(|i| i + base)));
    }

    pub fn map_positions(&mut self, f: impl Fn(Vec3) -> Vec3) {
        for p in &mut self.positions {
            *p = f(*p);
        }
    }

    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.positions.iter().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        )
    }

    pub fn corners(&self, t: [u32; 3]) -> [Vec3; 3] {
        t.map(|i| self.positions[i as usize])
    }

    pub fn area(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| triangle_area(self.corners(*t)) as f64)
            .sum()
    }

    /// Area-weighted vertex normals.
    pub fn vertex_normals(&self) -> Vec<Vec3> {
        let mut n = vec![Vec3::ZERO; self.positions.len()];
        for t in &self.triangles {
            let [a, b, c] = self.corners(*t);
            let face = (b - a).cross(c - a);
            for i in t {
                n[*i as usize] += face;
            }
        }
        n.into_iter().map(|v| v.normalize_or_zero()).collect()
    }

    /// Albedo at barycentric `w` of triangle `t`.
    pub fn albedo(&self, t: [u32; 3], w: Vec3) -> Vec3 {
        let [a, b, c] = t.map(|i| i as usize);
        let colour = self.colours[a] * w.x + self.colours[b] * w.y + self.colours[c] * w.z;
        let uv = self.uvs[a] * w.x + self.uvs[b] * w.y + self.uvs[c] * w.z;
        colour * self.texture.sample(uv)
    }
}

impl Default for Mesh {
    fn default() -> Mesh {
        Mesh::new()
    }
}

pub fn triangle_area([a, b, c]: [Vec3; 3]) -> f32 {
    (b - a).cross(c - a).length() * 0.5
}

/// Scanned models are y-up; Strata's world is z-up.
pub fn y_up_to_z_up(p: Vec3) -> Vec3 {
    Vec3::new(p.x, -p.z, p.y)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ply(dir: &Path, name: &str, colour: &str, values: [&str; 3]) -> std::path::PathBuf {
        let path = dir.join(name);
        let vertex = |x: &str| {
            format!(
                "{x}{}\n",
                if colour.is_empty() {
                    String::new()
                } else {
                    format!(" {}", values.join(" "))
                }
            )
        };
        let text = format!(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n{colour}element face 1\nproperty list uchar int vertex_indices\nend_header\n{}{}{}3 0 1 2\n",
            vertex("0 0 0"),
            vertex("1 0 0"),
            vertex("0 1 0"),
        );
        std::fs::write(&path, text).expect("write");
        path
    }

    #[test]
    fn a_ply_mesh_keeps_its_vertex_colours() {
        let dir = tempfile::tempdir().expect("tempdir");
        let bytes = "property uchar red\nproperty uchar green\nproperty uchar blue\n";
        let floats = "property float red\nproperty float green\nproperty float blue\n";
        let clay = Vec3::new(0.8, 0.7, 0.6);
        let red = Mesh::load_ply(&ply(dir.path(), "b.ply", bytes, ["255", "0", "51"]), clay)
            .expect("loads");
        assert_eq!(red.colours, vec![Vec3::new(1.0, 0.0, 0.2); 3]);
        let half = Mesh::load_ply(
            &ply(dir.path(), "f.ply", floats, ["0.5", "0.5", "0.5"]),
            clay,
        )
        .expect("loads");
        assert_eq!(half.colours, vec![Vec3::splat(0.5); 3]);
        let plain =
            Mesh::load_ply(&ply(dir.path(), "p.ply", "", ["", "", ""]), clay).expect("loads");
        assert_eq!(plain.colours, vec![clay; 3]);
    }
}
