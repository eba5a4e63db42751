//! Input readers. Each decodes its file into positions (f64) and rows of its own attributes.

pub mod las;
pub mod las_header;
pub mod las_layout;
pub mod las_normals;
pub mod laz_check;
pub mod ply;
pub mod ply_header;

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
}

#[derive(Debug, Clone)]
pub struct SourceInfo {
    pub path: PathBuf,
    pub points: u64,
    pub attributes: Vec<Attribute>,
    pub precision: Precision,
    /// What the reader changed to read the file (renamed attributes), for the user.
    pub warnings: Vec<String>,
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
}

/// Opens an input by its extension (.las, .laz, .ply, any case).
pub fn open_source(path: &Path) -> Result<Box<dyn PointSource>> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "las" | "laz" => Ok(Box::new(las::LasSource::open(path)?)),
        "ply" => Ok(Box::new(ply::PlySource::open(path)?)),
        _ => Err(ConvertError::input(
            path,
            "unknown input type (expected a .las, .laz or .ply file)",
        )),
    }
}
