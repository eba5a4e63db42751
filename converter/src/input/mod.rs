//! Input readers. Each decodes its file into positions (f64) and rows of its own attributes.

pub mod e57;
pub mod e57_decode;
mod e57_extras;
pub mod e57_header;
mod e57_limits;
mod e57_section;
pub mod las;
pub mod las_header;
pub mod las_layout;
pub mod las_normals;
pub mod laz_check;
pub mod laz_chunks;
pub mod ply;
pub mod ply_header;
mod ply_skip;

use crate::error::{ConvertError, Result};
use std::path::{Path, PathBuf};
use strata_format::Attribute;

/// How an input stores coordinates; decides the dataset's scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Precision {
    /// Integers with a scale and offset (LAS).
    Scaled {
        scale: [f64; 3],
        offset: [f64; 3],
    },
    Float32,
    Float64,
    Integer,
    /// Real coordinates known to within a step on each axis but on no shared grid: E57 scaled
    /// integers, which the scan's pose rotates off their grid.
    Resolution([f64; 3]),
}

/// The attribute (u16) that names the scan a point came from: an index into the dataset's list
/// of scanner positions (`Plan::scanners`, `scanners` in metadata.json). Sources number their
/// scans from the base `PointSource::set_scanner_base` gives them, so indices are global
/// across inputs: input i's scans follow those of inputs 0..i-1.
pub const SCANNER: &str = "scanner";

/// Renames an attribute of a file that holds no scan poses (a PLY property, a LAS extra-bytes
/// field) named `scanner` to `extra_scanner` (then `extra_scanner_2`, ...): its values index no
/// scanner position of the dataset, and taken for `SCANNER` they oriented normals towards
/// another input's scanners, or let `--orient scanner` run where no scanner was known. The
/// warning for the user, where one was renamed.
pub fn keep_scanner_name_free(attributes: &mut [Attribute]) -> Option<String> {
    let at = attributes.iter().position(|a| a.name == SCANNER)?;
    let new = extra_name(SCANNER, |n| attributes.iter().any(|a| a.name == n));
    attributes[at].name = new.clone();
    Some(format!(
        "its \"{SCANNER}\" attribute names no scan this dataset knows the position of (only an \
         E57 file's scans have one); kept as \"{new}\""
    ))
}

/// The name a field called `name` is kept under where that one is taken: `extra_NAME`, then
/// `extra_NAME_2`, ..., the first of them not `taken`.
pub fn extra_name(name: &str, taken: impl Fn(&str) -> bool) -> String {
    let base = format!("extra_{name}");
    let mut new = base.clone();
    let mut n = 2;
    while taken(&new) {
        new = format!("{base}_{n}");
        n += 1;
    }
    new
}

/// The `scanner` value of points whose input says nothing of scanners (LAS or PLY converted
/// together with E57). Every index at or above the list's length means "no known scanner".
pub const NO_SCANNER: u16 = u16::MAX;

#[derive(Debug, Clone)]
pub struct SourceInfo {
    pub path: PathBuf,
    pub points: u64,
    pub attributes: Vec<Attribute>,
    pub precision: Precision,
    /// What the reader changed to read the file (renamed attributes), for the user.
    pub warnings: Vec<String>,
    /// Where the scanner of each of the file's scans stood, in world coordinates (E57 poses);
    /// empty for inputs that do not say. The rows' `scanner` attribute indexes this list, from
    /// the source's base on.
    pub scanners: Vec<[f64; 3]>,
    /// The coordinate reference system the file states (LAS), if any.
    pub crs: Option<strata_format::Crs>,
    /// Its `gps_time` counts from a start the file does not give (an E57 scan without
    /// acquisitionStart): beside times of a base it would be read in that base. A time of no
    /// stated base otherwise (a PLY's) may be of any, and takes the others'.
    pub time_from_unknown_start: bool,
}

impl SourceInfo {
    /// Bytes of one attribute row of this source.
    pub fn row_len(&self) -> usize {
        self.attributes.iter().map(|a| a.size()).sum()
    }
}

pub trait PointSource {
    fn info(&self) -> &SourceInfo;
    /// Decodes up to `max` points, appending positions to `xyz` and attribute rows (in
    /// `info().attributes` order) to `rows`. Returns how many were decoded; 0 at the end.
    fn read(&mut self, max: usize, xyz: &mut Vec<[f64; 3]>, rows: &mut Vec<u8>) -> Result<usize>;
    /// Sets the index the rows' `scanner` attribute gives this source's first scan (0 unless
    /// set); called before the first `read`. Sources without scanners ignore it.
    fn set_scanner_base(&mut self, _first: u16) {}
}

/// Opens an input by its extension (.las, .laz, .ply, .e57, any case).
pub fn open_source(path: &Path) -> Result<Box<dyn PointSource>> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "las" | "laz" => Ok(Box::new(las::LasSource::open(path)?)),
        "ply" => Ok(Box::new(ply::PlySource::open(path)?)),
        "e57" => Ok(Box::new(e57::E57Source::open(path)?)),
        _ => Err(ConvertError::input(
            path,
            "unknown input type (expected a .las, .laz, .ply or .e57 file)",
        )),
    }
}
