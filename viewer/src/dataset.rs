//! An open dataset seen through a `Source`: metadata, hierarchy pages on demand, and nodes decoded
//! into the GPU point format.

use crate::pipelines::PointStream;
use crate::{HttpOptions, HttpSource, MmapSource, Source, ViewerError};
use glam::{DVec3, Vec3};
use std::path::Path;
use std::sync::{Arc, Mutex, PoisonError};
use strata_format::{
    AttrType, DatasetFile, GRID_CELLS_LOG2, HierarchyPage, Metadata, NodeColumns, NodeInfo,
    NodeKey, PageRef, RowLayout, decode_node, decode_page,
};

/// One node ready for upload: per point `[x, y, z, colour]` (f32 bits, then packed RGBA8) and
/// `intensity16 | classification << 16 | return_number << 24` (raw intensity, return number up
/// to 15).
pub struct GpuNode {
    pub key: NodeKey,
    pub points: Vec<[u32; 4]>,
    pub attributes: Vec<u32>,
    /// Per-point streams beyond position and colour that the dataset stores (normals, radius),
    /// as the GPU reads them: `PointStream::bytes_per_point` bytes a point.
    pub streams: Vec<(PointStream, Vec<u8>)>,
    /// Stored (compressed) bytes read for this node.
    pub bytes_read: u64,
}

/// How stored attributes become colours; decided once from the root node.
#[derive(Debug, Clone, Copy)]
struct ColourSource {
    rgb: Option<(usize, AttrType)>,
    rgb_shift: u32,
    intensity: Option<(usize, AttrType)>,
    intensity_max: f64,
    classification: Option<(usize, AttrType)>,
    return_number: Option<(usize, AttrType)>,
}

pub struct StreamDataset {
    source: Arc<dyn Source>,
    metadata: Metadata,
    /// The root page, read at open: the renderer starts from it without asking again.
    root: HierarchyPage,
    /// The root node, read at open to learn the colours, until the renderer first asks for it.
    root_node: Mutex<Option<(NodeInfo, NodeColumns)>>,
    layout: RowLayout,
    anchor: DVec3,
    colour: ColourSource,
}

impl StreamDataset {
    /// Opens `http://HOST:PORT/DATASET` or a local dataset directory.
    pub fn open(location: &str, http: HttpOptions) -> Result<StreamDataset, ViewerError> {
        if location.starts_with("http://") || location.starts_with("https://") {
            let (source, metadata) = HttpSource::open(location, http)?;
            StreamDataset::from_source(Arc::new(source), metadata)
        } else {
            StreamDataset::open_path(Path::new(location))
        }
    }

    /// Opens a local dataset directory.
    pub fn open_path(dir: &Path) -> Result<StreamDataset, ViewerError> {
        let (source, metadata) = MmapSource::open(dir)?;
        StreamDataset::from_source(Arc::new(source), metadata)
    }

    /// Opens a dataset from any source whose metadata has been read; reads the root page and
    /// root node to learn the colour encoding.
    pub fn from_source(
        source: Arc<dyn Source>,
        metadata: Metadata,
    ) -> Result<StreamDataset, ViewerError> {
        let layout = metadata.row_layout();
        let edge = (1u64 << metadata.cube.bits) as f64;
        let anchor = DVec3::from_array(std::array::from_fn(|i| {
            metadata.offset[i] + metadata.scale[i] * (metadata.cube.min[i] as f64 + edge * 0.5)
        }));
        let find = |name: &str| layout.index_of(name).map(|i| (i, layout.attributes[i].ty));
        // Colour is only usable as three components.
        let rgb = layout
            .index_of("rgb")
            .filter(|&i| layout.attributes[i].count == 3)
            .map(|i| (i, layout.attributes[i].ty));
        let root = decode_root(source.as_ref(), &metadata)?;
        let mut ds = StreamDataset {
            source,
            root,
            root_node: Mutex::new(None),
            colour: ColourSource {
                rgb,
                rgb_shift: 0,
                intensity: find("intensity"),
                intensity_max: 1.0,
                classification: find("classification"),
                return_number: find("return_number"),
            },
            metadata,
            layout,
            anchor,
        };
        if let Some(info) = ds.root.root_node()
            && info.point_count > 0
        {
            let columns = ds.read_columns(&info)?;
            ds.colour = ds.learn_colour(&columns);
            ds.root_node = Mutex::new(Some((info, columns)));
        }
        Ok(ds)
    }

    pub fn location(&self) -> String {
        self.source.location()
    }

    pub fn metadata(&self) -> &Metadata {
        &self.metadata
    }

    /// Real-world position of the anchor that all viewer coordinates are relative to.
    pub fn anchor(&self) -> DVec3 {
        self.anchor
    }

    /// The intensity shown at full brightness (the 99th percentile of the root node's).
    pub fn intensity_max(&self) -> f64 {
        self.colour.intensity_max
    }

    pub fn has_rgb(&self) -> bool {
        self.colour.rgb.is_some()
    }

    /// Bounds of the stored points relative to the anchor.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let b = &self.metadata.bounds;
        (
            (DVec3::from_array(b.min) - self.anchor).as_vec3(),
            (DVec3::from_array(b.max) - self.anchor).as_vec3(),
        )
    }

    /// A node's cube relative to the anchor: minimum corner and edge length.
    pub fn node_cube(&self, key: NodeKey) -> (Vec3, f32) {
        let m = &self.metadata;
        let (min, edge) = key.int_bounds(m.cube.min, m.cube.bits);
        let real = DVec3::from_array(std::array::from_fn(|i| {
            m.offset[i] + m.scale[i] * min[i] as f64
        }));
        (
            (real - self.anchor).as_vec3(),
            (edge as f64 * m.scale[0]) as f32,
        )
    }

    /// Distance between a node's points in world units (one sampling cell).
    pub fn node_spacing(&self, key: NodeKey) -> f32 {
        let (_, edge) = self.node_cube(key);
        edge / (1u32 << GRID_CELLS_LOG2) as f32
    }

    pub fn root_page(&self) -> PageRef {
        self.metadata.root_page()
    }

    /// The root page, decoded at open.
    pub fn root_hierarchy_page(&self) -> &HierarchyPage {
        &self.root
    }

    pub fn load_page(&self, page: &PageRef) -> Result<HierarchyPage, ViewerError> {
        load_page(self.source.as_ref(), &self.metadata, page)
    }

    pub(crate) fn read_columns(&self, info: &NodeInfo) -> Result<NodeColumns, ViewerError> {
        let payload = self
            .source
            .read(DatasetFile::Octree, info.offset, info.size as u64)?;
        decode_node(
            &payload,
            info.point_count as usize,
            info.checksum,
            &self.layout,
        )
        .map_err(|e| {
            ViewerError::source(
                format!("{}/{}", self.location(), DatasetFile::Octree.name()),
                format!("node {}: {e}", info.key),
            )
        })
    }

    /// Reads, verifies, decompresses and converts one node.
    pub fn load_node(&self, info: &NodeInfo) -> Result<GpuNode, ViewerError> {
        let mut kept = self
            .root_node
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        if let Some((root, columns)) = kept.take_if(|(root, _)| root == info) {
            drop(kept);
            return Ok(self.to_gpu(&root, &columns));
        }
        drop(kept);
        let columns = self.read_columns(info)?;
        Ok(self.to_gpu(info, &columns))
    }

    fn learn_colour(&self, root: &NodeColumns) -> ColourSource {
        let mut c = self.colour;
        if let Some((i, ty)) = c.rgb {
            let col = root.attribute(&self.layout, i);
            let max = col
                .chunks_exact(ty.size())
                .map(|v| ty.read_f64(v))
                .fold(0.0, f64::max);
            // 16-bit LAS colour is often 8-bit values stored in 16 bits.
            c.rgb_shift = if ty.size() >= 2 && max > 255.0 { 8 } else { 0 };
        }
        if let Some((i, ty)) = c.intensity {
            let mut values: Vec<f64> = root
                .attribute(&self.layout, i)
                .chunks_exact(ty.size())
                .map(|v| ty.read_f64(v))
                .collect();
            values.sort_by(f64::total_cmp);
            // The 99th percentile: a few saturated returns should not darken everything.
            let p99 = values
                .get(values.len().saturating_sub(1) * 99 / 100)
                .copied()
                .unwrap_or(1.0);
            c.intensity_max = if p99 > 0.0 { p99 } else { 1.0 };
        }
        c
    }

    fn to_gpu(&self, info: &NodeInfo, cols: &NodeColumns) -> GpuNode {
        let n = cols.count;
        let m = &self.metadata;
        let base = DVec3::from_array(m.offset) - self.anchor;
        let scale = DVec3::from_array(m.scale);
        let column = |c: usize| &cols.bytes[c * n * 4..(c + 1) * n * 4];
        let (xs, ys, zs) = (column(0), column(1), column(2));
        let read_i32 = |b: &[u8], i: usize| {
            i32::from_le_bytes([b[i * 4], b[i * 4 + 1], b[i * 4 + 2], b[i * 4 + 3]]) as f64
        };
        let c = &self.colour;
        let rgb = c.rgb.map(|(i, ty)| (cols.attribute(&self.layout, i), ty));
        let intensity = c
            .intensity
            .map(|(i, ty)| (cols.attribute(&self.layout, i), ty));
        let class = c
            .classification
            .map(|(i, ty)| (cols.attribute(&self.layout, i), ty));
        let returns = c
            .return_number
            .map(|(i, ty)| (cols.attribute(&self.layout, i), ty));
        let mut points = Vec::with_capacity(n);
        let mut attributes = Vec::with_capacity(n);
        for p in 0..n {
            let x = base.x + scale.x * read_i32(xs, p);
            let y = base.y + scale.y * read_i32(ys, p);
            let z = base.z + scale.z * read_i32(zs, p);
            let colour = match rgb {
                Some((col, ty)) => {
                    let s = ty.size();
                    let ch = |k: usize| {
                        let v = ty.read_f64(&col[(p * 3 + k) * s..(p * 3 + k + 1) * s]) as u32;
                        (v >> c.rgb_shift).min(255)
                    };
                    ch(0) | (ch(1) << 8) | (ch(2) << 16) | (255 << 24)
                }
                None => 0xffc8_c8c8,
            };
            // Raw, so that filters compare stored values; colouring scales it on the GPU.
            let inten = intensity.map_or(0, |(col, ty)| {
                let s = ty.size();
                ty.read_f64(&col[p * s..(p + 1) * s]).clamp(0.0, 65535.0) as u32
            });
            let ret = returns.map_or(0, |(col, ty)| {
                let s = ty.size();
                (ty.read_f64(&col[p * s..(p + 1) * s]) as u32).min(15)
            });
            let cls = class.map_or(0, |(col, ty)| {
                let s = ty.size();
                ty.read_f64(&col[p * s..(p + 1) * s]) as u32 & 0xff
            });
            points.push([
                (x as f32).to_bits(),
                (y as f32).to_bits(),
                (z as f32).to_bits(),
                colour,
            ]);
            attributes.push(inten | (cls << 16) | (ret << 24));
        }
        GpuNode {
            key: info.key,
            points,
            attributes,
            // No stored attribute feeds a stream yet: normals and radii arrive with the
            // format's normal and radius attributes.
            streams: Vec::new(),
            bytes_read: info.size as u64,
        }
    }
}

/// Reads and decodes one hierarchy page from `source`.
fn load_page(
    source: &dyn Source,
    metadata: &Metadata,
    page: &PageRef,
) -> Result<HierarchyPage, ViewerError> {
    let bytes = source.read(DatasetFile::Hierarchy, page.offset, page.size)?;
    let levels = metadata.hierarchy.page_levels;
    decode_page(&bytes, page, levels, metadata.layout()).map_err(|e| {
        ViewerError::source(
            format!("{}/{}", source.location(), DatasetFile::Hierarchy.name()),
            format!(
                "hierarchy page at byte {} (nodes under {}): {e}",
                page.offset, page.root
            ),
        )
    })
}

fn decode_root(source: &dyn Source, metadata: &Metadata) -> Result<HierarchyPage, ViewerError> {
    load_page(source, metadata, &metadata.root_page())
}
