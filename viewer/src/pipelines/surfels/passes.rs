//! The surfels' GPU passes: depth (with the offset z_o), blend (fixed-point sums of colour,
//! normal and depth), shade (normalise, light, keep the surface); their per-screen buffers
//! and the per-arena range tables with what the LOD drew below each node.

use super::param;
use crate::ViewerError;
use crate::gpu::GpuContext;
use crate::gpu::async_readback::AsyncReadback;
use crate::gpu::readback::read_buffer;
use crate::gpu::timing::Timer;
use crate::pipelines::params::ResolvedParams;
use crate::pipelines::projection::{
    COLOUR_WGSL, FILTERS_WGSL, GROUP_SIZE, OCT16_WGSL, RANGE_SEARCH_WGSL, pixel_groups,
    plane_buffer, range_table, split_groups,
};
use crate::pipelines::shader::{ShaderSource, Variants};
use crate::pipelines::{
    BOX_WALK_WGSL, LIGHTING_WGSL, PipelineFrame, PointStream, ScreenBuffer, ViewFrame,
};
use crate::renderer::SurfacePixel;
use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

pub(super) const UNIFORMS_WGSL: &str = include_str!("uniforms.wgsl");
pub(super) const SURFEL_WGSL: &str = include_str!("surfel.wgsl");
const SUMS_WGSL: &str = include_str!("sums.wgsl");
const PLANAR_WGSL: &str = include_str!("planar.wgsl");
pub(super) const CURVED_WGSL: &str = include_str!("curved.wgsl");
const DEPTH_WGSL: &str = include_str!("depth.wgsl");
const BLEND_WGSL: &str = include_str!("blend.wgsl");
const THREAD_LISTING_WGSL: &str = include_str!("thread_listing.wgsl");
const THREAD_LISTED_WGSL: &str = include_str!("thread_listed.wgsl");
const THREAD_ALL_WGSL: &str = include_str!("thread_all.wgsl");
const SHADE_WGSL: &str = include_str!("shade.wgsl");

/// `mode` of the planar surfels (`MODE_PLANAR` in uniforms.wgsl).
pub const MODE_PLANAR: u32 = 0;
/// Words per pixel of the depth planes (`PLANE_WORDS` in uniforms.wgsl).
pub const PLANE_WORDS: u64 = 3;
/// Words per pixel of the blend sums (`SUM_WORDS` in sums.wgsl).
pub const SUM_WORDS: u64 = 9;
/// Storage buffers the depth and blend passes bind in one stage.
pub const STORAGE_BUFFERS: u32 = 8;
/// Words before the slots in a list of curved surfels (`LIST_HEADER` in surfel.wgsl): the
/// count, then the curved modules' indirect dispatch.
pub const LIST_HEADER: u64 = 4;

/// What the dataset's normals are (`NORMALS_*` in uniforms.wgsl).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Normals {
    /// None: discs facing the eye.
    None = 0,
    /// Oriented (as stored, towards scanners, or up): c-surfels bend away from them.
    Outward = 1,
    /// Not oriented (`--orient none`): each is first turned towards the eye, the one side
    /// known to be outside wherever a surface is seen from the front.
    FacingEye = 2,
}

/// The surfels' uniforms, laid out as `Surfels` in uniforms.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct SurfelUniforms {
    pub eye: [f32; 4],
    pub forward: [f32; 4],
    pub right: [f32; 4],
    pub up: [f32; 4],
    pub back_faces: u32,
    pub rings: u32,
    pub mode: u32,
    pub normals: u32,
    pub sin_epsilon: f32,
    pub h: f32,
    pub falloff: f32,
    pub depth_offset: f32,
    pub curvature: f32,
    pub flat_px: f32,
    pub pad1: f32,
    pub pad2: f32,
    pub ring_phi: [[f32; 4]; 4],
}

impl SurfelUniforms {
    /// `curvature`: the dataset's `curvature_scale`, where it has one; `back_faces`: whether
    /// its normals mark back faces (`StreamDataset::normals_mark_back_faces`).
    pub fn new(
        view: &ViewFrame,
        params: &ResolvedParams,
        normals: Normals,
        curvature: Option<f32>,
        back_faces: bool,
    ) -> SurfelUniforms {
        let rays = view.pixel_rays();
        SurfelUniforms {
            eye: rays.eye,
            forward: rays.forward,
            right: rays.right,
            up: rays.up,
            back_faces: u32::from(back_faces),
            rings: param(params, "rings") as u32,
            mode: param(params, "mode") as u32,
            normals: normals as u32,
            sin_epsilon: param(params, "epsilon").to_radians().sin(),
            h: param(params, "h"),
            falloff: param(params, "falloff"),
            depth_offset: param(params, "depth_offset"),
            curvature: curvature
                .filter(|_| param(params, "curvature") != 0.0)
                .unwrap_or(0.0),
            flat_px: param(params, "flat_px"),
            pad1: 0.0,
            pad2: 0.0,
            ring_phi: SurfelUniforms::ring_phi(param(params, "h"), param(params, "rings") as u32),
        }
    }

    /// phi(r) = 1 - exp(-(r^2 / h^2)^2) at the outer edge of each of `rings` rings (at most 16,
    /// the parameter's largest), as `ring_phi` in uniforms.wgsl holds it.
    pub fn ring_phi(h: f32, rings: u32) -> [[f32; 4]; 4] {
        let mut table = [[0.0; 4]; 4];
        for k in 1..=rings.min(16) {
            let q = (k as f32 / rings as f32).powi(2) / (h * h);
            table[(k as usize - 1) / 4][(k as usize - 1) % 4] = 1.0 - (-q * q).exp();
        }
        table
    }
}

/// Every module the surfels compile: the depth and the blend pass once for planar and once for
/// curved surfels (a module that carries the c-surfel's code draws planar surfels at half the
/// speed on lavapipe), then the shading. Where curved surfels can exist, the planar depth
/// pass lists them (a third depth module, so that the planar mode does not carry the listing),
/// and the curved modules run over that list alone.
pub fn shaders(sides: u32) -> Vec<ShaderSource> {
    let mut v = sided_shaders(sides).to_vec();
    v.push(shade_shader());
    v
}

/// The depth and the blend modules, with SIDES `sides`: depth planar, listing and curved,
/// then blend planar and curved.
fn sided_shaders(sides: u32) -> [ShaderSource; 5] {
    let depth = |label, shape, thread| {
        ShaderSource::new(
            label,
            &[
                UNIFORMS_WGSL,
                FILTERS_WGSL,
                RANGE_SEARCH_WGSL,
                OCT16_WGSL,
                SURFEL_WGSL,
                BOX_WALK_WGSL,
                shape,
                thread,
                DEPTH_WGSL,
            ],
        )
        .with_constant("SIDES", sides as f64)
    };
    let blend = |label, shape, thread| {
        ShaderSource::new(
            label,
            &[
                UNIFORMS_WGSL,
                FILTERS_WGSL,
                RANGE_SEARCH_WGSL,
                COLOUR_WGSL,
                SUMS_WGSL,
                OCT16_WGSL,
                SURFEL_WGSL,
                BOX_WALK_WGSL,
                shape,
                thread,
                BLEND_WGSL,
            ],
        )
        .with_constant("SIDES", sides as f64)
    };
    [
        depth("surfel depth planar", PLANAR_WGSL, THREAD_ALL_WGSL),
        depth("surfel depth listing", PLANAR_WGSL, THREAD_LISTING_WGSL),
        depth("surfel depth curved", CURVED_WGSL, THREAD_LISTED_WGSL),
        blend("surfel blend planar", PLANAR_WGSL, THREAD_ALL_WGSL),
        blend("surfel blend curved", CURVED_WGSL, THREAD_LISTED_WGSL),
    ]
}

/// The shading: the blend normalised and lit, pinholes of the near surface closed (the
/// far-side rule, shade.wgsl) and one-pixel cracks filled.
fn shade_shader() -> ShaderSource {
    ShaderSource::new(
        "surfel shade",
        &[UNIFORMS_WGSL, SUMS_WGSL, LIGHTING_WGSL, SHADE_WGSL],
    )
}

/// A pass's modules: for planar surfels, for planar ones listing the curved (the depth pass
/// only), and for curved surfels.
struct Kinds {
    planar: wgpu::ComputePipeline,
    listing: Option<wgpu::ComputePipeline>,
    curved: wgpu::ComputePipeline,
}

/// The depth and blend passes for one number of sides (`SIDES` in surfel.wgsl).
struct Sided {
    depth: Kinds,
    blend: Kinds,
}

pub struct SurfelPasses {
    sided: Variants<u32, Sided>,
    shade: wgpu::ComputePipeline,
}

/// The `sides` a pipeline is made with before a frame asks for others.
pub const DEFAULT_SIDES: u32 = 6;

/// The depth and blend passes with SIDES `sides`.
fn compile_sided(device: &wgpu::Device, sides: u32) -> Sided {
    let [
        depth_planar,
        listing,
        depth_curved,
        blend_planar,
        blend_curved,
    ] = sided_shaders(sides).map(|s| s.compute(device, None));
    Sided {
        depth: Kinds {
            planar: depth_planar,
            listing: Some(listing),
            curved: depth_curved,
        },
        blend: Kinds {
            planar: blend_planar,
            listing: None,
            curved: blend_curved,
        },
    }
}

impl SurfelPasses {
    pub fn new(ctx: &GpuContext) -> Result<SurfelPasses, ViewerError> {
        ctx.require_storage_buffers("surfels", STORAGE_BUFFERS)?;
        Ok(SurfelPasses {
            sided: Variants::new(DEFAULT_SIDES, compile_sided(&ctx.device, DEFAULT_SIDES)),
            shade: shade_shader().compute(&ctx.device, None),
        })
    }

    pub fn screen_buffers(width: u32, height: u32) -> Vec<ScreenBuffer> {
        let pixels = width as u64 * height as u64;
        vec![
            ScreenBuffer {
                label: "surfel depth planes",
                bytes: pixels * PLANE_WORDS * 4,
            },
            ScreenBuffer {
                label: "surfel blend sums",
                bytes: pixels * SUM_WORDS * 4,
            },
            ScreenBuffer {
                label: "surfel surface",
                bytes: pixels * 16,
            },
            ScreenBuffer {
                label: "surfel albedo",
                bytes: pixels * 4,
            },
        ]
    }

    /// `sides`: the n-gons' corners (the `sides` parameter).
    pub fn encode(
        &mut self,
        frame: &PipelineFrame,
        encoder: &mut wgpu::CommandEncoder,
        targets: &mut SurfelTargets,
        uniforms: &SurfelUniforms,
        sides: u32,
        timer: &mut Timer,
    ) -> Result<(), ViewerError> {
        let device = &frame.ctx.device;
        let sided = self.sided.get(sides, |n| compile_sided(device, n));
        let screen = frame.screen;
        frame
            .ctx
            .queue
            .write_buffer(&targets.uniforms, 0, bytemuck::bytes_of(uniforms));
        encoder.clear_buffer(&targets.planes, 0, None);
        encoder.clear_buffer(&targets.sums, 0, None);
        encoder.clear_buffer(&targets.counts, 0, None);
        let tables: Vec<(u32, wgpu::Buffer, u32)> = frame
            .arenas
            .iter()
            .map(|d| {
                let (table, groups) = range_table(d.arena, &d.ranges, GROUP_SIZE);
                let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("surfel ranges"),
                    contents: bytemuck::cast_slice(&table),
                    usage: wgpu::BufferUsages::STORAGE,
                });
                (d.arena, buffer, groups)
            })
            .collect();
        // Planar surfels exist in every mode (points without a normal are discs); curved ones
        // only where the mode and the normals allow them.
        let curved = uniforms.mode != MODE_PLANAR && uniforms.normals != Normals::None as u32;
        // A list of curved surfels per arena, with room for each of its points where curved
        // ones can exist; emptied, with its dispatch at (0, 1, 1), before the depth pass.
        let capacities: Vec<u64> = tables
            .iter()
            .map(|(_, _, groups)| {
                if curved {
                    *groups as u64 * GROUP_SIZE as u64
                } else {
                    0
                }
            })
            .collect();
        targets.grow_curved_lists(device, &capacities);
        let lists = &targets.curved_lists[..capacities.len()];
        for list in lists.iter().filter(|_| curved) {
            frame
                .ctx
                .queue
                .write_buffer(list, 0, bytemuck::cast_slice(&[0u32, 0, 1, 1]));
        }
        let mut arena_groups = Vec::with_capacity(tables.len());
        for (arena, ranges, groups) in &tables {
            let (a, [normals, radii]) = frame
                .cache
                .arena_streams(*arena, [PointStream::Normals, PointStream::Radius])?;
            arena_groups.push(([&a.points, ranges, &a.attributes, normals, radii], *groups));
        }
        let per_point = |name: &str,
                         kinds: &Kinds,
                         own: [&wgpu::Buffer; 2],
                         timer: &mut Timer,
                         encoder: &mut wgpu::CommandEncoder| {
            let timestamp_writes = timer.pass(encoder, name);
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(name),
                timestamp_writes,
            });
            // (module, whether it binds the lists, whether it runs over them). Where curved
            // surfels can exist, the depth pass's planar module lists them, and the curved
            // module runs over each list.
            let mut pipes = Vec::with_capacity(2);
            match (&kinds.listing, curved) {
                (Some(listing), true) => pipes.push((listing, true, false)),
                _ => pipes.push((&kinds.planar, false, false)),
            }
            if curved {
                pipes.push((&kinds.curved, true, true));
            }
            for (pipe, binds_list, listed) in pipes {
                let fb = bind(
                    device,
                    pipe,
                    0,
                    &[&screen.uniforms, &targets.uniforms, own[0], own[1]],
                );
                pass.set_pipeline(pipe);
                pass.set_bind_group(0, &fb, &[]);
                for ((buffers, groups), list) in arena_groups.iter().zip(lists) {
                    if *groups == 0 {
                        continue;
                    }
                    let mut bound = buffers.to_vec();
                    if binds_list {
                        bound.push(list);
                    }
                    pass.set_bind_group(1, &bind(device, pipe, 1, &bound), &[]);
                    if listed {
                        // The dispatch the depth pass counted (words 1 to 3).
                        pass.dispatch_workgroups_indirect(list, 4);
                    } else {
                        let (x, y) = split_groups(*groups);
                        pass.dispatch_workgroups(x, y, 1);
                    }
                }
            }
        };
        per_point(
            "surfel depth",
            &sided.depth,
            [&targets.planes, &targets.counts],
            timer,
            encoder,
        );
        per_point(
            "surfel blend",
            &sided.blend,
            [&targets.planes, &targets.sums],
            timer,
            encoder,
        );

        let view = screen.output.create_view(&Default::default());
        let mut entries: Vec<wgpu::BindGroupEntry> = [
            &screen.uniforms,
            &targets.uniforms,
            &targets.planes,
            &targets.sums,
            &targets.surface,
            &targets.albedo,
        ]
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: b.as_entire_binding(),
        })
        .collect();
        entries.push(wgpu::BindGroupEntry {
            binding: 6,
            resource: wgpu::BindingResource::TextureView(&view),
        });
        let shade = &self.shade;
        let bg = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("surfel shade"),
            layout: &shade.get_bind_group_layout(0),
            entries: &entries,
        });
        {
            let timestamp_writes = timer.pass(encoder, "surfel shade");
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("surfel shade"),
                timestamp_writes,
            });
            pass.set_pipeline(shade);
            pass.set_bind_group(0, &bg, &[]);
            let (gx, gy) = pixel_groups(screen.width, screen.height);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        targets
            .counts_readback
            .record(encoder, &targets.counts, 0, 8);
        Ok(())
    }
}

fn bind(
    device: &wgpu::Device,
    pipe: &wgpu::ComputePipeline,
    group: u32,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: b.as_entire_binding(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("surfels"),
        layout: &pipe.get_bind_group_layout(group),
        entries: &entries,
    })
}

/// The per-screen buffers.
pub struct SurfelTargets {
    pub width: u32,
    pub height: u32,
    uniforms: wgpu::Buffer,
    /// Per pixel: the complement of the offset front depth's bits, then of the nearest's.
    planes: wgpu::Buffer,
    sums: wgpu::Buffer,
    surface: wgpu::Buffer,
    albedo: wgpu::Buffer,
    /// Surfels drawn: planar, curved.
    counts: wgpu::Buffer,
    pub counts_readback: AsyncReadback,
    /// Per arena drawn, the curved surfels the planar depth pass listed (thread_listing.wgsl).
    curved_lists: Vec<wgpu::Buffer>,
}

impl SurfelTargets {
    pub fn new(device: &wgpu::Device, width: u32, height: u32) -> SurfelTargets {
        let pixels = width as u64 * height as u64;
        let storage = |label: &str, bytes: u64| plane_buffer(device, label, bytes);
        SurfelTargets {
            width,
            height,
            uniforms: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("surfel uniforms"),
                size: std::mem::size_of::<SurfelUniforms>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            planes: storage("surfel depth planes", pixels * PLANE_WORDS * 4),
            sums: storage("surfel blend sums", pixels * SUM_WORDS * 4),
            surface: storage("surfel surface", pixels * 16),
            albedo: storage("surfel albedo", pixels * 4),
            counts: storage("surfel counts", 8),
            counts_readback: AsyncReadback::new(device, "surfel counts readback", 8),
            curved_lists: Vec::new(),
        }
    }

    /// One list of curved surfels per capacity (in surfels), kept from frame to frame and
    /// its capacity grown to the next power of two, so that nodes arriving do not remake them
    /// every frame.
    fn grow_curved_lists(&mut self, device: &wgpu::Device, capacities: &[u64]) {
        for (k, capacity) in capacities.iter().enumerate() {
            if self
                .curved_lists
                .get(k)
                .is_some_and(|b| b.size() >= (LIST_HEADER + capacity) * 4)
            {
                continue;
            }
            let list = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("surfel curved list"),
                size: (LIST_HEADER + capacity.next_power_of_two()) * 4,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::INDIRECT
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            match self.curved_lists.get_mut(k) {
                Some(old) => *old = list,
                None => self.curved_lists.push(list),
            }
        }
    }

    fn pixels(&self) -> u64 {
        self.width as u64 * self.height as u64
    }

    pub fn read_counts(&self, ctx: &GpuContext) -> Result<[u32; 2], ViewerError> {
        let bytes = read_buffer(ctx, &self.counts, 8)?;
        counts_from(&bytes)
            .ok_or_else(|| ViewerError::Gpu("the surfel counts came back short".into()))
    }

    pub fn read_albedo(&self, ctx: &GpuContext) -> Result<Vec<Option<[u8; 3]>>, ViewerError> {
        let bytes = read_buffer(ctx, &self.albedo, self.pixels() * 4)?;
        Ok(crate::pipelines::surface::albedo_from(&bytes))
    }

    pub fn read_surface(&self, ctx: &GpuContext) -> Result<Vec<Option<SurfacePixel>>, ViewerError> {
        let bytes = read_buffer(ctx, &self.surface, self.pixels() * 16)?;
        Ok(crate::pipelines::surface::surface_from(&bytes))
    }
}

/// Planar and curved surfel counts from the first eight bytes of a readback.
pub fn counts_from(bytes: &[u8]) -> Option<[u32; 2]> {
    let word = |k: usize| -> Option<u32> {
        Some(u32::from_le_bytes(
            bytes.get(4 * k..4 * k + 4)?.try_into().ok()?,
        ))
    };
    Some([word(0)?, word(1)?])
}
