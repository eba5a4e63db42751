//! The reference of point shadows (paper 004, section 6): which of the mesh's visible surface
//! pixels a directional light reaches, by a ray from each towards the light against every
//! triangle; the mesh's picture with those shadows; and the scores of a shadowed frame's lit or
//! shadowed states against them.

use super::mesh::Mesh;
use glam::{DVec3, Mat4, Vec3};
use strata_viewer::pipelines::LIGHTING_WGSL;

/// Pixels whose surface turns from the light by less than this cosine are not scored: their
/// light is ambient alone, shadowed or not.
const MIN_LIGHT_COSINE: f32 = 0.1;

/// The ambient share of the shared lighting (`AMBIENT` in lighting.wgsl): a shadowed pixel's
/// colour is its albedo times this.
pub fn ambient() -> f32 {
    LIGHTING_WGSL
        .lines()
        .find_map(|l| l.trim().strip_prefix("const AMBIENT: f32 = "))
        .and_then(|v| v.trim_end_matches(';').parse().ok())
        .unwrap_or(0.25)
}

/// Per pixel of the reference surface (view-space normal facing the eye and linear depth):
/// whether the light in world direction `light` reaches it; `None` on background and where the
/// surface turns away from the light. `view` is the camera's, `offset` the dataset's anchor.
pub fn lit_by_mesh(
    mesh: &Mesh,
    offset: DVec3,
    view: Mat4,
    tan_half: [f32; 2],
    size: (u32, u32),
    surface: &[Option<([f32; 3], f32)>],
    light: Vec3,
) -> Vec<Option<bool>> {
    let triangles: Vec<[Vec3; 3]> = mesh
        .triangles
        .iter()
        .map(|t| mesh.corners(*t).map(|c| (c.as_dvec3() - offset).as_vec3()))
        .collect();
    let (lo, hi) = mesh.bounds();
    let lift = (hi - lo).length() * 1e-3;
    let to_world = view.inverse();
    let l = light.normalize();
    let (w, h) = (size.0 as usize, size.1 as usize);
    let pixel = |i: usize| -> Option<bool> {
        let (n_view, depth) = surface[i]?;
        let (x, y) = ((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
        let ndc = [x / w as f32 * 2.0 - 1.0, 1.0 - y / h as f32 * 2.0];
        let p_view = Vec3::new(ndc[0] * tan_half[0], ndc[1] * tan_half[1], -1.0) * depth;
        let p = to_world.transform_point3(p_view);
        let n = to_world
            .transform_vector3(Vec3::from_array(n_view))
            .normalize();
        if n.dot(l) < MIN_LIGHT_COSINE {
            return None;
        }
        let origin = p + n * lift;
        Some(!triangles.iter().any(|t| hits(origin, l, t)))
    };
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let chunk = (w * h).div_ceil(threads).max(1);
    let mut out = vec![None; w * h];
    std::thread::scope(|s| {
        for (k, part) in out.chunks_mut(chunk).enumerate() {
            let pixel = &pixel;
            s.spawn(move || {
                for (j, v) in part.iter_mut().enumerate() {
                    *v = pixel(k * chunk + j);
                }
            });
        }
    });
    out
}

/// Whether the ray from `o` along `d` meets triangle `t` in front of `o` (Möller–Trumbore).
fn hits(o: Vec3, d: Vec3, [a, b, c]: &[Vec3; 3]) -> bool {
    let (e1, e2) = (*b - *a, *c - *a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-12 {
        return false;
    }
    let inv = 1.0 / det;
    let s = o - *a;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    e2.dot(q) * inv > 0.0
}

/// The mesh lit from the light (`lit`: its picture unshadowed, `albedo` its unlit colour) with
/// its shadows: where the light does not reach, the ambient term alone (the shared Blinn-Phong
/// with nothing of the light arriving), as a shadowed point is lit.
pub fn shadowed_reference(lit: &[u8], albedo: &[u8], reached: &[Option<bool>]) -> Vec<u8> {
    let ambient = ambient();
    let mut out = lit.to_vec();
    for (i, _) in reached
        .iter()
        .enumerate()
        .filter(|(_, r)| **r == Some(false))
    {
        for c in 0..3 {
            out[4 * i + c] = (albedo[4 * i + c] as f32 * ambient).round() as u8;
        }
    }
    out
}

/// How a shadowed frame's lit and shadowed states match the mesh's shadows.
pub struct ShadowScores {
    /// The share of the scored pixels (a surface in both, facing the light) whose lit or
    /// shadowed state agrees with the mesh's.
    pub state: f64,
    /// Of the scored pixels shadowed in the frame or by the mesh, the share shadowed in both:
    /// where shadows cover little of the picture, `state` is high without any (a frame that
    /// draws none scores the lit share), this is not.
    pub shadow_iou: f64,
    /// Of the penumbra's pixels (between lit and shadowed by more than a tenth either way),
    /// the share darker, by more than 2 % of the way from shadowed to lit, than both
    /// neighbours across the penumbra (along the axis its brightness changes most on): speckle.
    pub speckle: f64,
}

/// `frame` against the mesh's shadows (`lit`), a pixel's state read against the same
/// pipeline's picture without shadows (`unshadowed`) and its unlit colour (`albedo`), over the
/// pixels of `region`.
pub fn shadow_scores(
    frame: &[u8],
    unshadowed: &[u8],
    albedo: &[u8],
    lit: &[Option<bool>],
    region: &[bool],
    size: (u32, u32),
) -> ShadowScores {
    let ambient = ambient();
    let luma = |p: &[u8]| 0.299 * p[0] as f32 + 0.587 * p[1] as f32 + 0.114 * p[2] as f32;
    let (mut scored, mut agree) = (0usize, 0usize);
    let (mut both, mut either) = (0usize, 0usize);
    for (i, state) in lit.iter().enumerate() {
        let Some(reached) = state else { continue };
        let px = 4 * i..4 * i + 4;
        if region[i] {
            let low = luma(&albedo[px.clone()]) * ambient;
            let (y, bright) = (luma(&frame[px.clone()]), luma(&unshadowed[px]));
            let frame_lit = (y - bright).abs() < (y - low).abs();
            scored += 1;
            agree += usize::from(frame_lit == *reached);
            both += usize::from(!frame_lit && !reached);
            either += usize::from(!frame_lit || !reached);
        }
    }
    // Speckle across the penumbra.
    let (w, h) = (size.0 as usize, size.1 as usize);
    let y = |i: usize| luma(&frame[4 * i..4 * i + 4]);
    let (mut penumbra, mut speckled) = (0usize, 0usize);
    for yy in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let i = yy * w + x;
            if !region[i] || lit[i].is_none() {
                continue;
            }
            let bright = luma(&unshadowed[4 * i..4 * i + 4]);
            let low = luma(&albedo[4 * i..4 * i + 4]) * ambient;
            let margin = 0.1 * (bright - low).abs();
            let v = y(i);
            if v <= low + margin || v >= bright - margin {
                continue;
            }
            penumbra += 1;
            // Across the penumbra: along the axis its brightness changes most on.
            let (a, b) = if (y(i + 1) - y(i - 1)).abs() >= (y(i + w) - y(i - w)).abs() {
                (i - 1, i + 1)
            } else {
                (i - w, i + w)
            };
            let step = 0.02 * (bright - low).abs();
            if v < y(a) - step && v < y(b) - step {
                speckled += 1;
            }
        }
    }
    ShadowScores {
        state: agree as f64 / scored.max(1) as f64,
        // Neither shadowed anywhere: they agree.
        shadow_iou: if either == 0 {
            1.0
        } else {
            both as f64 / either as f64
        },
        speckle: speckled as f64 / penumbra.max(1) as f64,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ambient_share_is_read_from_the_shared_lighting() {
        assert_eq!(ambient(), 0.25);
    }

    #[test]
    fn a_ray_meets_a_triangle_in_front_only() {
        let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let o = Vec3::new(0.2, 0.2, -1.0);
        assert!(hits(o, Vec3::Z, &t));
        assert!(!hits(o, -Vec3::Z, &t));
        assert!(!hits(Vec3::new(0.8, 0.8, -1.0), Vec3::Z, &t));
    }
}
