//! Depth peeling (paper 004, sections 4 and 5): the next layer's points, those farther than
//! d~ (by the normal at grazing angles) behind the previous layer's filled depth, culled as the
//! projection culls; one 64-bit pass where the device has 64-bit atomics, leaving complemented
//! keys, else two 32-bit passes (as on GL), leaving complemented depth and index planes.

use super::passes::{Entry, UNIFORMS_WGSL, bind};
use super::targets::FiltersTargets;
use crate::ViewerError;
use crate::gpu::timing::Timer;
use crate::pipelines::projection::{
    ArenaGroup, CULL_WGSL, FILTERS_WGSL, NO_CULL_WGSL, OCT16_WGSL, PROJECT_WGSL, RANGE_SEARCH_WGSL,
    split_groups,
};
use crate::pipelines::shader::ShaderSource;

const PEEL_DEPTH_WGSL: &str = include_str!("peel_depth.wgsl");
const PEEL_INDEX_WGSL: &str = include_str!("peel_index.wgsl");
const PEEL_INT64_WGSL: &str = include_str!("peel_int64.wgsl");
const REACH_NORMAL_WGSL: &str = include_str!("reach_normal.wgsl");
const REACH_FLAT_WGSL: &str = include_str!("reach_flat.wgsl");

/// The peels' modules, in the order `Peels::new` takes them.
pub fn shaders(int64: bool) -> Vec<ShaderSource> {
    let peel = |label, emit, cull: bool| {
        let mut parts = vec![UNIFORMS_WGSL, emit, FILTERS_WGSL, RANGE_SEARCH_WGSL];
        let reach = emit != PEEL_INDEX_WGSL;
        parts.push(OCT16_WGSL);
        if cull {
            parts.push(CULL_WGSL);
            parts.extend(reach.then_some(REACH_NORMAL_WGSL));
        } else {
            parts.push(NO_CULL_WGSL);
            parts.extend(reach.then_some(REACH_FLAT_WGSL));
        }
        parts.push(PROJECT_WGSL);
        let source = ShaderSource::new(label, &parts);
        // A back face spared at the margin would come back as a layer of its own.
        if cull {
            source.with_constant("BACK_FACE_MARGIN", 0.0)
        } else {
            source
        }
    };
    let mut v = vec![
        peel("peel depth", PEEL_DEPTH_WGSL, false),
        peel("peel index", PEEL_INDEX_WGSL, false),
        peel("peel depth culled", PEEL_DEPTH_WGSL, true),
        peel("peel index culled", PEEL_INDEX_WGSL, true),
    ];
    if int64 {
        v.push(peel("peel int64", PEEL_INT64_WGSL, false));
        v.push(peel("peel int64 culled", PEEL_INT64_WGSL, true));
    }
    v
}

/// A peel's two modules: nearest depth, then lowest index at it; and the one pass of both
/// where the device has 64-bit atomics.
struct Peel {
    depth: wgpu::ComputePipeline,
    index: wgpu::ComputePipeline,
    int64: Option<wgpu::ComputePipeline>,
}

/// The peels drawing every point and culling back faces.
pub struct Peels {
    plain: Peel,
    culled: Peel,
}

/// What one peel reads and writes.
pub struct PeelFrame<'a, 'e> {
    pub device: &'a wgpu::Device,
    pub encoder: &'e mut wgpu::CommandEncoder,
    pub timer: &'e mut Timer,
    pub frame_entry: Entry<'a>,
    pub fil_entry: Entry<'a>,
    /// The previous layer's final texels.
    pub reference: &'a wgpu::Buffer,
    pub targets: &'a FiltersTargets,
    /// Per drawn arena: its range table, then points, attributes, normals, lit; and radii.
    pub arenas: &'a [(ArenaGroup, [&'a wgpu::Buffer; 4], &'a wgpu::Buffer)],
    pub cull: bool,
}

impl Peels {
    /// From the compiled modules of `shaders`, in order.
    pub fn new(
        next: &mut impl FnMut() -> Result<wgpu::ComputePipeline, ViewerError>,
        int64: bool,
    ) -> Result<Peels, ViewerError> {
        let (depth, index) = (next()?, next()?);
        let (depth_culled, index_culled) = (next()?, next()?);
        let (wide, wide_culled) = if int64 {
            (Some(next()?), Some(next()?))
        } else {
            (None, None)
        };
        Ok(Peels {
            plain: Peel {
                depth,
                index,
                int64: wide,
            },
            culled: Peel {
                depth: depth_culled,
                index: index_culled,
                int64: wide_culled,
            },
        })
    }

    /// Encodes the peel of the layer after `f.reference` into the targets' peel keys (returns
    /// true) or planes (false).
    pub fn encode(&self, f: PeelFrame) -> bool {
        let peel = if f.cull { &self.culled } else { &self.plain };
        // One 64-bit pass where the device can, else two 32-bit passes.
        let one_pass = match (&peel.int64, &f.targets.peel_keys) {
            (Some(p), Some(k)) => Some((p, k)),
            _ => None,
        };
        let mut passes: Vec<(&wgpu::ComputePipeline, wgpu::BindGroup)> = Vec::new();
        if let Some((pipe, keys)) = one_pass {
            f.encoder.clear_buffer(keys, 0, None);
            let group = bind(
                f.device,
                pipe,
                0,
                &[
                    f.frame_entry.clone(),
                    f.fil_entry.clone(),
                    (2, keys.as_entire_binding()),
                    (3, f.reference.as_entire_binding()),
                ],
            );
            passes.push((pipe, group));
        } else {
            f.encoder.clear_buffer(&f.targets.peel_depths, 0, None);
            f.encoder.clear_buffer(&f.targets.peel_indices, 0, None);
            let depth_group = bind(
                f.device,
                &peel.depth,
                0,
                &[
                    f.frame_entry.clone(),
                    f.fil_entry.clone(),
                    (2, f.targets.peel_depths.as_entire_binding()),
                    (3, f.reference.as_entire_binding()),
                ],
            );
            let index_group = bind(
                f.device,
                &peel.index,
                0,
                &[
                    f.frame_entry.clone(),
                    (2, f.targets.peel_depths.as_entire_binding()),
                    (3, f.targets.peel_indices.as_entire_binding()),
                ],
            );
            passes.push((&peel.depth, depth_group));
            passes.push((&peel.index, index_group));
        }
        let timestamp_writes = f.timer.pass(f.encoder, "peel");
        let mut pass = f.encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("peel"),
            timestamp_writes,
        });
        for (pipe, group) in &passes {
            pass.set_pipeline(pipe);
            pass.set_bind_group(0, group, &[]);
            for (g, [points, attributes, normals, _], radii) in f.arenas {
                if g.groups == 0 {
                    continue;
                }
                let entries = [
                    (0, points.as_entire_binding()),
                    (1, g.ranges.as_entire_binding()),
                    (2, attributes.as_entire_binding()),
                    (3, normals.as_entire_binding()),
                    (4, radii.as_entire_binding()),
                ];
                pass.set_bind_group(1, &bind(f.device, pipe, 1, &entries), &[]);
                let (x, y) = split_groups(g.groups);
                pass.dispatch_workgroups(x, y, 1);
            }
        }
        drop(pass);
        one_pass.is_some()
    }
}
