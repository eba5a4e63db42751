//! The cameras of a render: the one of `--camera` (or the whole dataset in view), or one a
//! frame along the keyframes of `--path`, eye and target each in a straight line between two.

use crate::ViewerError;
use crate::camera::Camera;
use crate::dataset::StreamDataset;
use crate::headless::{DEFAULT_FOV_DEG, FPS_RANGE, RenderOptions, default_camera};
use serde::Deserialize;

#[derive(Debug, Deserialize)]
struct PathFile {
    keyframes: Vec<Keyframe>,
}

#[derive(Debug, Deserialize)]
struct Keyframe {
    eye: [f64; 3],
    target: [f64; 3],
    #[serde(default)]
    fov: Option<f32>,
    /// Seconds from the keyframe before (`bookmarks::DEFAULT_SECONDS` where not given).
    #[serde(default)]
    seconds: Option<f32>,
}

/// Frames a fly-through takes at most from its keyframes' seconds.
const MAX_PATH_FRAMES: u32 = 100_000;

pub(crate) fn cameras(
    ds: &StreamDataset,
    opts: &RenderOptions,
) -> Result<Vec<Camera>, ViewerError> {
    let anchor = ds.anchor();
    let default = default_camera(ds, opts.width, opts.height);
    let Some(path) = &opts.path else {
        return Ok(vec![match &opts.camera {
            Some(spec) => Camera::parse(spec, anchor, default)?,
            None => default,
        }]);
    };
    let text = strata_format::read_side_file(path).map_err(|e| {
        ViewerError::argument(
            path.display().to_string(),
            format!("cannot read the camera path ({e})"),
        )
    })?;
    let file: PathFile = serde_json::from_str(&text).map_err(|e| {
        ViewerError::argument(
            path.display().to_string(),
            format!("not a camera path ({e}); expected {{\"keyframes\": [{{\"eye\": [x,y,z], \"target\": [x,y,z], \"fov\": deg, \"seconds\": s}}, ...]}}"),
        )
    })?;
    let keys: Vec<Camera> = file
        .keyframes
        .iter()
        .map(|k| {
            let spec = format!(
                "eye={},{},{};target={},{},{};fov={}",
                k.eye[0],
                k.eye[1],
                k.eye[2],
                k.target[0],
                k.target[1],
                k.target[2],
                k.fov.unwrap_or(DEFAULT_FOV_DEG)
            );
            Camera::parse(&spec, anchor, default)
                .map_err(|e| ViewerError::argument(path.display().to_string(), e.to_string()))
        })
        .collect::<Result<_, _>>()?;
    // A time that is no positive number would be taken as the default: refused instead.
    if let Some((i, s)) = file
        .keyframes
        .iter()
        .enumerate()
        .skip(1)
        .find_map(|(i, k)| {
            k.seconds
                .filter(|s| !(s.is_finite() && *s > 0.0))
                .map(|s| (i, s))
        })
    {
        return Err(ViewerError::argument(
            path.display().to_string(),
            format!(
                "keyframe {} has seconds {s}; it must be a positive number",
                i + 1
            ),
        ));
    }
    // 0: unpaced, each frame drawn as soon as the one before.
    if !opts.wait_complete && opts.fps != 0.0 && !FPS_RANGE.contains(&opts.fps) {
        return Err(ViewerError::argument(
            "--fps",
            format!(
                "{} is outside the {} to {} frames per second a fly-through is paced at (0: unpaced)",
                opts.fps,
                FPS_RANGE.start(),
                FPS_RANGE.end()
            ),
        ));
    }
    if let Some((i, f)) = keys
        .windows(2)
        .enumerate()
        .find_map(|(i, k)| Some((i, k[0].lerp_meets_target(&k[1])?)))
    {
        return Err(ViewerError::argument(
            path.display().to_string(),
            format!(
                "between keyframes {} and {} the eye passes through the target ({:.0} % of the \
                 way), where the view has no direction; add a keyframe between them",
                i + 1,
                i + 2,
                f * 100.0
            ),
        ));
    }
    let times = crate::bookmarks::keyframe_times(file.keyframes.iter().map(|k| k.seconds));
    let total = times.last().copied().unwrap_or(0.0);
    // Without --frames (0), one frame each 1/fps of the keyframes' times, both ends included.
    let n = match opts.frames {
        0 if opts.fps.is_finite() && opts.fps > 0.0 => {
            let n = (total as f64 * opts.fps as f64).round() + 1.0;
            // Too many, or no number at all (an infinite total).
            if n.is_nan() || n > MAX_PATH_FRAMES as f64 {
                return Err(ViewerError::argument(
                    path.display().to_string(),
                    format!(
                        "{total} s at {} frames per second is more than {MAX_PATH_FRAMES} frames",
                        opts.fps
                    ),
                ));
            }
            n as usize
        }
        // Every camera is made up front: a count no run needs is refused, not allocated.
        n if n > MAX_PATH_FRAMES => {
            return Err(ViewerError::argument(
                "--frames",
                format!("{n} is more than the {MAX_PATH_FRAMES} frames a fly-through may take"),
            ));
        }
        n => n as usize,
    };
    if keys.len() < 2 || n < 2 {
        return Err(ViewerError::argument(
            path.display().to_string(),
            "a fly-through needs at least two keyframes and two frames or more (--frames, or the keyframes' seconds at --fps)",
        ));
    }
    Ok((0..n)
        .map(|i| {
            let t = i as f32 / (n - 1) as f32 * total;
            let (seg, f) = crate::bookmarks::segment_at(&times, t);
            keys[seg].lerp(&keys[seg + 1], f)
        })
        .collect())
}
