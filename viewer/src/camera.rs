//! The camera, in coordinates relative to the dataset's anchor (the centre of its root cube), so
//! that f32 keeps sub-millimetre precision for scans placed at UTM or state-plane coordinates.

use crate::ViewerError;
use glam::{DVec3, Mat4, Vec3, Vec4};

/// The eight corners of the box `min`..`max`.
pub fn box_corners(min: Vec3, max: Vec3) -> [Vec3; 8] {
    std::array::from_fn(|i| {
        Vec3::new(
            if i & 1 == 0 { min.x } else { max.x },
            if i & 2 == 0 { min.y } else { max.y },
            if i & 4 == 0 { min.z } else { max.z },
        )
    })
}

/// Z is up, as in every survey coordinate system Strata reads.
pub const UP: Vec3 = Vec3::Z;

/// The farthest the wheel takes the eye from its target: the Earth seen whole from ten
/// thousand of its radii, within f32's range for every product the projection forms.
pub const MAX_DISTANCE: f32 = 1e11;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub target: Vec3,
    /// Vertical field of view in radians.
    pub fov_y: f32,
}

impl Camera {
    /// A view of the whole box from the south-west and above, its corners filling about 90 %
    /// of a view of `aspect` (width / height).
    pub fn fit(min: Vec3, max: Vec3, fov_y: f32, aspect: f32) -> Camera {
        let centre = (min + max) * 0.5;
        let radius = ((max - min) * 0.5).length().max(1e-3);
        let dir = Vec3::new(-0.45, -0.75, 0.6).normalize();
        let mut distance = radius / (fov_y * 0.5).sin() * 1.02;
        let mut cam = Camera {
            eye: centre + dir * distance,
            target: centre,
            fov_y,
        };
        // The bounding sphere is loose for flat scans: pull in until the corners touch 90 %.
        for _ in 0..6 {
            let vp =
                cam.projection(aspect.max(0.05), distance * 1e-3, distance * 10.0) * cam.view();
            let extent = box_corners(min, max)
                .into_iter()
                .map(|c| {
                    let p = vp.project_point3(c);
                    p.x.abs().max(p.y.abs())
                })
                .fold(0.0f32, f32::max);
            if !(extent.is_finite() && extent > 0.0) {
                break;
            }
            distance = (distance * extent / 0.9).max(radius * 0.1);
            cam.eye = centre + dir * distance;
        }
        cam
    }

    /// The vertical fields of view a camera may have, in degrees.
    pub const FOV_DEG: std::ops::RangeInclusive<f32> = 1.0..=170.0;

    /// Parses `eye=X,Y,Z;target=X,Y,Z;fov=DEG` in real-world coordinates. Missing parts keep
    /// the values of `default`.
    pub fn parse(spec: &str, anchor: DVec3, default: Camera) -> Result<Camera, ViewerError> {
        let mut cam = default;
        for part in spec.split(';').map(str::trim).filter(|p| !p.is_empty()) {
            let (key, value) = part.split_once('=').ok_or_else(|| {
                ViewerError::argument(spec, format!("camera part {part:?} is not KEY=VALUE"))
            })?;
            match key.trim() {
                "eye" => cam.eye = parse_point(spec, value, anchor)?,
                "target" => cam.target = parse_point(spec, value, anchor)?,
                "fov" => {
                    let deg: f32 = value.trim().parse().map_err(|_| {
                        ViewerError::argument(spec, format!("fov {value:?} is not a number"))
                    })?;
                    if !Camera::FOV_DEG.contains(&deg) {
                        return Err(ViewerError::argument(
                            spec,
                            format!("fov {deg} is outside 1 to 170 degrees"),
                        ));
                    }
                    cam.fov_y = deg.to_radians();
                }
                other => {
                    return Err(ViewerError::argument(
                        spec,
                        format!("unknown camera part {other:?} (expected eye, target or fov)"),
                    ));
                }
            }
        }
        if (cam.eye - cam.target).length() < 1e-6 {
            return Err(ViewerError::argument(
                spec,
                "camera eye and target coincide",
            ));
        }
        Ok(cam)
    }

    /// The camera in the `--camera` syntax, in real-world coordinates.
    pub fn to_spec(&self, anchor: DVec3) -> String {
        let e = anchor + self.eye.as_dvec3();
        let t = anchor + self.target.as_dvec3();
        format!(
            "eye={:.3},{:.3},{:.3};target={:.3},{:.3},{:.3};fov={:.1}",
            e.x,
            e.y,
            e.z,
            t.x,
            t.y,
            t.z,
            self.fov_y.to_degrees()
        )
    }

    pub fn forward(&self) -> Vec3 {
        (self.target - self.eye).normalize_or(Vec3::Y)
    }

    /// Right-handed view matrix; a view straight up or down borrows +Y as its up vector.
    pub fn view(&self) -> Mat4 {
        let f = self.forward();
        let up = if f.cross(UP).length_squared() < 1e-8 {
            Vec3::Y
        } else {
            UP
        };
        glam::camera::rh::view::look_at_mat4(self.eye, self.target, up)
    }

    pub fn projection(&self, aspect: f32, near: f32, far: f32) -> Mat4 {
        glam::camera::rh::proj::directx::perspective(self.fov_y, aspect, near, far)
    }

    /// Pixels per world unit at distance 1, for a viewport `height` pixels high.
    pub fn focal_px(&self, height: u32) -> f32 {
        height as f32 * 0.5 / (self.fov_y * 0.5).tan()
    }

    /// Turns the eye around the target: `yaw` about the vertical, `pitch` up and down.
    pub fn orbit(&mut self, yaw: f32, pitch: f32) {
        let offset = self.eye - self.target;
        let r = offset.length();
        let mut azimuth = offset.y.atan2(offset.x);
        let mut elevation = (offset.z / r).clamp(-1.0, 1.0).asin();
        azimuth -= yaw;
        elevation = (elevation + pitch).clamp(-1.55, 1.55);
        let dir = Vec3::new(
            elevation.cos() * azimuth.cos(),
            elevation.cos() * azimuth.sin(),
            elevation.sin(),
        );
        self.eye = self.target + dir * r;
    }

    /// Moves eye and target together by fractions of the view's width and height at the target.
    pub fn pan(&mut self, dx: f32, dy: f32) {
        let distance = (self.target - self.eye).length();
        let span = 2.0 * distance * (self.fov_y * 0.5).tan();
        let f = self.forward();
        let right = f.cross(UP).normalize_or(Vec3::X);
        let up = right.cross(f);
        let shift = (-right * dx + up * dy) * span;
        self.eye += shift;
        self.target += shift;
    }

    /// Moves the eye towards the target by `factor` of their distance (< 1 comes closer), no
    /// nearer than a hundred thousandth of the target's distance from the origin (or of a
    /// unit) and no farther than `MAX_DISTANCE`. Unbounded, three hundred wheel clicks put the
    /// eye on the target in f32, and two thousand at infinity: the view went blank, no zoom
    /// brought it back, and a view saved then held no numbers.
    pub fn zoom(&mut self, factor: f32) {
        let offset = self.eye - self.target;
        let r = offset.length();
        if !(r.is_finite() && r > 0.0) {
            return;
        }
        let nearest = self.target.abs().max_element().max(1.0) * 1e-5;
        let wanted = r * factor.clamp(0.01, 100.0);
        self.eye = self.target + offset * (wanted.clamp(nearest, MAX_DISTANCE.max(nearest)) / r);
    }

    /// Moves eye and target along the view axes (forward, right, up) by `step` world units.
    pub fn fly(&mut self, forward: f32, right: f32, up: f32) {
        let f = self.forward();
        let r = f.cross(UP).normalize_or(Vec3::X);
        let shift = f * forward + r * right + UP * up;
        self.eye += shift;
        self.target += shift;
    }

    /// Where on the way from `self` to `other` (a fraction, 0 to 1) the eye of their [`lerp`]
    /// passes through its target, within a ten-thousandth of the farther key's distance:
    /// there the view has no direction, and about it turns around at once.
    ///
    /// [`lerp`]: Camera::lerp
    pub fn lerp_meets_target(&self, other: &Camera) -> Option<f32> {
        let a = self.eye - self.target;
        let b = other.eye - other.target;
        let d = b - a;
        let f = if d.length_squared() > 0.0 {
            (-a.dot(d) / d.length_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        ((a + d * f).length() <= 1e-4 * a.length().max(b.length())).then_some(f)
    }

    /// Linear interpolation between two cameras (for fly-through paths).
    pub fn lerp(&self, other: &Camera, t: f32) -> Camera {
        Camera {
            eye: self.eye.lerp(other.eye, t),
            target: self.target.lerp(other.target, t),
            fov_y: self.fov_y + (other.fov_y - self.fov_y) * t,
        }
    }
}

fn parse_point(spec: &str, value: &str, anchor: DVec3) -> Result<Vec3, ViewerError> {
    let parts: Vec<f64> = value
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| ViewerError::argument(spec, format!("{value:?} is not X,Y,Z")))?;
    match parts[..] {
        [x, y, z] if parts.iter().all(|v| v.is_finite()) => {
            Ok((DVec3::new(x, y, z) - anchor).as_vec3())
        }
        _ => Err(ViewerError::argument(
            spec,
            format!("{value:?} is not three finite numbers X,Y,Z"),
        )),
    }
}

/// The six planes of a view-projection's frustum, as `normal.xyz, d` with the inside positive.
#[derive(Debug, Clone, Copy)]
pub struct Frustum {
    planes: [Vec4; 6],
}

impl Frustum {
    /// The frustum of `camera` in a view of `aspect`, between linear depths `near` and `far`:
    /// its sides from the view-projection's rows, its ends from the view axis itself. The far
    /// plane of the rows (the fourth less the third) cancels to rounding noise in f32 once far
    /// passes about 1e5 times near, as it does with the eye close to a wall of a large scan.
    pub fn of_view(camera: &Camera, aspect: f32, near: f32, far: f32) -> Frustum {
        let mut f = Frustum::from_view_proj(camera.projection(aspect, near, far) * camera.view());
        let forward = camera.forward();
        let at_eye = forward.dot(camera.eye);
        f.planes[4] = forward.extend(-(at_eye + near));
        f.planes[5] = (-forward).extend(at_eye + far);
        f
    }

    /// From a D3D-style (depth 0..1) view-projection matrix.
    pub fn from_view_proj(m: Mat4) -> Frustum {
        let r0 = m.row(0);
        let r1 = m.row(1);
        let r2 = m.row(2);
        let r3 = m.row(3);
        let planes = [r3 + r0, r3 - r0, r3 + r1, r3 - r1, r2, r3 - r2].map(|p| {
            let n = p.truncate().length();
            if n > 0.0 { p / n } else { p }
        });
        Frustum { planes }
    }

    /// Whether an axis-aligned box touches the frustum (conservative).
    pub fn intersects_box(&self, min: Vec3, max: Vec3) -> bool {
        self.planes.iter().all(|p| {
            let corner = Vec3::new(
                if p.x >= 0.0 { max.x } else { min.x },
                if p.y >= 0.0 { max.y } else { min.y },
                if p.z >= 0.0 { max.z } else { min.z },
            );
            p.truncate().dot(corner) + p.w >= 0.0
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_wheel_keeps_the_eye_off_its_target_and_finite() {
        let start = Camera {
            eye: Vec3::new(3.0, -4.0, 0.0),
            target: Vec3::ZERO,
            fov_y: 1.0,
        };
        let mut c = start;
        for _ in 0..2000 {
            c.zoom(0.8);
        }
        let near = (c.eye - c.target).length();
        assert!(near > 0.0 && c.eye != c.target, "{c:?}");
        c.zoom(1.25);
        assert!(
            (c.eye - c.target).length() > near,
            "zooming out moves away again"
        );
        for _ in 0..5000 {
            c.zoom(1.25);
        }
        assert!(c.eye.is_finite(), "{c:?}");
        assert!((c.eye - c.target).length() <= MAX_DISTANCE * 1.001);
        // The direction is kept all the way.
        let dir = (c.eye - c.target).normalize();
        assert!((dir - (start.eye - start.target).normalize()).length() < 1e-4);
    }

    #[test]
    fn parses_and_prints_real_world_cameras() {
        let anchor = DVec3::new(636_000.0, 849_000.0, 400.0);
        let default = Camera::fit(Vec3::splat(-10.0), Vec3::splat(10.0), 1.0, 1.0);
        let cam = Camera::parse(
            "eye=636100,849000,500; target=636000,849000,400;fov=45",
            anchor,
            default,
        )
        .expect("valid camera");
        assert_eq!(cam.eye, Vec3::new(100.0, 0.0, 100.0));
        assert_eq!(cam.target, Vec3::ZERO);
        assert!((cam.fov_y.to_degrees() - 45.0).abs() < 1e-4);
        let again = Camera::parse(&cam.to_spec(anchor), anchor, default).expect("round trip");
        assert!((again.eye - cam.eye).length() < 1e-3);
        for bad in [
            "eye=1,2",
            "fov=0",
            "eye=1,2,3;target=1,2,3",
            "zoom=3",
            "eye=a,b,c",
        ] {
            let shifted = DVec3::new(1.0, 2.0, 3.0);
            let base = Camera::fit(Vec3::ZERO, Vec3::ONE, 1.0, 1.0);
            let base = Camera {
                target: Vec3::ZERO,
                eye: Vec3::new(5.0, 0.0, 0.0),
                ..base
            };
            assert!(Camera::parse(bad, shifted * 0.0, base).is_err(), "{bad}");
        }
    }

    /// Keys whose eye and target swap meet halfway; keys whose eye passes beside the target,
    /// or stays put while the target moves, do not.
    #[test]
    fn a_flight_through_its_own_target_is_found() {
        let key = |eye: [f32; 3], target: [f32; 3]| Camera {
            eye: Vec3::from(eye),
            target: Vec3::from(target),
            fov_y: 1.0,
        };
        let a = key([0.0, 0.0, 0.0], [10.0, 0.0, 0.0]);
        let swapped = key([10.0, 0.0, 0.0], [0.0, 0.0, 0.0]);
        let f = a.lerp_meets_target(&swapped).expect("they meet");
        assert!((f - 0.5).abs() < 1e-6, "{f}");
        let lerped = a.lerp(&swapped, f);
        assert!((lerped.eye - lerped.target).length() < 1e-5);
        let beside = key([10.0, 1.0, 0.0], [0.0, 0.0, 0.0]);
        assert_eq!(a.lerp_meets_target(&beside), None);
        let turned = key([0.0, 0.0, 0.0], [0.0, 10.0, 0.0]);
        assert_eq!(a.lerp_meets_target(&turned), None);
        assert_eq!(a.lerp_meets_target(&a), None);
    }

    #[test]
    fn fitted_view_sees_the_box_and_culls_what_is_behind() {
        let cam = Camera::fit(Vec3::splat(-1.0), Vec3::splat(1.0), 0.8, 1.5);
        let vp = cam.projection(1.0, 0.01, 100.0) * cam.view();
        let f = Frustum::from_view_proj(vp);
        assert!(f.intersects_box(Vec3::splat(-1.0), Vec3::splat(1.0)));
        let behind = cam.eye + (cam.eye - cam.target) * 2.0;
        assert!(!f.intersects_box(behind - 0.1, behind + 0.1));
    }

    /// A wall a few millimetres from the eye in a view 30 km deep: far / near is 1e7, where
    /// the matrix's far plane is noise. The ends come from the view axis: the wall is in, a
    /// box beyond the far end out, and one just inside it in.
    #[test]
    fn a_deep_view_keeps_its_near_and_far_ends() {
        let cam = Camera {
            eye: Vec3::ZERO,
            target: Vec3::new(0.0, 1.0, 0.0),
            fov_y: 0.2,
        };
        let (near, far) = (0.003, 30_000.0);
        let f = Frustum::of_view(&cam, 1.5, near, far);
        let wall = Vec3::new(0.0, 0.005, 0.0);
        assert!(f.intersects_box(wall - 0.0005, wall + 0.0005));
        let nearer = Vec3::new(0.0, 0.001, 0.0);
        assert!(!f.intersects_box(nearer - 0.0005, nearer + 0.0005));
        let beyond = Vec3::new(0.0, 30_100.0, 0.0);
        assert!(!f.intersects_box(beyond - 10.0, beyond + 10.0));
        let inside = Vec3::new(0.0, 29_900.0, 0.0);
        assert!(f.intersects_box(inside - 10.0, inside + 10.0));
    }
}
