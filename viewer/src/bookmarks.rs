//! Camera bookmarks: named views in the dataset's coordinates, kept in a small JSON file beside
//! a local dataset (`bookmarks.json`) or in any file given. The file has the form of a
//! fly-through path (`{"keyframes": [{"name", "eye", "target", "fov"}, ...]}`), so `strata
//! render --path` plays the bookmarks back.

use crate::ViewerError;
use crate::camera::Camera;
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The file name of a dataset's own bookmarks, inside its directory.
pub const FILE_NAME: &str = "bookmarks.json";

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Bookmarks {
    pub keyframes: Vec<Bookmark>,
}

/// One view: the eye and the point looked at, in the dataset's coordinates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Bookmark {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    pub eye: [f64; 3],
    pub target: [f64; 3],
    /// Vertical field of view in degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov: Option<f32>,
    /// Seconds a fly-through takes to reach this view from the one before
    /// (`DEFAULT_SECONDS` where not given).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seconds: Option<f32>,
}

/// Seconds between two views of a fly-through that does not say.
pub const DEFAULT_SECONDS: f32 = 3.0;

/// The time of each view of a fly-through from its start: 0 for the first, then each view's
/// `seconds` after the one before (`DEFAULT_SECONDS` where missing, not a positive number).
pub fn keyframe_times(seconds: impl IntoIterator<Item = Option<f32>>) -> Vec<f32> {
    let mut t = 0.0f32;
    seconds
        .into_iter()
        .enumerate()
        .map(|(i, s)| {
            if i > 0 {
                t += s
                    .filter(|s| s.is_finite() && *s > 0.0)
                    .unwrap_or(DEFAULT_SECONDS);
            }
            t
        })
        .collect()
}

/// Where time `t` falls among `times` (at least two, increasing): the segment from view k to
/// view k + 1 and how far along it (0 to 1), clamped to the ends.
pub fn segment_at(times: &[f32], t: f32) -> (usize, f32) {
    if times.len() < 2 {
        return (0, 0.0);
    }
    let last = times.len().saturating_sub(2);
    let k = times[1..]
        .iter()
        .position(|&end| t < end)
        .unwrap_or(last)
        .min(last);
    let (a, b) = (times[k], times[k + 1]);
    let f = if b > a { (t - a) / (b - a) } else { 1.0 };
    (k, f.clamp(0.0, 1.0))
}

impl Bookmark {
    /// The view of `camera`, whose positions are relative to `anchor`.
    pub fn of(camera: &Camera, anchor: DVec3, name: String) -> Bookmark {
        Bookmark {
            name: Some(name),
            eye: (camera.eye.as_dvec3() + anchor).to_array(),
            target: (camera.target.as_dvec3() + anchor).to_array(),
            fov: Some(camera.fov_y.to_degrees()),
            seconds: None,
        }
    }

    /// The camera spec `Camera::parse` reads (`eye=..;target=..;fov=..`).
    pub fn spec(&self, default_fov_deg: f32) -> String {
        let [ex, ey, ez] = self.eye;
        let [tx, ty, tz] = self.target;
        let fov = self.fov.unwrap_or(default_fov_deg);
        format!("eye={ex},{ey},{ez};target={tx},{ty},{tz};fov={fov}")
    }
}

impl Bookmarks {
    /// Reads `path`; a file that does not exist yet holds no bookmarks.
    pub fn load(path: &Path) -> Result<Bookmarks, ViewerError> {
        let text = match strata_format::read_side_file(path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Bookmarks::default()),
            Err(e) => return Err(ViewerError::output(path, format!("cannot read ({e})"))),
        };
        serde_json::from_str(&text).map_err(|e| {
            ViewerError::output(
                path,
                format!("not a bookmarks file ({e}); expected {{\"keyframes\": [{{\"name\": \"..\", \"eye\": [x,y,z], \"target\": [x,y,z], \"fov\": deg}}, ...]}}"),
            )
        })
    }

    /// Writes through a temporary name, so a failed write leaves the old file.
    pub fn save(&self, path: &Path) -> Result<(), ViewerError> {
        let json = serde_json::to_string_pretty(self)
            .map_err(|e| ViewerError::output(path, format!("cannot encode ({e})")))?;
        crate::headless::write_atomic(path, json.as_bytes())
    }

    /// The bookmark named `name`, or the first one without a name asked for.
    pub fn find(&self, name: Option<&str>, path: &Path) -> Result<&Bookmark, ViewerError> {
        let found = match name {
            Some(n) => self.keyframes.iter().find(|b| b.name.as_deref() == Some(n)),
            None => self.keyframes.first(),
        };
        let mark = found.ok_or_else(|| {
            let names: Vec<&str> = self
                .keyframes
                .iter()
                .filter_map(|b| b.name.as_deref())
                .collect();
            ViewerError::output(
                path,
                match name {
                    Some(n) if names.is_empty() => format!("no bookmark is named {n:?}"),
                    Some(n) => format!(
                        "no bookmark is named {n:?} (there are {})",
                        names.join(", ")
                    ),
                    None => "holds no bookmark".to_string(),
                },
            )
        })?;
        // Refused here, where the file and the bookmark can be named, not by the camera.
        let which = || match &mark.name {
            Some(n) => format!("bookmark {n:?}"),
            None => "its first bookmark".to_string(),
        };
        let apart = (DVec3::from_array(mark.eye) - DVec3::from_array(mark.target)).length();
        if apart < 1e-6 {
            return Err(ViewerError::output(
                path,
                format!("{} has its eye at its target, so it looks nowhere", which()),
            ));
        }
        if let Some(fov) = mark.fov
            && !Camera::FOV_DEG.contains(&fov)
        {
            return Err(ViewerError::output(
                path,
                format!(
                    "{} has a field of view of {fov} degrees, outside {} to {}",
                    which(),
                    Camera::FOV_DEG.start(),
                    Camera::FOV_DEG.end()
                ),
            ));
        }
        Ok(mark)
    }
}

/// Where a dataset's own bookmarks live: inside a local dataset's directory; `None` for a
/// dataset read over HTTP.
pub fn beside(location: &str) -> Option<PathBuf> {
    file_beside(location, FILE_NAME)
}

/// A file named `name` inside a local dataset's directory (bookmarks, measurements); `None`
/// for a dataset read over HTTP.
pub fn file_beside(location: &str, name: &str) -> Option<PathBuf> {
    let dir = Path::new(location);
    dir.is_dir().then(|| dir.join(name))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bookmarks_round_trip_and_become_camera_specs() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join(FILE_NAME);
        assert_eq!(
            Bookmarks::load(&path).expect("absent is empty"),
            Bookmarks::default()
        );
        let anchor = DVec3::new(500000.0, 4600000.0, 10.0);
        let default = Camera::fit(glam::Vec3::splat(-1.0), glam::Vec3::splat(1.0), 0.8, 1.5);
        let cam = Camera::parse(
            "eye=500010,4600020,40;target=500000,4600000,10;fov=45",
            anchor,
            default,
        )
        .expect("camera");
        let b = Bookmarks {
            keyframes: vec![Bookmark::of(&cam, anchor, "tower".into())],
        };
        b.save(&path).expect("saved");
        let back = Bookmarks::load(&path).expect("loaded");
        assert_eq!(back, b);
        let spec = back.find(Some("tower"), &path).expect("found").spec(50.0);
        let again = Camera::parse(&spec, anchor, default).expect("parses");
        assert!((again.eye - cam.eye).length() < 1e-3 && (again.fov_y - cam.fov_y).abs() < 1e-5);
        let e = back.find(Some("bridge"), &path).expect_err("unknown");
        assert!(e.to_string().contains("tower"), "{e}");
        // A view that looks nowhere is refused naming the file and the bookmark.
        let refused = |marks: &Bookmarks, fault: &str| {
            let e = marks.find(Some("tower"), &path).expect_err(fault);
            let said = e.to_string();
            assert!(said.contains(FILE_NAME) && said.contains(fault), "{said}");
        };
        let mut blind = back.clone();
        let [x, y, z] = blind.keyframes[0].eye;
        blind.keyframes[0].target = [x, y, z + 1e-7];
        refused(&blind, "bookmark \"tower\" has its eye at its target");
        // So is a field of view the camera cannot take.
        let mut wide = back.clone();
        wide.keyframes[0].fov = Some(175.0);
        refused(
            &wide,
            "\"tower\" has a field of view of 175 degrees, outside 1 to 170",
        );
    }

    #[test]
    fn a_fly_through_keeps_each_views_seconds() {
        let times = keyframe_times([None, Some(1.0), None, Some(-2.0), Some(0.5)]);
        assert_eq!(times, vec![0.0, 1.0, 4.0, 7.0, 7.5]);
        assert_eq!(segment_at(&times, 0.5), (0, 0.5));
        assert_eq!(segment_at(&times, 2.5), (1, 0.5));
        assert_eq!(segment_at(&times, 7.25), (3, 0.5));
        assert_eq!(segment_at(&times, 99.0), (3, 1.0));
        assert_eq!(segment_at(&times, -1.0), (0, 0.0));
        assert_eq!(segment_at(&[0.0], 1.0), (0, 0.0));
    }
}
