//! Measurements in the dataset's coordinates: distance along a polyline, area of a polygon,
//! height of one point above another, and the angle at a vertex. Computed in f64 from the
//! stored points the user picked, kept as GeoJSON so that a GIS reads them and the viewer reads
//! them back.

use crate::ViewerError;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// The file name of a dataset's own measurements, inside its directory.
pub const FILE_NAME: &str = "measurements.geojson";

/// What a measurement measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeasureKind {
    /// A polyline: each segment's length, the total, and the height difference end to end.
    Distance,
    /// A polygon: its area projected on the horizontal plane and in 3D.
    Area,
    /// The height of the second point above the first, with the distances between them.
    Height,
    /// The angle at the second of three points.
    Angle,
}

impl MeasureKind {
    pub const ALL: [MeasureKind; 4] = [
        MeasureKind::Distance,
        MeasureKind::Area,
        MeasureKind::Height,
        MeasureKind::Angle,
    ];

    pub fn name(self) -> &'static str {
        match self {
            MeasureKind::Distance => "distance",
            MeasureKind::Area => "area",
            MeasureKind::Height => "height",
            MeasureKind::Angle => "angle",
        }
    }

    /// The name with its article, for messages: "an area", "a distance".
    pub fn a_name(self) -> &'static str {
        match self {
            MeasureKind::Distance => "a distance",
            MeasureKind::Area => "an area",
            MeasureKind::Height => "a height",
            MeasureKind::Angle => "an angle",
        }
    }

    pub fn parse(s: &str) -> Result<MeasureKind, ViewerError> {
        MeasureKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| {
                ViewerError::argument(
                    s,
                    "unknown measurement (expected distance, area, height or angle)",
                )
            })
    }

    /// Points the kind takes exactly, where it takes a fixed number.
    pub fn fixed_points(self) -> Option<usize> {
        match self {
            MeasureKind::Height => Some(2),
            MeasureKind::Angle => Some(3),
            MeasureKind::Distance | MeasureKind::Area => None,
        }
    }

    /// Points the kind needs at least.
    pub fn min_points(self) -> usize {
        match self {
            MeasureKind::Distance | MeasureKind::Height => 2,
            MeasureKind::Area | MeasureKind::Angle => 3,
        }
    }
}

/// One measurement: its kind and its points in the dataset's coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    pub kind: MeasureKind,
    pub name: String,
    pub points: Vec<[f64; 3]>,
    /// The GeoJSON feature it was read from, if any: written back with its geometry and this
    /// project's properties replaced and the rest (a GIS's id, style, properties) as it was.
    pub source: Option<Value>,
}

/// The decimals value `name` of a measure prints with, its coordinates stored at `step`:
/// lengths to the step's (`strata_format::step_decimals`), areas to twice as many (the square
/// of the step), angles to a thousandth of a degree.
pub fn value_decimals(name: &str, step: f64) -> usize {
    let length = strata_format::step_decimals(step);
    match name {
        "angle_deg" => 3,
        _ if name.contains("area") => (2 * length).min(12),
        _ => length,
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn length(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

impl Measurement {
    /// Whether it has the points its kind needs.
    pub fn is_complete(&self) -> bool {
        let n = self.points.len();
        n >= self.kind.min_points() && self.kind.fixed_points().is_none_or(|f| n == f)
    }

    /// Whether another point can be added.
    pub fn takes_more(&self) -> bool {
        self.kind
            .fixed_points()
            .is_none_or(|f| self.points.len() < f)
    }

    /// The 3D length of each segment, in order (for an area, the closing one last).
    pub fn segment_lengths(&self) -> Vec<f64> {
        let p = &self.points;
        let mut out: Vec<f64> = p.windows(2).map(|w| length(sub(w[1], w[0]))).collect();
        if self.kind == MeasureKind::Area && p.len() >= 3 {
            out.push(length(sub(p[0], p[p.len() - 1])));
        }
        out
    }

    /// Area of the polygon projected on the horizontal plane (the shoelace formula).
    pub fn horizontal_area(&self) -> f64 {
        let Some(&o) = self.points.first() else {
            return 0.0;
        };
        // Relative to the first point: real-world coordinates are large, their products larger.
        let rel: Vec<[f64; 3]> = self.points.iter().map(|p| sub(*p, o)).collect();
        let n = rel.len();
        let twice: f64 = (0..n)
            .map(|i| {
                let (a, b) = (rel[i], rel[(i + 1) % n]);
                a[0] * b[1] - b[0] * a[1]
            })
            .sum();
        twice.abs() / 2.0
    }

    /// Area of the polygon in 3D: half the length of the sum of its edges' cross products
    /// (Newell's vector area), exact for a planar polygon and the area of its best-fitting
    /// projection otherwise.
    pub fn area_3d(&self) -> f64 {
        let Some(&o) = self.points.first() else {
            return 0.0;
        };
        let rel: Vec<[f64; 3]> = self.points.iter().map(|p| sub(*p, o)).collect();
        let n = rel.len();
        let mut s = [0.0; 3];
        for i in 0..n {
            let c = cross(rel[i], rel[(i + 1) % n]);
            for k in 0..3 {
                s[k] += c[k];
            }
        }
        length(s) / 2.0
    }

    /// For an area whose polygon crosses itself, the first two edges that cross
    /// (`polygon::crossing_edges`): its area then counts the loops with opposite signs, not
    /// the area a user meant.
    pub fn crossing_edges(&self) -> Option<(usize, usize)> {
        if self.kind != MeasureKind::Area {
            return None;
        }
        crate::polygon::crossing_edges(&self.points)
    }

    /// The angle at the second point between the rays to the first and the third, in degrees.
    pub fn angle_deg(&self) -> Option<f64> {
        let [a, v, b] = self.points.get(..3)?.try_into().ok()?;
        let (u, w) = (sub(a, v), sub(b, v));
        let (lu, lw) = (length(u), length(w));
        if lu == 0.0 || lw == 0.0 {
            return None;
        }
        // atan2 of |u x w| and u . w: accurate at angles near 0 and 180 degrees too.
        let dot = u[0] * w[0] + u[1] * w[1] + u[2] * w[2];
        Some(length(cross(u, w)).atan2(dot).to_degrees())
    }

    /// What it measures, as (name, value) in dataset units (square units for areas, degrees
    /// for angles), as the panel lists them and the GeoJSON properties keep them.
    pub fn values(&self) -> Vec<(&'static str, f64)> {
        let p = &self.points;
        if !self.is_complete() {
            return Vec::new();
        }
        let (first, last) = (p[0], p[p.len() - 1]);
        match self.kind {
            MeasureKind::Distance => vec![
                ("total_length", self.segment_lengths().iter().sum()),
                ("height_difference", last[2] - first[2]),
                (
                    "horizontal_distance",
                    p.windows(2)
                        .map(|w| length([w[1][0] - w[0][0], w[1][1] - w[0][1], 0.0]))
                        .sum(),
                ),
            ],
            MeasureKind::Area => vec![
                ("horizontal_area", self.horizontal_area()),
                ("area_3d", self.area_3d()),
                ("perimeter", self.segment_lengths().iter().sum()),
            ],
            MeasureKind::Height => vec![
                ("height", last[2] - first[2]),
                (
                    "horizontal_distance",
                    length([last[0] - first[0], last[1] - first[1], 0.0]),
                ),
                ("distance", length(sub(last, first))),
            ],
            MeasureKind::Angle => self
                .angle_deg()
                .map(|a| vec![("angle_deg", a)])
                .unwrap_or_default(),
        }
    }

    /// One line a value, for the panel and `strata measure`, to the decimals of the
    /// coordinates' `step` (`value_decimals`).
    pub fn lines(&self, step: f64) -> Vec<String> {
        let mut out = vec![format!("{} ({})", self.name, self.kind.name())];
        if self.kind == MeasureKind::Distance && self.points.len() > 2 {
            let d = value_decimals("segment", step);
            for (i, l) in self.segment_lengths().iter().enumerate() {
                out.push(format!("  segment {} {l:.d$}", i + 1));
            }
        }
        for (name, v) in self.values() {
            let d = value_decimals(name, step);
            out.push(format!("  {} {v:.d$}", name.replace('_', " ")));
        }
        if let Some((i, j)) = self.crossing_edges() {
            out.push(format!(
                "  the polygon crosses itself (edges {i} and {j}): its area subtracts one loop \
                 from the other; pick the corners in order around it"
            ));
        }
        if !self.is_complete() {
            out.push(format!(
                "  {} of at least {} points",
                self.points.len(),
                self.kind.min_points()
            ));
        }
        out
    }

    fn to_feature(&self) -> Value {
        let coords: Vec<Value> = self.points.iter().map(|p| json!(p)).collect();
        let geometry = match self.kind {
            MeasureKind::Area => {
                let mut ring = coords.clone();
                if let Some(first) = coords.first() {
                    ring.push(first.clone());
                }
                json!({"type": "Polygon", "coordinates": [ring]})
            }
            _ => json!({"type": "LineString", "coordinates": coords}),
        };
        let mut props = serde_json::Map::new();
        props.insert("name".into(), json!(self.name));
        props.insert("measure".into(), json!(self.kind.name()));
        for (k, v) in self.values() {
            props.insert(k.into(), json!(v));
        }
        if self.kind == MeasureKind::Distance {
            props.insert("segment_lengths".into(), json!(self.segment_lengths()));
        }
        // A GIS reading the file should see what the panel says: the area is not the one meant.
        if let Some((i, j)) = self.crossing_edges() {
            props.insert(CROSSING_EDGES.into(), json!([i, j]));
        }
        let mut feature = match &self.source {
            Some(Value::Object(f)) => f.clone(),
            _ => serde_json::Map::new(),
        };
        if let Some(Value::Object(kept)) = feature.get("properties") {
            // Ours are written anew: a crossing the polygon no longer has is not kept.
            for (k, v) in kept.iter().filter(|(k, _)| *k != CROSSING_EDGES) {
                props.entry(k.clone()).or_insert_with(|| v.clone());
            }
        }
        feature.insert("type".into(), json!("Feature"));
        feature.insert("geometry".into(), geometry);
        feature.insert("properties".into(), Value::Object(props));
        Value::Object(feature)
    }
}

/// The GeoJSON property naming the first two edges of an area's polygon that cross.
const CROSSING_EDGES: &str = "crossing_edges";

/// The measurements of a session, in the order they were made.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Measurements {
    pub items: Vec<Measurement>,
    /// The members of the FeatureCollection it was read from besides its features (a GIS's
    /// name and CRS), written back as they were.
    pub members: serde_json::Map<String, Value>,
}

impl Measurements {
    /// A GeoJSON FeatureCollection, coordinates in the dataset's own coordinate system.
    pub fn to_geojson(&self) -> Value {
        let features: Vec<Value> = self.items.iter().map(Measurement::to_feature).collect();
        let mut root = self.members.clone();
        root.insert("type".into(), json!("FeatureCollection"));
        root.insert("features".into(), Value::Array(features));
        Value::Object(root)
    }

    /// Reads a FeatureCollection (or one Feature) written by [`Measurements::to_geojson`] or by
    /// a GIS: LineStrings are distances and Polygons areas unless `properties.measure` says
    /// otherwise. `place` names the file in errors.
    pub fn from_geojson(text: &str, place: &str) -> Result<Measurements, ViewerError> {
        let fail = |what: String| ViewerError::source(place, what);
        let mut root: Value =
            serde_json::from_str(text).map_err(|e| fail(format!("not JSON ({e})")))?;
        // The features are taken out of the tree, not copied: a file of many holds them once.
        let (features, members) = match root["type"].as_str() {
            Some("FeatureCollection") => {
                let features = match root.get_mut("features").map(Value::take) {
                    Some(Value::Array(f)) => f,
                    _ => {
                        return Err(fail("the FeatureCollection has no features array".into()));
                    }
                };
                let mut members = match root {
                    Value::Object(m) => m,
                    _ => serde_json::Map::new(),
                };
                members.remove("features");
                (features, members)
            }
            Some("Feature") => (vec![root], serde_json::Map::new()),
            _ => {
                return Err(fail(
                    "not GeoJSON: expected a FeatureCollection or a Feature".into(),
                ));
            }
        };
        let items = features
            .iter()
            .enumerate()
            .map(|(i, f)| {
                feature_measurement(f, i).map_err(|what| fail(format!("feature {i}: {what}")))
            })
            .collect::<Result<_, _>>()?;
        Ok(Measurements { items, members })
    }

    /// Reads `path`; a file that does not exist holds none.
    pub fn load(path: &Path) -> Result<Measurements, ViewerError> {
        let text = match strata_format::read_side_file(path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Ok(Measurements::default());
            }
            Err(e) => return Err(ViewerError::output(path, format!("cannot read ({e})"))),
        };
        Measurements::from_geojson(&text, &path.display().to_string())
    }

    /// Reads `path`, which must exist (a file named on the command line).
    pub fn load_existing(path: &Path) -> Result<Measurements, ViewerError> {
        let text = strata_format::read_side_file(path)
            .map_err(|e| ViewerError::output(path, format!("cannot read ({e})")))?;
        Measurements::from_geojson(&text, &path.display().to_string())
    }

    /// Writes through a temporary name, so a failed write leaves the old file.
    pub fn save(&self, path: &Path) -> Result<(), ViewerError> {
        let json = serde_json::to_string_pretty(&self.to_geojson())
            .map_err(|e| ViewerError::output(path, format!("cannot encode ({e})")))?;
        crate::headless::write_atomic(path, json.as_bytes())
    }

    /// A name not yet taken, `KIND N`: N one more than the kind's count, or past any name
    /// of that form already given (by hand, or read from a file).
    pub fn next_name(&self, kind: MeasureKind) -> String {
        let n = self.items.iter().filter(|m| m.kind == kind).count();
        (n + 1..)
            .map(|k| format!("{} {k}", kind.name()))
            .find(|name| self.items.iter().all(|m| &m.name != name))
            .unwrap_or_default()
    }
}

fn feature_measurement(f: &Value, index: usize) -> Result<Measurement, String> {
    let geometry = &f["geometry"];
    let points_of = |v: &Value| -> Result<Vec<[f64; 3]>, String> {
        v.as_array()
            .ok_or("coordinates are not an array")?
            .iter()
            .map(|c| {
                let c = c.as_array().ok_or("a position is not an array")?;
                let n: Vec<f64> = c.iter().filter_map(Value::as_f64).collect();
                match n.as_slice() {
                    [x, y, z, ..] if n.len() == c.len() => Ok([*x, *y, *z]),
                    [x, y] if c.len() == 2 => Ok([*x, *y, 0.0]),
                    _ => Err("a position is not [x, y] or [x, y, z] in numbers".to_string()),
                }
            })
            .collect()
    };
    let (mut points, default_kind) = match geometry["type"].as_str() {
        Some("LineString") => (points_of(&geometry["coordinates"])?, MeasureKind::Distance),
        Some("Polygon") => {
            let ring = geometry["coordinates"]
                .get(0)
                .ok_or("the polygon has no ring")?;
            let mut p = points_of(ring)?;
            // GeoJSON closes rings; a measurement keeps each corner once.
            if p.len() >= 2 && p.first() == p.last() {
                p.pop();
            }
            (p, MeasureKind::Area)
        }
        Some(other) => return Err(format!("a {other} is not a measurement")),
        None => return Err("no geometry type".into()),
    };
    let props = &f["properties"];
    let kind = match props["measure"].as_str() {
        Some(k) => MeasureKind::parse(k).map_err(|e| e.to_string())?,
        None => default_kind,
    };
    if kind == MeasureKind::Area && geometry["type"] != "Polygon" && points.len() >= 2 {
        // An area written as a closed LineString.
        if points.first() == points.last() {
            points.pop();
        }
    }
    if points.iter().flatten().any(|c| !c.is_finite()) {
        return Err("a coordinate is not a finite number".into());
    }
    let name = props["name"]
        .as_str()
        .map(str::to_string)
        .unwrap_or_else(|| format!("{} {}", kind.name(), index + 1));
    let m = Measurement {
        kind,
        name,
        points,
        source: Some(f.clone()),
    };
    if !m.is_complete() {
        return Err(format!(
            "{} needs {} points, it has {}",
            kind.a_name(),
            match kind.fixed_points() {
                Some(n) => n.to_string(),
                None => format!("at least {}", kind.min_points()),
            },
            m.points.len()
        ));
    }
    Ok(m)
}

/// Where a dataset's own measurements live: inside a local dataset's directory.
pub fn beside(location: &str) -> Option<PathBuf> {
    crate::bookmarks::file_beside(location, FILE_NAME)
}

#[cfg(test)]
#[path = "measure_tests.rs"]
mod tests;
