//! `strata export DATASET -o DIR --format potree2`: the dataset as a Potree 2.0 dataset
//! (`metadata.json`, `hierarchy.bin`, `octree.bin`, "DEFAULT" encoding), the layout
//! PotreeConverter 2 writes and Potree 1.8+ and potree-core read. Strata's octree is Potree's,
//! node for node: the same integer cube halved per level, so each Strata node becomes the
//! Potree node of the same box and the export re-encodes nodes one at a time, in the memory of
//! one node. A DEFAULT record is the position as three i32 (Strata's own integers, with its
//! scale and offset) followed by each attribute's raw bytes: the export row layout already.

use crate::error::{ConvertError, Result};
use crate::export::{Target, Widened, widened};
use crate::ply_writer::UniqueNames;
use crate::potree2_hierarchy::{NodeData, STEP, encode};
use crate::replace::{Folder, check_output};
use crate::writers::part_path;
use rayon::prelude::*;
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::Path;
use strata_format::{AttrType, DatasetFile, LocalDataset, NodeInfo, RowLayout};

/// What the export wrote.
#[derive(Debug, Clone, Copy)]
pub struct Potree2Summary {
    pub points: u64,
    pub nodes: u64,
    pub bytes: u64,
}

/// Potree's name for a Strata attribute: the LAS ones as PotreeConverter spells them (which
/// Potree's colouring by classification, intensity or return looks for), others as they are.
fn potree_name(name: &str) -> String {
    match name {
        "gps_time" => "gps-time".into(),
        "return_number"
        | "number_of_returns"
        | "scan_direction_flag"
        | "edge_of_flight_line"
        | "classification_flags"
        | "scan_angle_rank"
        | "scan_angle"
        | "user_data"
        | "point_source_id"
        | "scanner_channel" => name.replace('_', " "),
        other => other.into(),
    }
}

/// Potree's type name. 64-bit integers never reach it: `widened` makes them doubles (Potree's
/// decoder reads no 64-bit integer type), refusing one a double would round.
fn potree_type(ty: AttrType) -> &'static str {
    match ty {
        AttrType::U8 => "uint8",
        AttrType::I8 => "int8",
        AttrType::U16 => "uint16",
        AttrType::I16 => "int16",
        AttrType::U32 => "uint32",
        AttrType::I32 => "int32",
        AttrType::F32 | AttrType::F16 => "float",
        AttrType::U64 | AttrType::I64 | AttrType::F64 => "double",
    }
}

/// One attribute of the export rows as Potree lists it, with the range of its values.
struct Column {
    name: String,
    ty: AttrType,
    count: usize,
    at: usize,
    description: String,
    scale: Option<Vec<f64>>,
    offset: Option<Vec<f64>>,
    min: Vec<f64>,
    max: Vec<f64>,
}

impl Column {
    fn json(&self) -> Value {
        let size = self.count * self.ty.size();
        let mut v = json!({
            "name": self.name,
            "description": self.description,
            "size": size,
            "numElements": self.count,
            "elementSize": self.ty.size(),
            "type": potree_type(self.ty),
            "min": self.min,
            "max": self.max,
        });
        if let (Some(s), Value::Object(m)) = (&self.scale, &mut v) {
            m.insert("scale".into(), json!(s));
        }
        if let (Some(o), Value::Object(m)) = (&self.offset, &mut v) {
            m.insert("offset".into(), json!(o));
        }
        v
    }

    /// The range of this column's values in `rows` (export rows of `stride` bytes): per
    /// element, a typed loop, so that a node costs one dispatch per column.
    fn range_in(&self, rows: &[u8], stride: usize) -> (Vec<f64>, Vec<f64>) {
        let (mut min, mut max) = (
            vec![f64::INFINITY; self.count],
            vec![f64::NEG_INFINITY; self.count],
        );
        let w = self.ty.size();
        for c in 0..self.count {
            let at = self.at + c * w;
            macro_rules! scan {
                ($t:ty, $n:literal) => {{
                    let (mut lo, mut hi) = (<$t>::MAX, <$t>::MIN);
                    for row in rows.chunks_exact(stride) {
                        let mut b = [0u8; $n];
                        b.copy_from_slice(&row[at..at + $n]);
                        let v = <$t>::from_le_bytes(b);
                        lo = if v < lo { v } else { lo };
                        hi = if v > hi { v } else { hi };
                    }
                    if !rows.is_empty() {
                        min[c] = lo as f64;
                        max[c] = hi as f64;
                    }
                }};
            }
            match self.ty {
                AttrType::U8 => scan!(u8, 1),
                AttrType::I8 => scan!(i8, 1),
                AttrType::U16 => scan!(u16, 2),
                AttrType::I16 => scan!(i16, 2),
                AttrType::U32 => scan!(u32, 4),
                AttrType::I32 => scan!(i32, 4),
                AttrType::U64 => scan!(u64, 8),
                AttrType::I64 => scan!(i64, 8),
                // Floats: NaN and the infinities are no range a viewer can scale colours to
                // (nor JSON numbers); f16 never reaches export rows (widened to f32).
                AttrType::F16 | AttrType::F32 | AttrType::F64 => {
                    for row in rows.chunks_exact(stride) {
                        let v = self.ty.read_f64(&row[at..]);
                        if v.is_finite() {
                            min[c] = min[c].min(v);
                            max[c] = max[c].max(v);
                        }
                    }
                }
            }
        }
        (min, max)
    }

    fn widen_to(&mut self, (min, max): &(Vec<f64>, Vec<f64>)) {
        for c in 0..self.count {
            self.min[c] = self.min[c].min(min[c]);
            self.max[c] = self.max[c].max(max[c]);
        }
    }
}

/// Whether Potree reads `name` (a Strata name) as one of its own attributes: such names keep
/// their Potree spelling, and another attribute that would take it (an extra-bytes field
/// named `gps-time` beside the GPS time) is the one numbered.
fn potree_reads(name: &str) -> bool {
    potree_name(name) != name
        || matches!(
            name,
            "rgb" | "intensity" | "classification" | "normal" | "nir"
        )
}

/// The columns of `layout` (export rows): a three-component f32 `normal` split into
/// NormalX, NormalY and NormalZ, the names Potree combines into its normal. Each name is
/// given once (`UniqueNames`, as PLY export's properties): Potree keys attributes by name,
/// so a second one of a name would be read as the first.
fn columns(layout: &RowLayout) -> Vec<Column> {
    let mut cols = vec![Column {
        name: "position".into(),
        ty: AttrType::I32,
        count: 3,
        at: 0,
        description: String::new(),
        scale: None,
        offset: None,
        min: vec![f64::INFINITY; 3],
        max: vec![f64::NEG_INFINITY; 3],
    }];
    for (a, &at) in layout.attributes.iter().zip(&layout.offsets) {
        let col = |name: String, count: usize, at: usize| Column {
            name,
            ty: a.ty,
            count,
            at,
            description: a.description.clone(),
            scale: a.scale.clone(),
            offset: a.offset.clone(),
            min: vec![f64::INFINITY; count],
            max: vec![f64::NEG_INFINITY; count],
        };
        if a.name == "normal" && a.count == 3 && a.ty == AttrType::F32 {
            for (c, axis) in ["NormalX", "NormalY", "NormalZ"].into_iter().enumerate() {
                cols.push(col(axis.into(), 1, at + 4 * c));
            }
        } else {
            cols.push(col(potree_name(&a.name), a.count as usize, at));
        }
    }
    // Potree's own attributes name themselves first, then the others in order. Potree reads
    // whatever is named `rgb` as 3 x uint16: without a colour, the name is no one's.
    let colour = cols.iter().any(|c| c.name == "rgb" && c.count == 3);
    let mut names = UniqueNames::new(if colour {
        &["position"]
    } else {
        &["position", "rgb"]
    });
    let own: Vec<bool> = std::iter::once(false)
        .chain(layout.attributes.iter().flat_map(|a| {
            let split = a.name == "normal" && a.count == 3 && a.ty == AttrType::F32;
            std::iter::repeat_n(potree_reads(&a.name), if split { 3 } else { 1 })
        }))
        .collect();
    for first in [true, false] {
        for (c, _) in cols
            .iter_mut()
            .zip(&own)
            .skip(1)
            .filter(|(_, o)| **o == first)
        {
            c.name = names.take(std::mem::take(&mut c.name));
        }
    }
    cols
}

/// Nodes decoded at once: enough to keep both cores busy, few enough that memory stays small.
const BATCH_NODES: usize = 32;

/// One node as Potree records, with the range of each column.
struct NodeRecords {
    rows: Vec<u8>,
    ranges: Vec<(Vec<f64>, Vec<f64>)>,
}

fn node_records(
    ds: &LocalDataset,
    node: &NodeInfo,
    wide: &Widened,
    cols: &[Column],
    output: &Path,
) -> Result<NodeRecords> {
    if node.point_count == 0 {
        return Ok(NodeRecords {
            rows: Vec::new(),
            ranges: cols.iter().map(|c| c.range_in(&[], 1)).collect(),
        });
    }
    let cols_read = ds.read_node(node)?;
    // Potree places a point by the node it is stored in: one outside that node's cube would
    // be drawn, and found, in the wrong place.
    let meta = ds.metadata();
    if let Some(i) = cols_read.first_outside(node.key, meta.cube.min, meta.cube.bits) {
        return Err(ConvertError::input(
            ds.path_of(DatasetFile::Octree),
            format!(
                "node {}: point {i} lies outside the node's cube",
                node.key.name()
            ),
        ));
    }
    let stored = cols_read.to_rows(ds.layout());
    crate::export::check_finite(ds.dir(), meta, &node.key, &stored, ds.layout().stride)?;
    let rows = if wide.is_identity() {
        stored
    } else {
        let mut out = Vec::new();
        wide.convert(&stored, &mut out, output)
            .map_err(|e| e.placed(ds.dir(), &node.key, |r| r))?;
        out
    };
    let ranges = cols
        .iter()
        .map(|c| c.range_in(&rows, wide.layout.stride))
        .collect();
    Ok(NodeRecords { rows, ranges })
}

/// A Potree 2.0 dataset is a folder: a name that ends as a point file's (`city.las`) asked for
/// that file, which `export` writes without `--format potree2`.
pub fn refuse_file_name(output: &Path) -> Result<()> {
    let name = output
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    match [".las", ".laz", ".ply", ".e57"]
        .iter()
        .find(|ext| name.ends_with(*ext))
    {
        Some(ext) => Err(ConvertError::output(
            output,
            format!(
                "ends in {ext}, a point file's name, but a Potree 2.0 dataset is a folder: give the folder a name without it"
            ),
        )),
        None => Ok(()),
    }
}

/// Writes `dataset` to the folder `output` as a Potree 2.0 dataset. The folder appears
/// whole or not at all: it is written as `OUTPUT.part` and renamed at the end.
pub fn export_potree2(dataset: &Path, output: &Path, overwrite: bool) -> Result<Potree2Summary> {
    crate::replace::refuse_source(dataset, output)?;
    check_output(output, overwrite, Folder::Dataset)?;
    refuse_file_name(output)?;
    let ds = LocalDataset::open(dataset)?;
    // octree.bin holds every export row uncompressed (the hierarchy is 22 bytes a node): refused
    // now rather than when the disk fills.
    let records = ds.metadata().points * widened(ds.layout(), Target::Potree2).layout.stride as u64;
    crate::disk::check_space(&[(output, records + 22 * ds.metadata().nodes)])?;
    // Potree names a dataset after its folder.
    let name = output
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let part = part_path(output);
    let _ = fs::remove_dir_all(&part);
    fs::create_dir_all(&part).map_err(|e| ConvertError::io(&part, "cannot create", e))?;
    let written = write_dataset(&ds, &part, &name, output).and_then(|summary| {
        if output.exists() {
            fs::remove_dir_all(output)
                .map_err(|e| ConvertError::io(output, "cannot replace", e))?;
        }
        fs::rename(&part, output)
            .map_err(|e| ConvertError::io(output, "cannot move into place", e))?;
        Ok(summary)
    });
    if written.is_err() {
        let _ = fs::remove_dir_all(&part);
    }
    written
}

/// Writes the Potree 2.0 files into `dir`; `output` (its final name) is named in errors about
/// the points.
fn write_dataset(
    ds: &LocalDataset,
    dir: &Path,
    name: &str,
    output: &Path,
) -> Result<Potree2Summary> {
    let meta = ds.metadata();
    let layout = ds.layout();
    let wide = widened(layout, Target::Potree2);
    let mut cols = columns(&wide.layout);
    let octree_path = dir.join("octree.bin");
    let io = |p: &Path| {
        let p = p.to_path_buf();
        move |e: std::io::Error| ConvertError::io(&p, "cannot write", e)
    };
    let file = File::create(&octree_path).map_err(io(&octree_path))?;
    let mut out = BufWriter::with_capacity(1 << 20, file);
    let (mut nodes, mut offset, mut points) = (BTreeMap::new(), 0u64, 0u64);
    let all = ds.all_nodes()?;
    // Nodes are decoded, turned into records and measured in parallel, a batch at a time, and
    // written in order: memory stays that of one batch.
    for batch in all.chunks(BATCH_NODES) {
        let done: Vec<Result<NodeRecords>> = batch
            .par_iter()
            .map(|node| node_records(ds, node, &wide, &cols, output))
            .collect();
        for (node, records) in batch.iter().zip(done) {
            let records = records?;
            for (c, range) in cols.iter_mut().zip(&records.ranges) {
                c.widen_to(range);
            }
            out.write_all(&records.rows).map_err(io(&octree_path))?;
            let size = records.rows.len() as u64;
            nodes.insert(
                node.key,
                NodeData {
                    points: node.point_count,
                    offset: if size > 0 { offset } else { 0 },
                    size,
                },
            );
            offset += size;
            points += node.point_count as u64;
        }
    }
    // The nodes' counts add up to the dataset's, or some were lost or repeated.
    if points != meta.points {
        return Err(ConvertError::input(
            ds.path_of(DatasetFile::Metadata),
            format!(
                "says the dataset holds {} points, but its nodes hold {points}",
                meta.points
            ),
        ));
    }
    let file = out
        .into_inner()
        .map_err(|e| ConvertError::io(&octree_path, "cannot write", e.into_error()))?;
    file.sync_all().map_err(io(&octree_path))?;

    let hierarchy = encode(&nodes);
    let hierarchy_path = dir.join("hierarchy.bin");
    fs::write(&hierarchy_path, &hierarchy.bytes).map_err(io(&hierarchy_path))?;

    let real = |k: usize, v: i64| meta.offset[k] + meta.scale[k] * v as f64;
    let side = 1i64 << meta.cube.bits;
    let cube_min: Vec<f64> = (0..3).map(|k| real(k, meta.cube.min[k])).collect();
    let cube_max: Vec<f64> = (0..3).map(|k| real(k, meta.cube.min[k] + side)).collect();
    // An element with no value (no points, or none finite): 0 to 0, a range a viewer can
    // take, where null is none.
    for c in cols.iter_mut() {
        for (lo, hi) in c.min.iter_mut().zip(c.max.iter_mut()) {
            if *lo > *hi {
                (*lo, *hi) = (0.0, 0.0);
            }
        }
    }
    // The position's range in the dataset's coordinates, as PotreeConverter states it.
    for k in 0..3 {
        cols[0].min[k] = real(k, cols[0].min[k] as i64);
        cols[0].max[k] = real(k, cols[0].max[k] as i64);
    }
    let attributes: Vec<Value> = cols.iter().map(Column::json).collect();
    let metadata = json!({
        "version": "2.0",
        "name": name,
        "description": format!("written by Strata {}", env!("CARGO_PKG_VERSION")),
        "points": points,
        "projection": meta.crs.as_ref().and_then(|c| c.wkt.clone()).unwrap_or_default(),
        "hierarchy": {
            "firstChunkSize": hierarchy.first_chunk_size,
            "stepSize": STEP,
            "depth": hierarchy.depth,
        },
        "offset": meta.offset,
        "scale": meta.scale,
        "spacing": meta.spacing,
        "boundingBox": { "min": cube_min, "max": cube_max },
        "encoding": "DEFAULT",
        "attributes": attributes,
    });
    let text = serde_json::to_string_pretty(&metadata)
        .map_err(|e| ConvertError::output(dir, format!("cannot encode metadata.json ({e})")))?;
    // Last, so that a folder with metadata.json has the files it names.
    let metadata_path = dir.join("metadata.json");
    fs::write(&metadata_path, text).map_err(io(&metadata_path))?;
    Ok(Potree2Summary {
        points,
        nodes: nodes.len() as u64,
        bytes: offset + hierarchy.bytes.len() as u64,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use strata_format::Attribute;

    /// Rows of `layout` from each point's position and attribute bytes.
    fn rows_of(points: &[(i32, Vec<u8>)]) -> Vec<u8> {
        let mut rows = Vec::new();
        for (x, attrs) in points {
            for _ in 0..3 {
                rows.extend_from_slice(&x.to_le_bytes());
            }
            rows.extend_from_slice(attrs);
        }
        rows
    }

    #[test]
    fn ranges_are_typed_and_64_bit_integers_go_out_as_doubles_only_where_exact() {
        let layout = RowLayout::new(vec![
            Attribute::new("intensity", AttrType::U16, 1),
            Attribute::new("ticks", AttrType::I64, 1),
            Attribute::new("gps_time", AttrType::F64, 1),
        ]);
        let point = |x: i32, i: u16, t: i64, g: f64| {
            let mut b = i.to_le_bytes().to_vec();
            b.extend_from_slice(&t.to_le_bytes());
            b.extend_from_slice(&g.to_le_bytes());
            (x, b)
        };
        let rows = rows_of(&[point(-5, 700, -3, 2.5), point(9, 65535, 1 << 40, -1.0)]);
        let wide = widened(&layout, Target::Potree2);
        let mut out = Vec::new();
        wide.convert(&rows, &mut out, Path::new("p2"))
            .expect("exact");
        let cols = columns(&wide.layout);
        let names: Vec<&str> = cols.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["position", "intensity", "ticks", "gps-time"]);
        let ranges: Vec<_> = cols
            .iter()
            .map(|c| c.range_in(&out, wide.layout.stride))
            .collect();
        assert_eq!(ranges[0], (vec![-5.0; 3], vec![9.0; 3]));
        assert_eq!(ranges[1], (vec![700.0], vec![65535.0]));
        assert_eq!(ranges[2], (vec![-3.0], vec![(1u64 << 40) as f64]));
        assert_eq!(ranges[3], (vec![-1.0], vec![2.5]));
        assert_eq!(cols[2].json()["type"], "double");
        let at = wide.layout.offsets[1];
        let tick = |r: usize| AttrType::F64.read_f64(&out[r * wide.layout.stride + at..]);
        assert_eq!((tick(0), tick(1)), (-3.0, (1u64 << 40) as f64));
        // One a double would round is refused, as PLY export refuses it, not rounded.
        let big = (1i64 << 53) + 1;
        let rows = rows_of(&[point(0, 1, 5, 0.0), point(1, 1, big, 0.0)]);
        let e = wide
            .convert(&rows, &mut out, Path::new("p2"))
            .expect_err("rounded")
            .to_string();
        assert!(
            e.contains("ticks is 9007199254740993")
                && e.contains("no Potree 2.0 attribute holds exactly"),
            "{e}"
        );
    }

    #[test]
    fn colour_is_16_bit_normals_are_floats_and_names_are_unique() {
        let layout = RowLayout::new(vec![
            Attribute::new("gps-time", AttrType::F64, 1),
            Attribute::new("rgb", AttrType::U8, 3),
            Attribute::new("normal", AttrType::F64, 3),
            Attribute::new("gps_time", AttrType::F64, 1),
        ]);
        let mut b = 7.0f64.to_le_bytes().to_vec();
        b.extend_from_slice(&[255, 128, 0]);
        for n in [0.6f64, 0.8, 0.0] {
            b.extend_from_slice(&n.to_le_bytes());
        }
        b.extend_from_slice(&1.5f64.to_le_bytes());
        let rows = rows_of(&[(0, b)]);
        let wide = widened(&layout, Target::Potree2);
        let mut out = Vec::new();
        wide.convert(&rows, &mut out, Path::new("p2"))
            .expect("fits");
        let cols = columns(&wide.layout);
        let shapes: Vec<(&str, &str, usize)> = cols
            .iter()
            .map(|c| (c.name.as_str(), potree_type(c.ty), c.count))
            .collect();
        assert_eq!(
            shapes,
            [
                ("position", "int32", 3),
                ("gps-time_1", "double", 1),
                ("rgb", "uint16", 3),
                ("NormalX", "float", 1),
                ("NormalY", "float", 1),
                ("NormalZ", "float", 1),
                ("gps-time", "double", 1),
            ]
        );
        let rgb: Vec<u16> = (0..3)
            .map(|c| {
                let at = cols[2].at + 2 * c;
                u16::from_le_bytes([out[at], out[at + 1]])
            })
            .collect();
        assert_eq!(rgb, [65535, 128 * 257, 0]);
        let normal: Vec<f64> = (3..6)
            .map(|c| AttrType::F32.read_f64(&out[cols[c].at..]))
            .collect();
        assert_eq!(normal, [0.6f32 as f64, 0.8f32 as f64, 0.0]);
        // A scalar named `rgb` (a LAS extra-bytes field) is no colour: Potree would read it
        // as one.
        let scalar = RowLayout::new(vec![Attribute::new("rgb", AttrType::U8, 1)]);
        let names: Vec<String> = columns(&scalar).into_iter().map(|c| c.name).collect();
        assert_eq!(names, ["position", "rgb_1"]);
    }
}
