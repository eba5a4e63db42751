//! An open dataset seen through a `Source`: metadata, hierarchy pages on demand, and nodes decoded
//! into the GPU point format.

use crate::marks::{Marks, WordFit};
use crate::pipelines::PointStream;
use crate::settings::ColourMode;
use crate::streams::{NormalKind, StreamSource, normal_attribute};
use crate::{HttpOptions, HttpSource, LocalSource, Source, ViewerError};
use glam::{DVec3, Vec3};
use std::path::Path;
use std::sync::{Arc, Mutex, PoisonError};
use strata_format::{
    AttrType, DatasetFile, GRID_CELLS_LOG2, HierarchyPage, Metadata, NodeColumns, NodeInfo,
    NodeKey, PageRef, RowLayout, decode_node, decode_page,
};

mod gpu_words;
pub(crate) mod sampling;

/// One node ready for upload: per point `[x, y, z, colour]` (f32 bits, then packed RGBA8) and
/// `intensity16 | classification << 16 | return_number << 24` (raw intensity, return number up
/// to 15). The colour's alpha byte is the surface variation, 0 to 255 over 0 to
/// `StreamDataset::variation_max` (255 where the dataset has none).
pub struct GpuNode {
    pub key: NodeKey,
    /// What the colours' RGB bytes hold.
    pub colours: ColourWord,
    /// The attribute ranges its points were marked by (`MARK_HIDDEN`).
    pub marks: Marks,
    pub points: Vec<[u32; 4]>,
    pub attributes: Vec<u32>,
    /// Per-point streams beyond position and colour that the dataset stores (normals, radius),
    /// as the GPU reads them: `PointStream::bytes_per_point` bytes a point.
    pub streams: Vec<(PointStream, Vec<u8>)>,
    /// Stored (compressed) bytes read for this node.
    pub bytes_read: u64,
    /// The spacing its points are sampled at, measured from them (`sampling`); `None` for a
    /// node too small to tell.
    pub sampling: Option<f32>,
}

/// What the RGB bytes of a point's colour hold. The projection colours by the others from the
/// point's position and attribute word; the normal, which has no room there, takes the place
/// of the stored colour while the viewer colours by it (nodes are loaded again on a change).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ColourWord {
    /// The stored `rgb` (grey where there is none).
    #[default]
    Stored,
    /// The normal, `(n * 0.5 + 0.5) * 255` (grey for a point without one).
    Normal,
}

/// The colour of a point without a colour or a normal.
const GREY: u32 = 0xffc8_c8c8;

/// How stored attributes become colours; decided once from the root node.
#[derive(Debug, Clone, Copy)]
struct ColourSource {
    rgb: Option<(usize, AttrType)>,
    rgb_shift: u32,
    intensity: Option<(usize, AttrType)>,
    intensity_max: f64,
    classification: Option<(usize, AttrType)>,
    return_number: Option<(usize, AttrType)>,
    normal: Option<(usize, NormalKind)>,
    variation: Option<(usize, AttrType)>,
    variation_max: f64,
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
    streams: StreamSource,
    /// Which filters the GPU's attribute word answers exactly for these attribute types.
    word_fit: WordFit,
}

/// Whether `location` names a dataset served over HTTP rather than a local directory.
pub fn is_remote(location: &str) -> bool {
    let scheme = location.get(..8).unwrap_or(location).to_ascii_lowercase();
    scheme.starts_with("http://") || scheme.starts_with("https://")
}

impl StreamDataset {
    /// Opens `http://HOST:PORT/DATASET` or a local dataset directory.
    pub fn open(location: &str, http: HttpOptions) -> Result<StreamDataset, ViewerError> {
        if is_remote(location) {
            let (source, metadata) = HttpSource::open(location, http)?;
            StreamDataset::from_source(Arc::new(source), metadata)
        } else {
            StreamDataset::open_path(Path::new(location))
        }
    }

    /// Opens a local dataset directory.
    pub fn open_path(dir: &Path) -> Result<StreamDataset, ViewerError> {
        let (source, metadata) = LocalSource::open(dir)?;
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
        let normal = normal_attribute(&layout);
        let variation = layout
            .index_of("surface_variation")
            .filter(|&i| layout.attributes[i].count == 1 && layout.attributes[i].ty.is_float())
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
                normal,
                variation,
                variation_max: MAX_VARIATION,
            },
            streams: StreamSource::of(&layout),
            word_fit: WordFit::of(&layout),
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

    /// The points of the root node: a budget below them draws nothing.
    pub fn root_points(&self) -> u64 {
        self.root
            .root_node()
            .map_or(0, |n| u64::from(n.point_count))
    }

    /// Whether the points carry a one-valued attribute `name` (one a range may filter on).
    pub fn has_attribute(&self, name: &str) -> bool {
        self.layout
            .index_of(name)
            .is_some_and(|i| self.layout.attributes[i].count == 1)
    }

    pub fn has_rgb(&self) -> bool {
        self.colour.rgb.is_some()
    }

    /// The surface variation shown at the top of the ramp (the 99th percentile of the root
    /// node's, at most 1/3, the largest there is).
    pub fn variation_max(&self) -> f64 {
        self.colour.variation_max
    }

    /// kappa r / sqrt(s) for a point whose colour's alpha byte holds the share s of
    /// `variation_max` and whose stored radius is r, kappa its surface's curvature; where the
    /// converter estimated the surface variation (`--normals`). On a sphere of radius R the k
    /// nearest neighbours within r_k have variation r_k^2 / (24 R^2), and r = r_k sqrt(ln 100 / k)
    /// (SPEC.md section 4), so kappa r = sqrt(24 variation ln 100 / k).
    pub fn curvature_scale(&self) -> Option<f64> {
        self.colour.variation?;
        let k = self.metadata.normals.as_ref()?.k;
        (k > 0).then(|| (24.0 * self.colour.variation_max * 100f64.ln() / k as f64).sqrt())
    }

    /// Whether the dataset has what colouring by `mode` needs (rgb, intensity and the others
    /// fall back or colour alike without theirs; normal and curvature are not offered).
    pub fn offers(&self, mode: ColourMode) -> bool {
        match mode {
            ColourMode::Normal => self.colour.normal.is_some(),
            ColourMode::Curvature => self.colour.variation.is_some(),
            _ => true,
        }
    }

    /// Refuses a colouring the dataset lacks the attribute for, naming it.
    pub fn check_colour(&self, mode: ColourMode) -> Result<(), ViewerError> {
        match mode.attribute() {
            Some(attribute) if !self.offers(mode) => Err(ViewerError::source(
                self.location(),
                format!(
                    "colouring by {} needs the \"{attribute}\" attribute, which the dataset does not have (convert it with --normals)",
                    mode.name()
                ),
            )),
            _ => Ok(()),
        }
    }

    /// The colouring the projection applies for `mode`: elevation where the dataset lacks
    /// what `mode` needs.
    pub fn shader_colour(&self, mode: ColourMode) -> ColourMode {
        let lacking = match mode {
            ColourMode::Rgb => !self.has_rgb(),
            other => !self.offers(other),
        };
        if lacking { ColourMode::Elevation } else { mode }
    }

    /// What the colours' RGB bytes must hold for `mode`.
    pub fn colour_word(&self, mode: ColourMode) -> ColourWord {
        match self.shader_colour(mode) {
            ColourMode::Normal => ColourWord::Normal,
            _ => ColourWord::Stored,
        }
    }

    /// Bounds of the stored points relative to the anchor.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let b = &self.metadata.bounds;
        (
            (DVec3::from_array(b.min) - self.anchor).as_vec3(),
            (DVec3::from_array(b.max) - self.anchor).as_vec3(),
        )
    }

    /// A node's cube relative to the anchor: minimum corner and edge length. A dataset whose
    /// axes have different steps (SPEC allows it; converters before one step per axis wrote
    /// them for float inputs) has boxes, not cubes: the cube on the longest edge holds the box,
    /// so that culling never drops a node that is in view.
    pub fn node_cube(&self, key: NodeKey) -> (Vec3, f32) {
        let m = &self.metadata;
        let (_, edge) = key.int_bounds(m.cube.min, m.cube.bits);
        let step = m.scale.iter().copied().fold(0.0, f64::max);
        (self.node_point(key, 0.0), (edge as f64 * step) as f32)
    }

    /// A node's centre relative to the anchor: the middle of its box on each axis (of its
    /// cube, where every axis has the dataset's one step).
    pub fn node_centre(&self, key: NodeKey) -> Vec3 {
        self.node_point(key, 0.5)
    }

    /// The point `along` the way from a node's minimum corner to its maximum one, per axis in
    /// that axis's step, relative to the anchor.
    fn node_point(&self, key: NodeKey, along: f64) -> Vec3 {
        let m = &self.metadata;
        let (min, edge) = key.int_bounds(m.cube.min, m.cube.bits);
        let real = DVec3::from_array(std::array::from_fn(|i| {
            m.offset[i] + m.scale[i] * (min[i] as f64 + edge as f64 * along)
        }));
        (real - self.anchor).as_vec3()
    }

    /// Whether the dataset stores normals (the `Normals` stream is all "none" otherwise).
    pub fn has_normals(&self) -> bool {
        self.streams.has_normals()
    }

    /// Whether its normals are oriented (taken from the inputs, or turned towards the scanners
    /// or up), rather than left facing either way (`--orient none`).
    pub fn normals_face_outward(&self) -> bool {
        self.metadata
            .normals
            .as_ref()
            .is_none_or(|n| n.orient != "none" || n.computed == 0)
    }

    /// Whether its normals point out of every surface (kept from the inputs, or turned towards
    /// the scanner that saw each point), so that a normal facing away from the eye marks a back
    /// face. Normals turned up are right only for surfaces seen from above (a wall's face
    /// either way), so they do not qualify.
    pub fn normals_mark_back_faces(&self) -> bool {
        self.has_normals()
            && self
                .metadata
                .normals
                .as_ref()
                .is_none_or(|n| n.orient == "scanner" || n.computed == 0)
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

    pub fn read_columns(&self, info: &NodeInfo) -> Result<NodeColumns, ViewerError> {
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
                self.source.file_location(DatasetFile::Octree),
                format!("node {}: {e}", info.key),
            )
        })
    }

    /// Reads, verifies, decompresses and converts one node, its colours' RGB holding `colours`
    /// and its points outside `marks` marked.
    pub fn load_node(
        &self,
        info: &NodeInfo,
        colours: ColourWord,
        marks: &Marks,
    ) -> Result<GpuNode, ViewerError> {
        let mut kept = self
            .root_node
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        if let Some((root, columns)) = kept.take_if(|(root, _)| root == info) {
            drop(kept);
            return Ok(self.to_gpu(&root, &columns, colours, marks));
        }
        drop(kept);
        let columns = self.read_columns(info)?;
        Ok(self.to_gpu(info, &columns, colours, marks))
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
        if let Some((i, ty)) = c.variation {
            let mut values: Vec<f64> = root
                .attribute(&self.layout, i)
                .chunks_exact(ty.size())
                .map(|v| ty.read_f64(v))
                .filter(|v| v.is_finite())
                .collect();
            values.sort_by(f64::total_cmp);
            // As for intensity: the 99th percentile, so that a few edges do not flatten the
            // ramp over the planes.
            let p99 = values
                .get(values.len().saturating_sub(1) * 99 / 100)
                .copied()
                .unwrap_or(MAX_VARIATION);
            c.variation_max = if p99 > 0.0 {
                p99.min(MAX_VARIATION)
            } else {
                MAX_VARIATION
            };
        }
        c
    }

    /// The filters of `filter` the loader answers (attributes the GPU does not hold, or not
    /// exactly: `word_fit`), resolved against the dataset; an unknown attribute is refused,
    /// naming the ones there are.
    pub fn marks(&self, filter: &crate::settings::PointFilter) -> Result<Marks, ViewerError> {
        Marks::of_filter(&self.layout, filter, self.word_fit, &self.location())
    }

    /// Refuses, before anything is drawn, a filter the dataset cannot answer: an attribute it
    /// lacks (`marks`), or classes to show none of which it holds a point of, where its
    /// metadata counts them (a mistyped code gave a blank image and exit 0).
    pub fn check_filter(&self, filter: &crate::settings::PointFilter) -> Result<(), ViewerError> {
        self.marks(filter)?;
        let counted = &self.metadata.classes;
        if let (Some(mask), false) = (filter.classes, filter.classes_beyond)
            && !counted.is_empty()
        {
            let shown = |c: u64| c < 256 && (mask[(c / 32) as usize] >> (c % 32)) & 1 == 1;
            let held = counted
                .iter()
                .any(|(code, &n)| n > 0 && code.parse::<u64>().is_ok_and(shown));
            if !held {
                let codes: Vec<&str> = counted.keys().map(String::as_str).collect();
                return Err(ViewerError::source(
                    self.location(),
                    format!(
                        "no point has a class the filter shows (the dataset's classes are {})",
                        codes.join(", ")
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Which filters the GPU's attribute word answers exactly (the others: `marks`).
    pub fn word_fit(&self) -> WordFit {
        self.word_fit
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
            source.file_location(DatasetFile::Hierarchy),
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

/// The largest surface variation there is, λ0 / (λ0 + λ1 + λ2) with λ0 the smallest.
const MAX_VARIATION: f64 = 1.0 / 3.0;
