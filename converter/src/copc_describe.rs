//! Reading a LAS, LAZ or COPC file's header for `strata info`: the checks the conversion
//! makes, then for COPC the octree and hierarchy it states.

use crate::copc::{ENTRY_SIZE, INFO_SIZE};
use crate::error::{ConvertError, Result};
use crate::input::las_header::{LasHeader, read_at};
use std::fs::File;
use std::path::Path;

/// The deepest level a hierarchy entry may name: a node's cells are 32-bit in COPC's key.
const MAX_DEPTH: i32 = 31;

/// What `strata info` says of a COPC file: its octree and its hierarchy.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CopcSummary {
    pub centre: [f64; 3],
    pub halfsize: f64,
    pub spacing: f64,
    pub gps_time: [f64; 2],
    /// Hierarchy entries with points, and the deepest level.
    pub nodes: u64,
    pub depth: i32,
    /// Points the hierarchy lists.
    pub points: u64,
}

/// What `strata info` says of a LAS, LAZ or COPC file.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FileSummary {
    /// "las", "laz" or "copc".
    pub kind: &'static str,
    pub version: String,
    pub point_format: u8,
    pub points: u64,
    pub min: [f64; 3],
    pub max: [f64; 3],
    pub scale: [f64; 3],
    pub offset: [f64; 3],
    pub copc: Option<CopcSummary>,
}

/// Reads the header (and, for COPC, the hierarchy) of the LAS/LAZ file `path`.
pub fn describe(path: &Path) -> Result<FileSummary> {
    // The conversion's checks first: a damaged file is named as `convert` names it, not by
    // the reader's first failed read.
    let file = File::open(path).map_err(|e| ConvertError::io(path, "cannot open", e))?;
    let len = file
        .metadata()
        .map_err(|e| ConvertError::io(path, "cannot read file size", e))?
        .len();
    let raw = LasHeader::read(&file, len).map_err(|e| ConvertError::input(path, e))?;
    if raw.compressed {
        crate::input::laz_check::check_laz(&file, &raw)
            .map_err(|e| ConvertError::input(path, e))?;
    } else {
        // The header's count is what is printed: a file that does not hold those records is
        // refused as `convert` refuses it, not summed up as if whole.
        raw.check_uncompressed_records()
            .map_err(|e| ConvertError::input(path, e))?;
    }
    let reader = las::Reader::from_path(path)
        .map_err(|e| ConvertError::output(path, format!("not a LAS or LAZ file ({e})")))?;
    let h = reader.header();
    let copc = read_summary(&raw, &file, path)?;
    let (b, t, v, format) = (h.bounds(), h.transforms(), h.version(), h.point_format());
    Ok(FileSummary {
        kind: match (&copc, format.is_compressed) {
            (Some(_), _) => "copc",
            (None, true) => "laz",
            (None, false) => "las",
        },
        version: format!("{}.{}", v.major, v.minor),
        point_format: format.to_u8().unwrap_or(0),
        points: h.number_of_points(),
        min: [b.min.x, b.min.y, b.min.z],
        max: [b.max.x, b.max.y, b.max.z],
        scale: [t.x.scale, t.y.scale, t.z.scale],
        offset: [t.x.offset, t.y.offset, t.z.offset],
        copc,
    })
}

/// The COPC info of a LAS/LAZ file whose first VLR is COPC's, with its hierarchy summed up;
/// `None` for a file that is not COPC. The records come from our own header reader: the las
/// crate keeps only the first EVLR, and a writer may put another (a CRS) before the hierarchy.
fn read_summary(raw: &LasHeader, file: &File, path: &Path) -> Result<Option<CopcSummary>> {
    let Some(info) = raw.vlrs.first().filter(|v| v.is("copc", 1)) else {
        return Ok(None);
    };
    let bad = |what: &str| ConvertError::output(path, format!("COPC {what}"));
    if info.data_len < INFO_SIZE {
        return Err(bad("info VLR is shorter than 160 bytes"));
    }
    let read = |at: u64, len: u64| {
        read_at(file, at, len as usize).map_err(|e| bad(&format!("record cannot be read: {e}")))
    };
    let d = read(info.data_at, INFO_SIZE)?;
    let f = |i: usize| f64::from_le_bytes(d[i * 8..i * 8 + 8].try_into().unwrap_or([0; 8]));
    let hierarchy = raw
        .find("copc", 1000)
        .ok_or_else(|| bad("hierarchy EVLR is missing"))?;
    // What a COPC reader takes on trust: the cube, and where the root hierarchy page is.
    let u = |i: usize| u64::from_le_bytes(d[i * 8..i * 8 + 8].try_into().unwrap_or([0; 8]));
    if let Some(name) = [("centre", f(0)), ("centre", f(1)), ("centre", f(2))]
        .into_iter()
        .chain([("half size", f(3)), ("spacing", f(4))])
        .find(|&(name, v)| !v.is_finite() || (name != "centre" && v <= 0.0))
        .map(|(name, _)| name)
    {
        return Err(bad(&format!(
            "info VLR's {name} is not a finite{} number",
            if name == "centre" { "" } else { " positive" }
        )));
    }
    let (root_at, root_size) = (u(5), u(6));
    let (data_at, data_end) = (
        hierarchy.data_at,
        hierarchy.data_at.saturating_add(hierarchy.data_len),
    );
    // Pages are whole entries on the EVLR's grid of entries: a page begun mid-entry gives a
    // reader other entries than those checked below.
    let on_grid = |at: u64| at >= data_at && (at - data_at).is_multiple_of(ENTRY_SIZE as u64);
    if hierarchy.data_len % ENTRY_SIZE as u64 != 0 {
        return Err(bad(&format!(
            "hierarchy EVLR is {} bytes long, not whole entries of {ENTRY_SIZE}",
            hierarchy.data_len
        )));
    }
    if root_size == 0
        || root_size % ENTRY_SIZE as u64 != 0
        || !on_grid(root_at)
        || root_at
            .checked_add(root_size)
            .is_none_or(|end| end > data_end)
    {
        return Err(bad(&format!(
            "info VLR puts the root hierarchy page at byte {root_at}, {root_size} bytes long, \
             which is not a page of whole entries inside the hierarchy EVLR \
             (bytes {data_at} to {data_end})"
        )));
    }
    let hierarchy = read(data_at, hierarchy.data_len)?;
    let (mut nodes, mut depth, mut points) = (0u64, 0i32, 0u64);
    let chunks = (raw.offset_to_points, raw.points_end());
    // Every entry of the EVLR (the pages a writer puts there one after the other; entries
    // of -1 points, pointing at pages elsewhere, are not counted), each checked as a reader
    // takes it on trust: its node inside the octree, its chunk among the points, its page
    // inside the hierarchy.
    for (k, e) in hierarchy.chunks_exact(ENTRY_SIZE).enumerate() {
        let int = |i: usize| i32::from_le_bytes(e[i..i + 4].try_into().unwrap_or([0; 4]));
        let (key, count) = ([int(0), int(4), int(8), int(12)], int(28));
        let (at, size) = (
            u64::from_le_bytes(e[16..24].try_into().unwrap_or([0; 8])),
            i64::from(int(24)),
        );
        let entry = |fault: String| {
            let [d, x, y, z] = key;
            bad(&format!(
                "hierarchy entry {k} (node {d}-{x}-{y}-{z}) {fault}"
            ))
        };
        let side = 1i64.checked_shl(key[0].clamp(0, 62) as u32).unwrap_or(0);
        if !(0..=MAX_DEPTH).contains(&key[0])
            || key[1..].iter().any(|&c| !(0..side).contains(&i64::from(c)))
        {
            return Err(entry("names no node of an octree".into()));
        }
        let (lo, hi, what) = match count {
            -1 => (data_at, data_end, "page inside the hierarchy EVLR"),
            0 => continue,
            c if c > 0 => (chunks.0, chunks.1, "chunk among the point data"),
            c => return Err(entry(format!("holds {c} points"))),
        };
        let end = u64::try_from(size).ok().and_then(|n| at.checked_add(n));
        let whole_page = count != -1 || (size % ENTRY_SIZE as i64 == 0 && on_grid(at));
        if size <= 0 || at < lo || end.is_none_or(|end| end > hi) {
            return Err(entry(format!(
                "puts its {what} at byte {at}, {size} bytes long, outside bytes {lo} to {hi}"
            )));
        }
        if !whole_page {
            return Err(entry(format!(
                "puts its page at byte {at}, {size} bytes long, which is not whole entries of \
                 the hierarchy EVLR"
            )));
        }
        if count > 0 {
            nodes += 1;
            points += count as u64;
            depth = depth.max(key[0]);
        }
    }
    if points != raw.points {
        return Err(bad(&format!(
            "hierarchy lists {points} points, and the header {}",
            raw.points
        )));
    }
    Ok(Some(CopcSummary {
        centre: [f(0), f(1), f(2)],
        halfsize: f(3),
        spacing: f(4),
        gps_time: [f(7), f(8)],
        nodes,
        depth,
        points,
    }))
}
