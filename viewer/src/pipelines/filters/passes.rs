//! The filters pipeline's GPU passes, per layer: peel (layers after the first, which is the
//! projection's own, culled by the normals), resolve into texels, fill background and occluded
//! pixels (iterated, each iteration skipped by an indirect dispatch once one changed nothing),
//! then smooth and shade in one pass, with anti-aliasing and front-to-back blending.

use super::peel::{PeelFrame, Peels};
use super::shade::{ShadePipelines, ShadeVariant};
use super::targets::{FiltersTargets, STEP_STRIDE};
use crate::ViewerError;
use crate::gpu::GpuContext;
use crate::gpu::timing::Timer;
use crate::pipelines::projection::{
    ArenaGroup, COLOUR_WGSL, GROUP_SIZE, OCT16_WGSL, RANGE_SEARCH_WGSL, pixel_groups,
};
use crate::pipelines::shader::ShaderSource;
use crate::pipelines::shadows::LIT_STREAM;
use crate::pipelines::{PipelineFrame, PointStream};
use bytemuck::{Pod, Zeroable};

/// The filters' uniforms and layer texels, first in every module.
pub(super) const UNIFORMS_WGSL: &str = include_str!("uniforms.wgsl");
const RESOLVE_WGSL: &str = include_str!("resolve.wgsl");
const RESOLVE_PLANES_WGSL: &str = include_str!("resolve_planes.wgsl");
const RESOLVE_KEYS_WGSL: &str = include_str!("resolve_keys.wgsl");
const FILL_WGSL: &str = include_str!("fill.wgsl");
/// The hole filling's 3x3 masks, shared with the light map's fill.
pub(crate) const MASKS_WGSL: &str = include_str!("masks.wgsl");
const ARGS_WGSL: &str = include_str!("args.wgsl");
const TILES_WGSL: &str = include_str!("tiles.wgsl");

/// Layers at most (`MAX_LAYERS` in uniforms.wgsl).
pub const MAX_LAYERS: u32 = 8;
/// Fill iterations at most, per kind and layer (`MAX_ITERATIONS`).
pub const MAX_ITERATIONS: u32 = 16;
// The first layer's fill starts on the tiles that hold a point or lie beside one (tiles.wgsl):
// its background fill must not carry a texel past the tile beside, one pixel an iteration.
const _: () = assert!(MAX_ITERATIONS <= 16, "a fill tile is 16 pixels wide");
/// Storage buffers the filters bind in one pass at most (the resolve's).
pub const STORAGE_BUFFERS: u32 = 11;
/// Classes with an opacity of their own (`CLASSES`): the ASPRS standard classes 0 to 18.
pub const CLASSES: usize = 19;
/// Words of the counters buffer (`COUNTERS`): a flag per layer, then a flag per layer, kind
/// and iteration.
pub const COUNTERS: u64 = (MAX_LAYERS + MAX_LAYERS * 2 * MAX_ITERATIONS) as u64;

/// The fill's tile lists, one per kind and iteration (`LIST_HEADER`, `LISTS` and `list_of` in
/// uniforms.wgsl).
pub const LIST_HEADER: u64 = 4;
pub const LISTS: u64 = 2 * MAX_ITERATIONS as u64;

pub fn list_of(kind: u32, iteration: u32) -> u64 {
    (kind as u64 - 1) * MAX_ITERATIONS as u64 + iteration as u64
}

/// `kind` of a step (`ARGS_*` in uniforms.wgsl).
pub const ARGS_LAYER: u32 = 0;
pub const ARGS_BACKGROUND: u32 = 1;
pub const ARGS_OCCLUDED: u32 = 2;

/// The filters' uniforms, laid out as `Filters` in uniforms.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct FiltersUniforms {
    pub eye: [f32; 4],
    pub forward: [f32; 4],
    pub right: [f32; 4],
    pub up: [f32; 4],
    pub light: [f32; 4],
    pub class_opacity: [[f32; 4]; 5],
    pub dtilde: f32,
    pub normals: u32,
    pub opacity: f32,
    pub lit_scale: f32,
    pub pad0: f32,
    pub pad1: f32,
    pub pad2: f32,
    pub pad3: f32,
}

/// What one dispatch works on, laid out as `Step` in uniforms.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct Step {
    pub layer: u32,
    pub iteration: u32,
    pub kind: u32,
    pub complemented: u32,
}

/// Every module the filters compile, the peels' first; `int64`: the device has 64-bit atomics.
pub fn shaders(int64: bool) -> Vec<ShaderSource> {
    let mut v = super::peel::shaders(int64);
    v.extend([
        ShaderSource::new(
            "filters resolve",
            &[
                UNIFORMS_WGSL,
                COLOUR_WGSL,
                OCT16_WGSL,
                RANGE_SEARCH_WGSL,
                RESOLVE_WGSL,
                RESOLVE_PLANES_WGSL,
            ],
        ),
        ShaderSource::new("fill background", &[UNIFORMS_WGSL, MASKS_WGSL, FILL_WGSL])
            .with_entry("background"),
        ShaderSource::new("fill occluded", &[UNIFORMS_WGSL, MASKS_WGSL, FILL_WGSL])
            .with_entry("occluded"),
        ShadeVariant::default().source(),
        ShaderSource::new("filters args", &[UNIFORMS_WGSL, ARGS_WGSL]),
        ShaderSource::new("filters tiles", &[UNIFORMS_WGSL, TILES_WGSL]),
    ]);
    if int64 {
        v.push(ShaderSource::new(
            "filters resolve keys",
            &[
                UNIFORMS_WGSL,
                COLOUR_WGSL,
                OCT16_WGSL,
                RANGE_SEARCH_WGSL,
                RESOLVE_WGSL,
                RESOLVE_KEYS_WGSL,
            ],
        ));
    }
    v
}

pub struct FiltersPasses {
    peels: Peels,
    resolve: wgpu::ComputePipeline,
    /// The resolve reading 64-bit keys, where the device has 64-bit atomics.
    resolve_keys: Option<wgpu::ComputePipeline>,
    background: wgpu::ComputePipeline,
    occluded: wgpu::ComputePipeline,
    shades: ShadePipelines,
    args: wgpu::ComputePipeline,
    tiles: wgpu::ComputePipeline,
}

/// What a frame's passes are told beyond the uniforms.
pub struct FrameSetup {
    pub layers: u32,
    pub fill_iterations: u32,
    /// The projection culled back faces (the peels then cull too).
    pub cull: bool,
    pub shade: ShadeVariant,
}

/// A bind group entry: binding and resource.
pub(crate) type Entry<'a> = (u32, wgpu::BindingResource<'a>);

/// A bind group of `pipe`'s layout `group` from (binding, resource) pairs.
pub(crate) fn bind(
    device: &wgpu::Device,
    pipe: &wgpu::ComputePipeline,
    group: u32,
    entries: &[Entry],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = entries
        .iter()
        .map(|(binding, resource)| wgpu::BindGroupEntry {
            binding: *binding,
            resource: resource.clone(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("filters"),
        layout: &pipe.get_bind_group_layout(group),
        entries: &entries,
    })
}

impl FiltersPasses {
    pub fn new(ctx: &GpuContext) -> Result<FiltersPasses, ViewerError> {
        ctx.require_storage_buffers("filters", STORAGE_BUFFERS)?;
        let mut compiled = shaders(ctx.int64_atomics)
            .into_iter()
            .map(|s| s.compute(&ctx.device, None));
        let mut next = || {
            compiled
                .next()
                .ok_or_else(|| ViewerError::Gpu("a filters shader is missing".into()))
        };
        let peels = Peels::new(&mut next, ctx.int64_atomics)?;
        let (resolve, background, occluded, shade, args, tiles) = (
            next()?,
            next()?,
            next()?,
            next()?,
            next()?,
            next()?,
        );
        let resolve_keys = if ctx.int64_atomics {
            Some(next()?)
        } else {
            None
        };
        Ok(FiltersPasses {
            peels,
            resolve,
            resolve_keys,
            background,
            occluded,
            shades: ShadePipelines::new(ShadeVariant::default(), shade),
            args,
            tiles,
        })
    }

    pub fn encode(
        &mut self,
        frame: &PipelineFrame,
        encoder: &mut wgpu::CommandEncoder,
        targets: &mut FiltersTargets,
        uniforms: &FiltersUniforms,
        setup: &FrameSetup,
        timer: &mut Timer,
    ) -> Result<(), ViewerError> {
        let device = &frame.ctx.device;
        let shade = self
            .shades
            .get(setup.shade, |v| v.source().compute(device, None));
        let screen = frame.screen;
        let queue = &frame.ctx.queue;
        queue.write_buffer(&targets.uniforms, 0, bytemuck::bytes_of(uniforms));
        encoder.clear_buffer(&targets.counters, 0, None);
        // No clear of the blend: the first layer's shading writes every pixel of it.

        let arenas: Vec<(ArenaGroup, [&wgpu::Buffer; 4], &wgpu::Buffer)> = frame
            .arenas
            .iter()
            .map(|d| {
                let (a, [normals, radii, lit]) = frame.cache.arena_streams(
                    d.arena,
                    [PointStream::Normals, PointStream::Radius, LIT_STREAM],
                )?;
                Ok((
                    ArenaGroup::new(device, d, GROUP_SIZE),
                    [&a.points, &a.attributes, normals, lit],
                    radii,
                ))
            })
            .collect::<Result<_, ViewerError>>()?;

        // Every dispatch's step, at its own 256-byte slot of the steps buffer.
        let mut steps: Vec<Step> = Vec::new();
        let mut step_bind = |pipe: &wgpu::ComputePipeline, group: u32, step: Step| {
            let offset = steps.len() as u64 * STEP_STRIDE;
            steps.push(step);
            bind(
                device,
                pipe,
                group,
                &[(
                    0,
                    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &targets.steps,
                        offset,
                        size: wgpu::BufferSize::new(std::mem::size_of::<Step>() as u64),
                    }),
                )],
            )
        };
        let frame_entry = || (0, screen.uniforms.as_entire_binding());
        let fil_entry = || (1, targets.uniforms.as_entire_binding());
        let (gx, gy) = pixel_groups(screen.width, screen.height);
        let output = screen.output.create_view(&Default::default());

        // The buffer holding the previous layer's final texels (the peel's reference).
        let mut reference: Option<usize> = None;
        // The layer's pixels are 64-bit keys (else depth and index planes).
        let mut keyed = frame.int64;
        for layer in 0..setup.layers.min(MAX_LAYERS) {
            if let Some(r) = reference {
                keyed = self.peels.encode(PeelFrame {
                    device,
                    encoder,
                    timer,
                    frame_entry: frame_entry(),
                    fil_entry: fil_entry(),
                    reference: &targets.texels[r],
                    targets,
                    arenas: &arenas,
                    cull: setup.cull,
                });
            }

            // Resolve into the buffer that is not the reference.
            let mut current = match reference {
                Some(r) => 1 - r,
                None => 0,
            };
            encoder.clear_buffer(&targets.texels[current], 0, None);
            // The first layer's fill starts only where the resolve put points (tiles.wgsl): the
            // other buffer must hold the same background everywhere else.
            if reference.is_none() {
                encoder.clear_buffer(&targets.texels[1 - current], 0, None);
            }
            encoder.clear_buffer(&targets.tiles, 0, None);
            {
                let keys = match (keyed, reference.is_some()) {
                    (false, _) => None,
                    (true, false) => screen.keys.as_ref(),
                    (true, true) => targets.peel_keys.as_ref(),
                };
                let (resolve, mut entries) = match (keys, &self.resolve_keys) {
                    (Some(keys), Some(pipe)) => (pipe, vec![(2, keys.as_entire_binding())]),
                    (Some(_), None) => {
                        return Err(ViewerError::Gpu(
                            "the filters were given 64-bit keys on a device without 64-bit atomics"
                                .into(),
                        ));
                    }
                    (None, _) => {
                        let (depths, indices) = if reference.is_some() {
                            (&targets.peel_depths, &targets.peel_indices)
                        } else {
                            (&screen.depths, &screen.indices)
                        };
                        (
                            &self.resolve,
                            vec![
                                (2, depths.as_entire_binding()),
                                (3, indices.as_entire_binding()),
                            ],
                        )
                    }
                };
                entries.extend([
                    frame_entry(),
                    fil_entry(),
                    (4, targets.texels[current].as_entire_binding()),
                    (5, targets.counters.as_entire_binding()),
                    (6, targets.tiles.as_entire_binding()),
                ]);
                let fb = bind(device, resolve, 0, &entries);
                let sb = step_bind(
                    resolve,
                    2,
                    Step {
                        layer,
                        iteration: 0,
                        kind: ARGS_LAYER,
                        complemented: reference.is_some() as u32,
                    },
                );
                let timestamp_writes = timer.pass(encoder, "filters resolve");
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("filters resolve"),
                    timestamp_writes,
                });
                pass.set_pipeline(resolve);
                pass.set_bind_group(0, &fb, &[]);
                pass.set_bind_group(2, &sb, &[]);
                for (g, [points, attributes, normals, lit], radii) in &arenas {
                    if g.groups == 0 {
                        continue;
                    }
                    let ab = bind(
                        device,
                        resolve,
                        1,
                        &[
                            (0, points.as_entire_binding()),
                            (1, g.ranges.as_entire_binding()),
                            (2, attributes.as_entire_binding()),
                            (3, normals.as_entire_binding()),
                            (4, lit.as_entire_binding()),
                            (5, radii.as_entire_binding()),
                        ],
                    );
                    pass.set_bind_group(1, &ab, &[]);
                    pass.dispatch_workgroups(gx, gy, 1);
                }
            }

            // Arguments of the peeled layers' shading, from the counters.
            let args_group = bind(
                device,
                &self.args,
                0,
                &[
                    frame_entry(),
                    (2, targets.counters.as_entire_binding()),
                    (3, targets.args.as_entire_binding()),
                ],
            );
            let set_args = |pass: &mut wgpu::ComputePass, step_group: &wgpu::BindGroup| {
                pass.set_pipeline(&self.args);
                pass.set_bind_group(0, &args_group, &[]);
                pass.set_bind_group(1, step_group, &[]);
                pass.dispatch_workgroups(1, 1, 1);
            };

            // Fill: background pixels, then occluded ones, ping-ponging between the texel
            // buffers; each iteration dispatched over the tile list the tiles pass made for
            // it, whose count is the dispatch's workgroup count.
            if setup.fill_iterations > 0 {
                encoder.clear_buffer(&targets.tile_lists, 0, None);
                let tiles_group = bind(
                    device,
                    &self.tiles,
                    0,
                    &[
                        frame_entry(),
                        (2, targets.tiles.as_entire_binding()),
                        (3, targets.tile_lists.as_entire_binding()),
                    ],
                );
                let timestamp_writes = timer.pass(encoder, "fill");
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("fill"),
                    timestamp_writes,
                });
                for (kind, pipe) in [
                    (ARGS_BACKGROUND, &self.background),
                    (ARGS_OCCLUDED, &self.occluded),
                ] {
                    for iteration in 0..setup.fill_iterations.min(MAX_ITERATIONS) {
                        let step = Step {
                            layer,
                            iteration,
                            kind,
                            complemented: 0,
                        };
                        let tiles_step = step_bind(&self.tiles, 1, step);
                        pass.set_pipeline(&self.tiles);
                        pass.set_bind_group(0, &tiles_group, &[]);
                        pass.set_bind_group(1, &tiles_step, &[]);
                        pass.dispatch_workgroups((gx * gy).div_ceil(64), 1, 1);
                        let fill_step = step_bind(pipe, 1, step);
                        let mut entries = vec![
                            frame_entry(),
                            (2, targets.texels[current].as_entire_binding()),
                            (3, targets.texels[1 - current].as_entire_binding()),
                            (4, targets.counters.as_entire_binding()),
                            (5, targets.tiles.as_entire_binding()),
                            (6, targets.tile_lists.as_entire_binding()),
                        ];
                        // Only the occluded fill reads d~.
                        if kind == ARGS_OCCLUDED {
                            entries.push(fil_entry());
                        }
                        let fb = bind(device, pipe, 0, &entries);
                        pass.set_pipeline(pipe);
                        pass.set_bind_group(0, &fb, &[]);
                        pass.set_bind_group(1, &fill_step, &[]);
                        let at = list_of(kind, iteration) * targets.list_words() * 4;
                        pass.dispatch_workgroups_indirect(&targets.tile_lists, at);
                        current = 1 - current;
                    }
                }
            }

            let layer_step = Step {
                layer,
                iteration: 0,
                kind: ARGS_LAYER,
                complemented: 0,
            };
            // The shade smooths the filled texels as it reads them; the next layer's peel reads
            // their depth, which smoothing keeps.
            {
                let args_step = step_bind(&self.args, 1, layer_step);
                let shade_step = step_bind(shade, 1, layer_step);
                let fb = bind(
                    device,
                    shade,
                    0,
                    &[
                        frame_entry(),
                        fil_entry(),
                        (2, targets.texels[current].as_entire_binding()),
                        (3, targets.accum.as_entire_binding()),
                        (4, targets.surface.as_entire_binding()),
                        (5, targets.albedo.as_entire_binding()),
                        (6, wgpu::BindingResource::TextureView(&output)),
                    ],
                );
                let timestamp_writes = timer.pass(encoder, "filters shade");
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("filters shade"),
                    timestamp_writes,
                });
                // The first layer always shades: it writes the background where nothing is.
                if layer > 0 {
                    set_args(&mut pass, &args_step);
                }
                pass.set_pipeline(shade);
                pass.set_bind_group(0, &fb, &[]);
                pass.set_bind_group(1, &shade_step, &[]);
                if layer > 0 {
                    pass.dispatch_workgroups_indirect(&targets.args, 0);
                } else {
                    pass.dispatch_workgroups(gx, gy, 1);
                }
            }
            reference = Some(current);
        }
        if steps.len() > targets.step_slots() {
            return Err(ViewerError::Gpu(format!(
                "the filters encoded {} steps, their buffer holds {}",
                steps.len(),
                targets.step_slots()
            )));
        }
        let mut bytes = vec![0u8; steps.len() * STEP_STRIDE as usize];
        for (k, s) in steps.iter().enumerate() {
            let at = k * STEP_STRIDE as usize;
            bytes[at..at + std::mem::size_of::<Step>()].copy_from_slice(bytemuck::bytes_of(s));
        }
        if !bytes.is_empty() {
            queue.write_buffer(&targets.steps, 0, &bytes);
        }
        targets
            .counters_readback
            .record(encoder, &targets.counters, 0, COUNTERS * 4);
        Ok(())
    }
}
