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
}

impl Bookmark {
    /// The view of `camera`, whose positions are relative to `anchor`.
    pub fn of(camera: &Camera, anchor: DVec3, name: String) -> Bookmark {
        Bookmark {
            name: Some(name),
            eye: (camera.eye.as_dvec3() + anchor).to_array(),
            target: (camera.target.as_dvec3() + anchor).to_array(),
            fov: Some(camera.fov_y.to_degrees()),
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
        let text = match std::fs::read_to_string(path) {
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
        let mut part = path.as_os_str().to_owned();
        part.push(".part");
        let part = PathBuf::from(part);
        std::fs::write(&part, json)
            .and_then(|_| std::fs::rename(&part, path))
            .map_err(|e| {
                let _ = std::fs::remove_file(&part);
                ViewerError::output(path, format!("cannot write ({e})"))
            })
    }

    /// The bookmark named `name`, or the first one without a name asked for.
    pub fn find(&self, name: Option<&str>, path: &Path) -> Result<&Bookmark, ViewerError> {
        let found = match name {
            Some(n) => self.keyframes.iter().find(|b| b.name.as_deref() == Some(n)),
            None => self.keyframes.first(),
        };
        found.ok_or_else(|| {
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
        })
    }
}

/// Where a dataset's own bookmarks live: inside a local dataset's directory; `None` for a
/// dataset read over HTTP.
pub fn beside(location: &str) -> Option<PathBuf> {
    let dir = Path::new(location);
    dir.is_dir().then(|| dir.join(FILE_NAME))
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
    }
}
