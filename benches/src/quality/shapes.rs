//! Procedural meshes for the stability sweeps: planes, boxes and spheres.

use super::mesh::Mesh;
use glam::{Vec2, Vec3};

/// A grid of `n` x `n` quads spanning `origin + s * u + t * v` for s, t in [0, 1], coloured
/// by a soft checker pattern so that colour errors show.
pub fn plane(origin: Vec3, u: Vec3, v: Vec3, n: u32, colour: Vec3) -> Mesh {
    let mut m = Mesh::new();
    for j in 0..=n {
        for i in 0..=n {
            let (s, t) = (i as f32 / n as f32, j as f32 / n as f32);
            let checker = ((s * 8.0).floor() + (t * 8.0).floor()) as i32 % 2 == 0;
            let c = if checker { colour } else { colour * 0.6 };
            m.push_vertex(origin + u * s + v * t, Vec2::new(s, t), c);
        }
    }
    let row = n + 1;
    for j in 0..n {
        for i in 0..n {
            let a = j * row + i;
            m.triangles.push([a, a + 1, a + row + 1]);
            m.triangles.push([a, a + row + 1, a + row]);
        }
    }
    m
}

/// An axis-aligned box from its six faces.
pub fn cuboid(min: Vec3, max: Vec3, colour: Vec3) -> Mesh {
    let d = max - min;
    let (x, y, z) = (Vec3::X * d.x, Vec3::Y * d.y, Vec3::Z * d.z);
    let mut m = Mesh::new();
    for face in [
        plane(min, y, x, 4, colour),
        plane(min + z, x, y, 4, colour),
        plane(min, x, z, 4, colour),
        plane(min + y, z, x, 4, colour),
        plane(min, z, y, 4, colour),
        plane(min + x, y, z, 4, colour),
    ] {
        m.append(&face);
    }
    m
}

/// A UV sphere.
pub fn sphere(centre: Vec3, radius: f32, rings: u32, colour: Vec3) -> Mesh {
    let mut m = Mesh::new();
    let segments = rings * 2;
    for r in 0..=rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..=segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            let dir = Vec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            );
            let band = (r / 2 + s / 4) % 2 == 0;
            let c = if band { colour } else { colour * 0.7 };
            m.push_vertex(centre + dir * radius, Vec2::ZERO, c);
        }
    }
    let row = segments + 1;
    for r in 0..rings {
        for s in 0..segments {
            let a = r * row + s;
            m.triangles.push([a, a + row, a + row + 1]);
            m.triangles.push([a, a + row + 1, a + 1]);
        }
    }
    m
}
