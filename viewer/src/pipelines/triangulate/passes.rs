//! The triangulation's GPU passes in the paper's order (its Figure 2 and Table 1): reproject
//! the previous frame's depth, keep the projected points in front of it (per arena, with their
//! search radii), search the sector neighbours (one 64-bit pass, or two), estimate normals
//! (with the radius feedback), rasterize the fans, keep each point's next radius (per arena),
//! shade, count holes.

use super::targets::{COUNT_WORDS, TriangulateTargets};
use crate::ViewerError;
use crate::gpu::GpuContext;
use crate::gpu::timing::Timer;
use crate::pipelines::projection::{
    ArenaGroup, GROUP_SIZE, OCT16_WGSL, RANGE_SEARCH_WGSL, pixel_groups,
};
use crate::pipelines::shader::{ShaderSource, Variants};
use crate::pipelines::{BOX_WALK_WGSL, LIGHTING_WGSL, PipelineFrame, PointStream};
use bytemuck::{Pod, Zeroable};

pub(super) const UNIFORMS_WGSL: &str = include_str!("uniforms.wgsl");
const COUNTS_WGSL: &str = include_str!("counts.wgsl");
const REPROJECT_WGSL: &str = include_str!("reproject.wgsl");
const GATHER_WGSL: &str = include_str!("gather.wgsl");
const SEARCH_WGSL: &str = include_str!("search.wgsl");
const RAYS_WGSL: &str = include_str!("rays.wgsl");
const SEARCH_DISTANCES_WGSL: &str = include_str!("search_distances.wgsl");
const SEARCH_IDS_WGSL: &str = include_str!("search_ids.wgsl");
const SEARCH_INT64_WGSL: &str = include_str!("search_int64.wgsl");
const FAN_WGSL: &str = include_str!("fan.wgsl");
const NORMALS_WGSL: &str = include_str!("normals.wgsl");
const RASTER_WGSL: &str = include_str!("raster.wgsl");
pub(super) const RASTER_SUMS32_WGSL: &str = include_str!("raster_sums32.wgsl");
pub(super) const RASTER_SUMS64_WGSL: &str = include_str!("raster_sums64.wgsl");
const RADII_WGSL: &str = include_str!("radii.wgsl");
const SHADE_WGSL: &str = include_str!("shade.wgsl");
pub(super) const SHADE_SUMS32_WGSL: &str = include_str!("shade_sums32.wgsl");
pub(super) const SHADE_SUMS64_WGSL: &str = include_str!("shade_sums64.wgsl");
const HOLES_WGSL: &str = include_str!("holes.wgsl");

/// Each point's kept value: its search radius and the last feedback distance (two f32).
pub const RADIUS_STREAM: PointStream = PointStream::Kept {
    name: "triangulate radius",
    bytes: 8,
};

/// Storage buffers the gather binds in one stage (the most of its passes; the raster binds 9).
/// The variants without `SIDES` bind what the sided ones use too (the normals, the back
/// faces' sums): the bind groups are the same for both.
pub(super) const STORAGE_BUFFERS: u32 = 10;

/// The triangulation's uniforms, laid out as `Triangulate` in uniforms.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct TriangulateUniforms {
    pub eye: [f32; 4],
    pub forward: [f32; 4],
    pub right: [f32; 4],
    pub up: [f32; 4],
    pub prev_eye: [f32; 4],
    pub prev_forward: [f32; 4],
    pub prev_right: [f32; 4],
    pub prev_up: [f32; 4],
    pub max_connection: f32,
    pub spacing_factor: f32,
    pub previous: u32,
    pub max_search_px: u32,
    pub stored_normals: u32,
    pub pad0: u32,
    pub pad1: u32,
    pub pad2: u32,
}

/// Every module the triangulation compiles on a device with 64-bit atomic min/max (`int64`)
/// or without: the registry's list, for validation. The 64-bit sums' modules, which need the
/// other 64-bit atomics too, are validated apart (tests.rs).
pub fn shaders(int64: bool) -> Vec<ShaderSource> {
    shaders_for(int64, false)
}

/// Every module the triangulation compiles; `int64`: the device has 64-bit atomic min/max, and
/// the sector search takes one pass instead of two, whose keys the fans read in place;
/// `sums64`: it adds 64-bit atomics too, and the blend sums are two of them a fragment.
pub fn shaders_for(int64: bool, sums64: bool) -> Vec<ShaderSource> {
    let mut v = vec![
        own("triangulate reproject", &[REPROJECT_WGSL, RAYS_WGSL]),
        own("triangulate normals", &[NORMALS_WGSL, FAN_WGSL])
            .with_constant("NEIGHBOUR_STRIDE", neighbour_stride(int64)),
        own(
            "triangulate radii",
            &[RADII_WGSL, RAYS_WGSL, RANGE_SEARCH_WGSL],
        ),
        own("triangulate holes", &[HOLES_WGSL]),
    ];
    let [gather, distances, ids, search64, raster, shade] = sided_shaders(false, int64, sums64);
    v.extend([gather, distances, ids, raster, shade]);
    if int64 {
        v.push(search64);
    }
    v
}

/// Words per sector of what the fans read: the ids, or the 64-bit keys.
fn neighbour_stride(int64: bool) -> f64 {
    if int64 { 2.0 } else { 1.0 }
}

/// A triangulation module of `parts` after the uniforms and counters.
fn own(label: &'static str, parts: &[&'static str]) -> ShaderSource {
    let mut all = vec![UNIFORMS_WGSL, COUNTS_WGSL];
    all.extend_from_slice(parts);
    ShaderSource::new(label, &all)
}

/// The gather, the two searches and the 64-bit one (which only a device with 64-bit atomics
/// compiles), the raster and the shade, telling a surface's sides apart by the normals
/// (`SIDES`) or not; `int64` and `sums64` as for `shaders_for`.
pub(super) fn sided_shaders(sides: bool, int64: bool, sums64: bool) -> [ShaderSource; 6] {
    let (raster_sums, shade_sums) = if sums64 {
        (RASTER_SUMS64_WGSL, SHADE_SUMS64_WGSL)
    } else {
        (RASTER_SUMS32_WGSL, SHADE_SUMS32_WGSL)
    };
    [
        own(
            "triangulate gather",
            &[GATHER_WGSL, RAYS_WGSL, RANGE_SEARCH_WGSL, OCT16_WGSL],
        ),
        own(
            "triangulate search distances",
            &[SEARCH_DISTANCES_WGSL, RAYS_WGSL, SEARCH_WGSL],
        ),
        own(
            "triangulate search ids",
            &[SEARCH_IDS_WGSL, RAYS_WGSL, SEARCH_WGSL],
        ),
        own(
            "triangulate search",
            &[SEARCH_INT64_WGSL, RAYS_WGSL, SEARCH_WGSL],
        ),
        own(
            "triangulate raster",
            &[RASTER_WGSL, FAN_WGSL, BOX_WALK_WGSL, raster_sums],
        )
        .with_constant("NEIGHBOUR_STRIDE", neighbour_stride(int64)),
        own("triangulate shade", &[LIGHTING_WGSL, SHADE_WGSL, shade_sums]),
    ]
    .map(|s| s.with_constant("SIDES", sides as u32 as f64))
}

/// The passes compiled per `SIDES`: the gather, the searches, the raster and the shade.
struct SidedPasses {
    gather: wgpu::ComputePipeline,
    distances: wgpu::ComputePipeline,
    ids: wgpu::ComputePipeline,
    /// The one-pass 64-bit search, where the device has 64-bit atomics.
    search64: Option<wgpu::ComputePipeline>,
    raster: wgpu::ComputePipeline,
    shade: wgpu::ComputePipeline,
}

impl SidedPasses {
    fn new(device: &wgpu::Device, int64: bool, sums64: bool, sides: bool) -> SidedPasses {
        let [gather, distances, ids, search64, raster, shade] =
            sided_shaders(sides, int64, sums64);
        SidedPasses {
            gather: gather.compute(device, None),
            distances: distances.compute(device, None),
            ids: ids.compute(device, None),
            search64: int64.then(|| search64.compute(device, None)),
            raster: raster.compute(device, None),
            shade: shade.compute(device, None),
        }
    }
}

/// Makes a per-arena pass's group 1 for each arena drawn from, for its pipeline.
type ArenaGroups<'a> = dyn Fn(&wgpu::ComputePipeline) -> Vec<wgpu::BindGroup> + 'a;

pub struct TriangulatePasses {
    reproject: wgpu::ComputePipeline,
    /// The gather, the searches, the raster and the shade, per whether they tell a surface's
    /// sides apart.
    sided: Variants<bool, SidedPasses>,
    /// The device has 64-bit atomics (the sided passes then include the one-pass search).
    int64: bool,
    /// And 64-bit atomic adds (the blend sums are 64-bit).
    sums64: bool,
    normals: wgpu::ComputePipeline,
    radii: wgpu::ComputePipeline,
    holes: wgpu::ComputePipeline,
}

impl TriangulatePasses {
    pub fn new(ctx: &GpuContext) -> Result<TriangulatePasses, ViewerError> {
        ctx.require_storage_buffers("triangulate", STORAGE_BUFFERS)?;
        let int64 = ctx.int64_atomics;
        let mut compiled: std::collections::HashMap<&str, wgpu::ComputePipeline> =
            shaders_for(int64, ctx.int64_sums)
            .into_iter()
            .map(|s| (s.label, s.compute(&ctx.device, None)))
            .collect();
        let mut take = |label: &str| {
            compiled
                .remove(label)
                .ok_or_else(|| ViewerError::Gpu(format!("no triangulation shader {label}")))
        };
        let plain = SidedPasses {
            gather: take("triangulate gather")?,
            distances: take("triangulate search distances")?,
            ids: take("triangulate search ids")?,
            search64: if int64 {
                Some(take("triangulate search")?)
            } else {
                None
            },
            raster: take("triangulate raster")?,
            shade: take("triangulate shade")?,
        };
        Ok(TriangulatePasses {
            reproject: take("triangulate reproject")?,
            sided: Variants::new(false, plain),
            int64,
            sums64: ctx.int64_sums,
            normals: take("triangulate normals")?,
            radii: take("triangulate radii")?,
            holes: take("triangulate holes")?,
        })
    }

    pub fn encode(
        &mut self,
        frame: &PipelineFrame,
        encoder: &mut wgpu::CommandEncoder,
        t: &mut TriangulateTargets,
        uniforms: &TriangulateUniforms,
        timer: &mut Timer,
    ) -> Result<(), ViewerError> {
        let device = &frame.ctx.device;
        let screen = frame.screen;
        let (int64, sums64) = (self.int64, self.sums64);
        let sided = self.sided.get(frame.normals_mark_back_faces, |sides| {
            SidedPasses::new(device, int64, sums64, sides)
        });
        frame
            .ctx
            .queue
            .write_buffer(&t.uniforms, 0, bytemuck::bytes_of(uniforms));
        // Only the sided passes add to and read the back faces' sums.
        if frame.normals_mark_back_faces {
            encoder.clear_buffer(&t.back_sums, 0, None);
        }
        for b in [
            &t.reprojected,
            &t.points,
            &t.distances,
            &t.neighbours,
            &t.feedback,
            &t.sums,
            &t.front,
            &t.counts,
        ]
        .into_iter()
        .chain(&t.keys)
        {
            encoder.clear_buffer(b, 0, None);
        }
        let (gx, gy) = pixel_groups(screen.width, screen.height);
        // The arenas drawn from, each with its range table (a point's range by `range_holding`),
        // its kept radii and its normals.
        let mut arenas = Vec::with_capacity(frame.arenas.len());
        for d in frame.arenas {
            let (a, [kept, normals]) = frame
                .cache
                .arena_streams(d.arena, [RADIUS_STREAM, PointStream::Normals])?;
            let table = ArenaGroup::new(device, d, GROUP_SIZE).ranges;
            arenas.push((a, table, kept, normals));
        }
        let mut pass = |name: &str,
                        pipe: &wgpu::ComputePipeline,
                        own: &[&wgpu::Buffer],
                        per_arena: Option<&ArenaGroups>,
                        output: Option<&wgpu::TextureView>| {
            let mut entries: Vec<wgpu::BindGroupEntry> = [&screen.uniforms]
                .into_iter()
                .chain(own.iter().copied())
                .enumerate()
                .map(|(i, b)| wgpu::BindGroupEntry {
                    binding: i as u32,
                    resource: b.as_entire_binding(),
                })
                .collect();
            if let Some(view) = output {
                entries.push(wgpu::BindGroupEntry {
                    binding: entries.len() as u32,
                    resource: wgpu::BindingResource::TextureView(view),
                });
            }
            let bg = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(name),
                layout: &pipe.get_bind_group_layout(0),
                entries: &entries,
            });
            let groups = per_arena.map(|f| f(pipe));
            let timestamp_writes = timer.pass(encoder, name);
            let mut p = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(name),
                timestamp_writes,
            });
            p.set_pipeline(pipe);
            p.set_bind_group(0, &bg, &[]);
            match groups {
                Some(groups) => {
                    for g in &groups {
                        p.set_bind_group(1, g, &[]);
                        p.dispatch_workgroups(gx, gy, 1);
                    }
                }
                None => p.dispatch_workgroups(gx, gy, 1),
            }
        };
        let arena_group = |pipe: &wgpu::ComputePipeline, buffers: &[&wgpu::Buffer]| {
            let entries: Vec<wgpu::BindGroupEntry> = buffers
                .iter()
                .enumerate()
                .map(|(i, b)| wgpu::BindGroupEntry {
                    binding: i as u32,
                    resource: b.as_entire_binding(),
                })
                .collect();
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("triangulation arena"),
                layout: &pipe.get_bind_group_layout(1),
                entries: &entries,
            })
        };

        if let (Some(previous), 1) = (&screen.previous_depths, uniforms.previous) {
            pass(
                "reproject",
                &self.reproject,
                &[&t.uniforms, previous, &t.reprojected],
                None,
                None,
            );
        }
        let gather_groups = |pipe: &wgpu::ComputePipeline| {
            arenas
                .iter()
                .map(|(a, table, kept, normals)| {
                    arena_group(pipe, &[&a.points, table, kept, normals])
                })
                .collect()
        };
        pass(
            "triangulate gather",
            &sided.gather,
            &[
                &t.uniforms,
                &screen.depths,
                &screen.indices,
                &t.reprojected,
                &t.points,
                &t.counts,
                &t.point_normals,
            ],
            Some(&gather_groups),
            None,
        );
        // The sector neighbours the fans read: the 64-bit keys in place, or the ids.
        let neighbours = match (&sided.search64, &t.keys) {
            (Some(search), Some(keys)) => {
                pass(
                    "search",
                    search,
                    &[&t.uniforms, &t.points, keys, &t.point_normals],
                    None,
                    None,
                );
                keys
            }
            _ => {
                pass(
                    "search distances",
                    &sided.distances,
                    &[&t.uniforms, &t.points, &t.distances, &t.point_normals],
                    None,
                    None,
                );
                pass(
                    "search ids",
                    &sided.ids,
                    &[
                        &t.uniforms,
                        &t.points,
                        &t.distances,
                        &t.neighbours,
                        &t.point_normals,
                    ],
                    None,
                    None,
                );
                &t.neighbours
            }
        };
        pass(
            "normals",
            &self.normals,
            &[
                &t.uniforms,
                &t.points,
                neighbours,
                &t.normals,
                &t.feedback,
                &t.point_normals,
            ],
            None,
            None,
        );
        pass(
            "triangulate",
            &sided.raster,
            &[
                &t.points,
                neighbours,
                &t.normals,
                &screen.colours,
                &t.sums,
                &t.front,
                &t.counts,
                &t.uniforms,
                &t.back_sums,
                &t.point_normals,
            ],
            None,
            None,
        );
        let radii_groups = |pipe: &wgpu::ComputePipeline| {
            arenas
                .iter()
                .map(|(_, table, kept, _)| arena_group(pipe, &[table, kept]))
                .collect()
        };
        pass(
            "radii",
            &self.radii,
            &[&t.uniforms, &screen.indices, &t.points, &t.feedback],
            Some(&radii_groups),
            None,
        );
        let view = screen.output.create_view(&Default::default());
        pass(
            "triangulate shade",
            &sided.shade,
            &[
                &t.uniforms,
                &t.sums,
                &t.front,
                &t.reconstructed,
                &t.surface,
                &t.albedo,
                &t.back_sums,
            ],
            None,
            Some(&view),
        );
        pass(
            "holes",
            &self.holes,
            &[&t.reconstructed, &t.counts],
            None,
            None,
        );
        drop(arenas);
        t.counts_readback
            .record(encoder, &t.counts, 0, COUNT_WORDS * 4);
        Ok(())
    }
}
