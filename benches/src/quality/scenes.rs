//! The scenes the harness renders: each a ground-truth mesh, where its points come from, and
//! the views to judge it from.

use super::cli::UserMesh;
use super::mesh::{Mesh, Texture, y_up_to_z_up};
use super::shapes::{cuboid, plane, sphere};
use anyhow::{Context, bail};
use glam::Vec3;
use std::path::{Path, PathBuf};

/// Light clay, for meshes without a texture.
pub const CLAY: Vec3 = Vec3::new(0.85, 0.78, 0.66);

pub enum Points {
    /// The mesh sampled at each density and noise of the sweep.
    Sampled,
    /// A real scan of the mesh's object (PLY x, y, z in the mesh's frame).
    Scan(PathBuf),
    /// Sampled, then thinned so that the density falls by this factor across the object.
    Gradient(f64),
}

pub struct View {
    pub eye: Vec3,
    pub target: Vec3,
    pub fov_deg: f32,
}

pub struct Scene {
    pub name: String,
    pub mesh: Mesh,
    pub points: Points,
    pub views: Vec<View>,
    /// Whether the scene belongs to the stability sweeps (fewer densities and noises).
    pub stability: bool,
}

/// Views from around and above, each framing the bounding sphere.
fn orbit(mesh: &Mesh, directions: &[Vec3], fov_deg: f32) -> Vec<View> {
    let (lo, hi) = mesh.bounds();
    let centre = (lo + hi) * 0.5;
    let radius = (hi - lo).length() * 0.5;
    let distance = radius / (fov_deg.to_radians() * 0.5).sin() * 0.95;
    directions
        .iter()
        .map(|d| View {
            eye: centre + d.normalize() * distance,
            target: centre,
            fov_deg,
        })
        .collect()
}

const ORBIT: [Vec3; 3] = [
    Vec3::new(0.15, -1.0, 0.25),
    Vec3::new(1.0, -0.6, 0.45),
    Vec3::new(-0.9, -0.4, 0.2),
];

pub fn bunny_mesh(data: &Path) -> anyhow::Result<Mesh> {
    let mut m = Mesh::load_ply(&data.join("bunny_bun_zipper.ply"), CLAY)?;
    m.map_positions(y_up_to_z_up);
    Ok(m)
}

pub fn spot_mesh(data: &Path) -> anyhow::Result<Mesh> {
    let texture = Texture::load_png(&data.join("spot_texture.png"))?;
    let mut m = Mesh::load_obj(&data.join("spot_triangulated.obj"), texture)?;
    m.map_positions(y_up_to_z_up);
    Ok(m)
}

/// The scenes of one run. `quick` keeps one view per scene and a subset of the sweeps.
pub fn scenes(data: &Path, quick: bool) -> anyhow::Result<Vec<Scene>> {
    let views = |m: &Mesh| {
        let n = if quick { 1 } else { ORBIT.len() };
        orbit(m, &ORBIT[..n], 40.0)
    };
    let bunny = bunny_mesh(data)?;
    let spot = spot_mesh(data)?;
    let mut out = vec![
        Scene {
            name: "bunny_scans".into(),
            views: views(&bunny),
            mesh: bunny.clone(),
            points: Points::Scan(data.join("bunny_range_scans_merged.ply")),
            stability: false,
        },
        Scene {
            name: "bunny".into(),
            views: views(&bunny),
            mesh: bunny,
            points: Points::Sampled,
            stability: false,
        },
        Scene {
            name: "spot".into(),
            views: views(&spot),
            mesh: spot,
            points: Points::Sampled,
            stability: false,
        },
    ];
    out.extend(stability_scenes(quick));
    Ok(out)
}

/// A mesh of the user's own: a PLY in one colour or an OBJ with its texture, turned to z up
/// where it has y up.
pub fn load_user_mesh(m: &UserMesh) -> anyhow::Result<Mesh> {
    let ext = m
        .path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let mut mesh = match (ext.as_deref(), &m.texture) {
        (Some("ply"), None) => Mesh::load_ply(&m.path, CLAY)?,
        (Some("ply"), Some(_)) => bail!(
            "--mesh {}: a texture needs an OBJ's texture coordinates",
            m.path.display()
        ),
        (Some("obj"), texture) => {
            let texture = match texture {
                Some(t) => Texture::load_png(t)?,
                None => Texture::white(),
            };
            Mesh::load_obj(&m.path, texture)?
        }
        _ => bail!("--mesh {}: not a .ply or .obj file", m.path.display()),
    };
    if m.y_up {
        mesh.map_positions(y_up_to_z_up);
    }
    let (lo, hi) = mesh.bounds();
    if !(hi - lo).is_finite() || (hi - lo).length() <= 0.0 {
        bail!("--mesh {}: the mesh has no extent", m.path.display());
    }
    Ok(mesh)
}

/// A scene of the user's own mesh, sampled and viewed as the bunny and Spot are, named by its
/// file's stem.
pub fn user_scene(m: &UserMesh, quick: bool) -> anyhow::Result<Scene> {
    let mesh = load_user_mesh(m)?;
    let name = m
        .path
        .file_stem()
        .and_then(|s| s.to_str())
        .context("--mesh: the file needs a name")?
        .to_string();
    let n = if quick { 1 } else { ORBIT.len() };
    Ok(Scene {
        name,
        views: orbit(&mesh, &ORBIT[..n], 40.0),
        mesh,
        points: Points::Sampled,
        stability: false,
    })
}

fn stability_scenes(quick: bool) -> Vec<Scene> {
    let mut out = Vec::new();
    // A unit plane seen ever closer to edge-on.
    let angles: &[f32] = if quick {
        &[85.0]
    } else {
        &[70.0, 80.0, 85.0, 88.0]
    };
    for &angle in angles {
        let mesh = plane(
            Vec3::new(-0.5, -0.5, 0.0),
            Vec3::X,
            Vec3::Y,
            32,
            Vec3::new(0.9, 0.8, 0.5),
        );
        let a = angle.to_radians();
        let eye = Vec3::new(0.0, -a.sin(), a.cos()) * 1.3;
        out.push(Scene {
            name: format!("grazing_{angle:.0}deg"),
            mesh,
            points: Points::Sampled,
            views: vec![View {
                eye,
                target: Vec3::ZERO,
                fov_deg: 40.0,
            }],
            stability: true,
        });
    }
    // Thin fins, one percent of their height thick.
    let mut fins = Mesh::new();
    for k in 0..3 {
        let x = -0.4 + 0.4 * k as f32;
        fins.append(&cuboid(
            Vec3::new(x, -0.3, 0.0),
            Vec3::new(x + 0.006, 0.3, 0.6),
            Vec3::new(0.7, 0.8, 0.9),
        ));
    }
    fins.append(&plane(
        Vec3::new(-0.6, -0.5, 0.0),
        Vec3::X * 1.2,
        Vec3::Y * 1.0,
        16,
        Vec3::new(0.6, 0.7, 0.5),
    ));
    out.push(Scene {
        name: "thin".into(),
        views: orbit(&fins, &[Vec3::new(0.8, -1.0, 0.5)], 40.0),
        mesh: fins,
        points: Points::Sampled,
        stability: true,
    });
    // A small panel a metre from the eye in front of a wall thirty metres away.
    let mut near_far = plane(
        Vec3::new(-15.0, 30.0, -10.0),
        Vec3::X * 30.0,
        Vec3::Z * 20.0,
        32,
        Vec3::new(0.8, 0.7, 0.6),
    );
    near_far.append(&plane(
        Vec3::new(-0.25, 1.0, -0.2),
        Vec3::X * 0.4,
        Vec3::Z * 0.3,
        8,
        Vec3::new(0.5, 0.7, 0.9),
    ));
    out.push(Scene {
        name: "near_far".into(),
        mesh: near_far,
        points: Points::Sampled,
        views: vec![View {
            eye: Vec3::ZERO,
            target: Vec3::new(0.0, 1.0, 0.0),
            fov_deg: 60.0,
        }],
        stability: true,
    });
    // A smooth ball whose sampling thins out sixteenfold from one side to the other.
    let ball = sphere(Vec3::ZERO, 1.0, 64, Vec3::new(0.75, 0.8, 0.9));
    out.push(Scene {
        name: "gradient".into(),
        views: orbit(&ball, &[Vec3::new(0.0, -1.0, 0.3)], 40.0),
        mesh: ball,
        points: Points::Gradient(16.0),
        stability: true,
    });
    // A ball inside a ball: nothing of the inner one may show.
    let mut nested = sphere(Vec3::ZERO, 1.0, 24, Vec3::new(0.8, 0.8, 0.7));
    nested.append(&sphere(Vec3::ZERO, 0.7, 24, Vec3::new(0.9, 0.2, 0.2)));
    out.push(Scene {
        name: "nested".into(),
        views: orbit(&nested, &[Vec3::new(0.3, -1.0, 0.4)], 40.0),
        mesh: nested,
        points: Points::Sampled,
        stability: true,
    });
    // A ball over a floor, for shadows (the lights are the harness's SHADOW_LIGHT and
    // GRAZING_LIGHT); the floor reaches far enough behind the ball for the long shadow of the
    // grazing light to fall on it in view.
    let mut shadow = plane(
        Vec3::new(-2.5, -1.5, 0.0),
        Vec3::X * 5.0,
        Vec3::Y * 5.5,
        24,
        Vec3::new(0.8, 0.75, 0.7),
    );
    shadow.append(&sphere(
        Vec3::new(0.0, 0.0, 0.6),
        0.35,
        24,
        Vec3::new(0.3, 0.5, 0.8),
    ));
    out.push(Scene {
        name: "shadow".into(),
        views: vec![View {
            eye: Vec3::new(0.3, -3.2, 2.6),
            target: Vec3::new(0.0, 0.0, 0.2),
            fov_deg: 40.0,
        }],
        mesh: shadow,
        points: Points::Sampled,
        stability: true,
    });
    // Three nested spheres of different colours, for transparency (paper 004's Figure 17).
    let mut layers = sphere(Vec3::ZERO, 1.0, 32, Vec3::new(0.2, 0.35, 0.85));
    layers.append(&sphere(Vec3::ZERO, 0.7, 32, Vec3::new(0.2, 0.75, 0.3)));
    layers.append(&sphere(Vec3::ZERO, 0.4, 32, Vec3::new(0.6, 0.4, 0.2)));
    out.push(Scene {
        name: "layers".into(),
        views: orbit(&layers, &[Vec3::new(0.2, -1.0, 0.3)], 40.0),
        mesh: layers,
        points: Points::Sampled,
        stability: true,
    });
    out
}
