use crate::{
    Attribute, DatasetId, FormatError, Layout, MAX_ATTRIBUTES, NodeKey, PageRef, ROOT_PAGE_OFFSET,
    RowLayout,
};
use serde::{Deserialize, Serialize};
use std::path::Path;

pub const FORMAT_NAME: &str = "strata-lpc";
pub const VERSION_MAJOR: u32 = 1;
/// The newest minor version this reader knows; it refuses newer ones (section 1 of SPEC.md).
pub const VERSION_MINOR: u32 = 1;

/// The most levels a 1.1 page may span (a full page of 8 levels is 2.4 million entries).
pub const MAX_PAGE_LEVELS: u32 = 8;

/// Real-world bounds of the stored points (the min and max of every coordinate).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Bounds {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

/// The root node's cube in integer coordinates: `[min, min + 2^bits)` on every axis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Cube {
    pub min: [i64; 3],
    pub bits: u32,
}

/// A name metadata.json may give one of the dataset's files: one plain, visible segment in
/// the dataset's directory (not a path, which could make a reader open any file on the
/// machine, and not metadata.json itself). Readers and the server hold names to it alike.
pub fn plain_file_name(name: &str) -> bool {
    !name.is_empty()
        && !name.starts_with('.')
        && !name.contains(['/', '\\', '\0', ':'])
        && name != crate::DatasetFile::Metadata.name()
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FileInfo {
    pub name: String,
    pub size: u64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Files {
    pub hierarchy: FileInfo,
    pub octree: FileInfo,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HierarchyInfo {
    pub root_page_offset: u64,
    pub root_page_size: u64,
    pub page_levels: u32,
}

/// Where one scan's scanner stood: the `scanner` attribute of the points it took indexes the
/// list of these.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scanner {
    /// World coordinates, in the units of the points.
    pub position: [f64; 3],
    /// The input file of the scan (its name, as in `sources`).
    pub source: String,
}

/// The contents of `metadata.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Metadata {
    pub format: String,
    pub version: [u32; 2],
    /// The dataset id, also in the heads of both binary files (format 1.1; absent in 1.0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub id: Option<DatasetId>,
    pub points: u64,
    pub nodes: u64,
    /// Deepest level that holds a node (root = 0).
    pub depth: u32,
    pub scale: [f64; 3],
    pub offset: [f64; 3],
    pub bounds: Bounds,
    pub cube: Cube,
    /// Point spacing of the root node in real units (x axis); halves with each level.
    pub spacing: f64,
    pub sampling: String,
    pub attributes: Vec<Attribute>,
    pub files: Files,
    pub hierarchy: HierarchyInfo,
    #[serde(default)]
    pub sources: Vec<String>,
    #[serde(default)]
    pub generator: String,
    /// What the converter changed while reading the inputs (a coarsened scale, renamed
    /// attributes, bounds measured instead of taken from a header); informative.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// Points per classification code (keys are the codes as decimal strings), where the
    /// points have a `classification` attribute; informative.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub classes: std::collections::BTreeMap<String, u64>,
    /// How the `normal`, `radius` and `surface_variation` attributes were made, where the
    /// converter estimated them (`strata convert --normals`); informative.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normals: Option<NormalsInfo>,
    /// Where each scan's scanner stood, for inputs that say (E57); the points' `scanner`
    /// attribute indexes this list (an index past its end names no scanner); informative.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub scanners: Vec<Scanner>,
    /// The inputs' coordinate reference system as they stated it, for exports to state it
    /// again; informative (SPEC.md section 2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crs: Option<Crs>,
}

/// A coordinate reference system as LAS files state it (LAS 1.4 R15, section 2.5): OGC WKT,
/// GeoTIFF keys, or both where an input carried both. Kept as given; no reader here
/// interprets it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Crs {
    /// The OGC WKT (record 2112 of `LASF_Projection`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wkt: Option<String>,
    /// The GeoTIFF keys (records 34735, 34736 and 34737).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geotiff: Option<GeoTiffKeys>,
}

/// GeoTIFF's GeoKeyDirectoryTag, with the doubles and text its keys point into.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GeoTiffKeys {
    pub keys: Vec<u16>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub doubles: Vec<f64>,
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub ascii: String,
}

/// What `strata convert --normals` did (SPEC.md section 4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NormalsInfo {
    /// Points per neighbourhood, the point itself included.
    pub k: u32,
    /// How normals were oriented: `"scanner"`, `"up"` or `"none"`.
    pub orient: String,
    /// Normals estimated by the converter.
    pub computed: u64,
    /// Normals taken from the inputs as they were.
    pub kept: u64,
    /// Points with fewer than k distinct neighbours within `search_radius` (their estimate
    /// used the n they had; their radius is `search_radius * sqrt(ln 100 / n)`, at most
    /// `search_radius`).
    pub partial: u64,
    /// Points given no normal (stored as none): fewer than three distinct positions within
    /// `search_radius`, the point's own included, or all of them on one line, through which
    /// no plane is better than another.
    #[serde(default)]
    pub no_normal: u64,
    /// Neighbours farther than this (real units) were not used; 0: no bound (the inputs
    /// gave no density to make one from, as when every point lies at one position).
    #[serde(default)]
    pub search_radius: f64,
    /// The mean of the `radius` attribute over all points.
    pub mean_radius: f64,
    /// Paper 001's global surfel size: the mean radius of the smallest circles enclosing the
    /// triangles of a hierarchical clustering into three-point clusters (section 3.4).
    pub surfel_radius: f64,
    /// Triangles that mean is taken over.
    pub triangles: u64,
}

impl Metadata {
    /// The binary layout of the files, from the version (checked by `from_json`).
    pub fn layout(&self) -> Layout {
        Layout::of_minor(self.version[1])
    }

    pub fn row_layout(&self) -> RowLayout {
        RowLayout::new(self.attributes.clone())
    }

    /// Where the root hierarchy page lies in `hierarchy.bin`.
    pub fn root_page(&self) -> PageRef {
        PageRef {
            root: NodeKey::ROOT,
            offset: self.hierarchy.root_page_offset,
            size: self.hierarchy.root_page_size,
            checksum: None,
        }
    }

    /// Bytes per point in an uncompressed node payload.
    pub fn point_bytes(&self) -> usize {
        self.row_layout().stride
    }

    /// Real coordinate of an integer position.
    pub fn to_real(&self, p: [i32; 3]) -> [f64; 3] {
        [
            self.offset[0] + self.scale[0] * p[0] as f64,
            self.offset[1] + self.scale[1] * p[1] as f64,
            self.offset[2] + self.scale[2] * p[2] as f64,
        ]
    }

    /// The first member holding a number JSON cannot carry (NaN or infinite), if any: such a
    /// member would be written as `null` and the dataset would not read back.
    pub fn non_finite(&self) -> Option<String> {
        let mut numbers: Vec<(String, f64)> = Vec::new();
        for (name, v) in [
            ("scale", &self.scale),
            ("offset", &self.offset),
            ("bounds.min", &self.bounds.min),
            ("bounds.max", &self.bounds.max),
        ] {
            numbers.extend(v.iter().map(|x| (name.to_string(), *x)));
        }
        numbers.push(("spacing".into(), self.spacing));
        if let Some(n) = &self.normals {
            numbers.push(("normals.mean_radius".into(), n.mean_radius));
            numbers.push(("normals.surfel_radius".into(), n.surfel_radius));
            numbers.push(("normals.search_radius".into(), n.search_radius));
        }
        for (i, s) in self.scanners.iter().enumerate() {
            numbers.extend(s.position.iter().map(|x| (format!("scanners[{i}]"), *x)));
        }
        for a in &self.attributes {
            for v in a.scale.iter().chain(a.offset.iter()).flatten() {
                numbers.push((format!("attribute \"{}\"", a.name), *v));
            }
        }
        numbers
            .into_iter()
            .find(|(_, v)| !v.is_finite())
            .map(|(name, _)| name)
    }

    pub fn to_json(&self) -> String {
        // Serialising plain data with string keys cannot fail.
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// Parses and checks `metadata.json`; `path` is used in error messages only. Refuses a
    /// major version other than ours and a minor version newer than ours, naming it.
    pub fn from_json(bytes: &[u8], path: &Path) -> Result<Metadata, FormatError> {
        let meta = Metadata::from_json_any_minor(bytes, path)?;
        if meta.version[1] > VERSION_MINOR {
            return Err(FormatError::UnsupportedVersion {
                path: path.into(),
                found: format!("{}.{}", meta.version[0], meta.version[1]),
                supported: format!("{VERSION_MAJOR}.0 to {VERSION_MAJOR}.{VERSION_MINOR}"),
            });
        }
        meta.check(path)?;
        Ok(meta)
    }

    /// As `from_json` but accepting any minor version of our major and checking no more than
    /// the members' types: for a server, which hands out the files without reading them.
    pub fn from_json_any_minor(bytes: &[u8], path: &Path) -> Result<Metadata, FormatError> {
        let value: serde_json::Value = serde_json::from_slice(bytes)
            .map_err(|e| FormatError::corrupt(path, format!("not valid JSON ({e})")))?;
        if value.get("format").and_then(|f| f.as_str()) != Some(FORMAT_NAME) {
            return Err(FormatError::corrupt(
                path,
                format!("not a Strata dataset (\"format\" is not \"{FORMAT_NAME}\")"),
            ));
        }
        let version = value
            .get("version")
            .and_then(|v| v.as_array())
            .and_then(|v| v.iter().map(|n| n.as_u64()).collect::<Option<Vec<_>>>());
        let Some(version) = version.filter(|v| v.len() == 2) else {
            // Named as found, so that a missing or malformed field is not shown as an empty
            // or wrapped version number.
            let found = value
                .get("version")
                .map_or("none".into(), |v| v.to_string());
            return Err(FormatError::corrupt(
                path,
                format!("\"version\" must be [major, minor], two whole numbers (found {found})"),
            ));
        };
        if version[0] != VERSION_MAJOR as u64 {
            return Err(FormatError::UnsupportedVersion {
                path: path.into(),
                found: format!("{}.{}", version[0], version[1]),
                supported: format!("{VERSION_MAJOR}.0 to {VERSION_MAJOR}.{VERSION_MINOR}"),
            });
        }
        serde_json::from_value(value)
            .map_err(|e| FormatError::corrupt(path, format!("malformed metadata ({e})")))
    }

    /// The real coordinates of the root cube's first and last integer positions on axis `a`.
    fn cube_ends(&self, a: usize) -> (f64, f64) {
        let first = self.cube.min[a] as f64;
        let last = first + (1u64 << self.cube.bits) as f64 - 1.0;
        (
            self.offset[a] + self.scale[a] * first,
            self.offset[a] + self.scale[a] * last,
        )
    }

    fn check(&self, path: &Path) -> Result<(), FormatError> {
        let bad = |what: &str| Err(FormatError::corrupt(path, what.to_string()));
        if self.scale.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
            return bad("scale must be finite and positive on every axis");
        }
        if self.offset.iter().any(|o| !o.is_finite()) {
            return bad("offset must be finite");
        }
        // The binary files lie in the dataset's own directory: a name that is a path could
        // make a reader open any file on the machine.
        for (what, file) in [
            ("files.hierarchy.name", &self.files.hierarchy),
            ("files.octree.name", &self.files.octree),
        ] {
            if !plain_file_name(&file.name) {
                return bad(&format!(
                    "{what} is {:?}; it must be a plain file name in the dataset's directory, \
                     not a path",
                    file.name
                ));
            }
        }
        if self.attributes.len() > MAX_ATTRIBUTES {
            return bad(&format!(
                "it lists {} attributes; a dataset has at most {MAX_ATTRIBUTES}",
                self.attributes.len()
            ));
        }
        // A reader sizes splats and picks levels by the spacing.
        if !(self.spacing.is_finite() && self.spacing > 0.0) {
            return bad("spacing must be finite and positive");
        }
        let (lo, hi) = (self.bounds.min, self.bounds.max);
        if self.points > 0
            && (0..3).any(|a| !(lo[a].is_finite() && hi[a].is_finite() && lo[a] <= hi[a]))
        {
            return bad("bounds must be finite, with min no greater than max on every axis");
        }
        if self.cube.bits > 32 {
            return bad("cube.bits must be at most 32");
        }
        // Every stored position lies in the root cube, so bounds beyond it were not made from
        // the points (a hand-edited file): a reader that fits its view to them sees nothing.
        if self.points > 0 {
            for (a, axis) in ["x", "y", "z"].into_iter().enumerate() {
                let (first, last) = self.cube_ends(a);
                if !(first.is_finite() && last.is_finite()) {
                    return bad(&format!(
                        "its scale {:e} and offset {:e} on axis {axis} put the root cube at \
                         {first:?} to {last:?}, where a coordinate is not a finite number",
                        self.scale[a], self.offset[a]
                    ));
                }
                // As `verify` allows: half a step, and the rounding of a large coordinate.
                let slack = |v: f64| 0.5 * self.scale[a] + 1e-9 * v.abs();
                if lo[a] < first - slack(first) || hi[a] > last + slack(last) {
                    return bad(&format!(
                        "the {axis} bounds {:?} to {:?} lie outside the root cube, which spans \
                         {first:?} to {last:?} in real units: no stored point can lie there",
                        lo[a], hi[a]
                    ));
                }
            }
        }
        // SPEC.md names the two; a reader that takes another name would take a tool's typo.
        if !["poisson", "random"].contains(&self.sampling.as_str()) {
            return bad(&format!(
                "sampling is {:?}; it must be \"poisson\" or \"random\"",
                self.sampling
            ));
        }
        if self.hierarchy.page_levels == 0 {
            return bad("hierarchy.page_levels must be at least 1");
        }
        if self.layout() == Layout::V1_1 {
            if self.id.is_none() {
                return bad("format 1.1 needs the dataset id (member \"id\")");
            }
            if self.hierarchy.root_page_offset != ROOT_PAGE_OFFSET {
                return bad(&format!(
                    "hierarchy.root_page_offset is {} but format 1.1 puts the root page at byte {ROOT_PAGE_OFFSET}",
                    self.hierarchy.root_page_offset
                ));
            }
            if !(2..=MAX_PAGE_LEVELS).contains(&self.hierarchy.page_levels) {
                return bad(&format!(
                    "hierarchy.page_levels is {} but format 1.1 allows 2 to {MAX_PAGE_LEVELS}",
                    self.hierarchy.page_levels
                ));
            }
            if self.hierarchy.root_page_size > u32::MAX as u64 {
                return bad("hierarchy.root_page_size does not fit the head's 32 bits");
            }
        }
        // Attributes are found by name (`rgb`, `classification`, a LAS field on export): a
        // second of one name would never be read, and an empty name names nothing.
        let mut names = std::collections::HashSet::new();
        for a in &self.attributes {
            if a.name.is_empty() || ["x", "y", "z"].contains(&a.name.as_str()) {
                return bad(&format!(
                    "an attribute is named {:?}, which names no attribute (a name is not empty, \
                     and x, y and z are the position)",
                    a.name
                ));
            }
            if !names.insert(a.name.as_str()) {
                return bad(&format!(
                    "two attributes are named '{}'; names are unique",
                    a.name
                ));
            }
            if a.count == 0 {
                return bad(&format!("attribute '{}' has count 0", a.name));
            }
            // One scale and one offset per component: a reader indexes them by component.
            for (what, values) in [("scale", &a.scale), ("offset", &a.offset)] {
                if let Some(v) = values
                    && (v.len() != a.count as usize || v.iter().any(|x| !x.is_finite()))
                {
                    return bad(&format!(
                        "attribute '{}' has {} {what} value(s) for its {} component(s); each \
                         must be a finite number, one per component",
                        a.name,
                        v.len(),
                        a.count
                    ));
                }
            }
            // A reader refuses an encoding it does not know (SPEC.md section 4): its bytes
            // mean something else than their type says.
            if let Some(encoding) = &a.encoding
                && !a.is_oct16()
            {
                return bad(&format!(
                    "attribute '{}' has encoding {encoding:?}, which this reader does not know \
                     (it knows \"{}\" on two u16)",
                    a.name,
                    crate::attribute::OCT16
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
#[path = "metadata_tests.rs"]
mod tests;
