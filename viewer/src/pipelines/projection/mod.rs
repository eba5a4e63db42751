//! The projection every pipeline starts from: clear, project (64-bit atomicMin, or two 32-bit
//! passes), then either a fused finish that resolves and shades in one pass (with the
//! pipeline's shading), or unpack and a per-arena resolve into depth and colour planes that
//! the pipeline's own passes read.

mod bind;
mod count;
mod facing;
mod screen;

pub use count::DrawnCount;
pub use facing::{FacingCheck, NormalSides};
pub use screen::{
    Screen, ScreenLimitError, check_screen, image_texture, largest_fitting, plane_buffer,
};

use super::ScreenBuffer;
use super::shader::ShaderSource;
use crate::gpu::GpuContext;
use crate::gpu::cache::NodeCache;
use crate::gpu::timing::Timer;
pub use bind::{ArenaGroup, range_table};
use bind::{arena_bind, frame_bind, project_arena_bind};
use bytemuck::{Pod, Zeroable};

pub const FRAME_WGSL: &str = include_str!("frame.wgsl");
const CLEAR_WGSL: &str = include_str!("clear.wgsl");
/// The projection pass, for pipelines that splat points with an `emit` of their own.
pub const PROJECT_WGSL: &str = include_str!("project.wgsl");
/// `culled(idx, pos)` by the Normals stream (group 1, binding 3), or never.
pub const CULL_WGSL: &str = include_str!("cull.wgsl");
pub const NO_CULL_WGSL: &str = include_str!("no_cull.wgsl");
/// `decode_oct16(word)`: a normal of the Normals stream (SPEC.md's oct16).
pub const OCT16_WGSL: &str = include_str!("oct16.wgsl");
/// `passes_filters(pos, attribute)`: the frame's point filters, for every pass that splats points.
pub const FILTERS_WGSL: &str = include_str!("filters.wgsl");
/// `range_of(group)`: the drawn range of a point workgroup, for every pass that walks them.
pub const RANGE_SEARCH_WGSL: &str = include_str!("range_search.wgsl");
const EMIT_INT64_WGSL: &str = include_str!("emit_int64.wgsl");
const EMIT_DEPTH32_WGSL: &str = include_str!("emit_depth32.wgsl");
const EMIT_INDEX32_WGSL: &str = include_str!("emit_index32.wgsl");
const UNPACK_WGSL: &str = include_str!("unpack.wgsl");
/// The colouring modes (RGB, intensity, classification, elevation) of a resolved point.
pub const COLOUR_WGSL: &str = include_str!("colour.wgsl");
const RESOLVE_WGSL: &str = include_str!("resolve.wgsl");
const KEYS_INT64_WGSL: &str = include_str!("keys_int64.wgsl");
const KEYS_INT32_WGSL: &str = include_str!("keys_int32.wgsl");
const FINISH_WGSL: &str = include_str!("finish.wgsl");
const SHADE_PLANES_WGSL: &str = include_str!("shade_planes.wgsl");

/// The projection's timed passes, in the order they can run.
pub const PASSES: [&str; 8] = [
    "clear",
    "project",
    "project_depth",
    "project_index",
    "count drawn",
    "unpack",
    "resolve",
    facing::FACING_PASS,
];

/// The per-frame uniforms, laid out as `Frame` in frame.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct FrameUniforms {
    pub view_proj: [[f32; 4]; 4],
    pub width: u32,
    pub height: u32,
    pub point_size: f32,
    pub size_mode: u32,
    pub focal_px: f32,
    pub colour_mode: u32,
    pub z_min: f32,
    pub z_max: f32,
    pub arena_shift: u32,
    pub background: u32,
    /// Clip boxes in `clip_boxes`.
    pub clip_count: u32,
    /// Points are drawn at least `footprint` times their stored radius across, where a
    /// pipeline declares the Radius stream and sets it (`Pipeline::uniforms`); 0: not at all.
    pub footprint: f32,
    /// The chosen pipeline's own shading parameters, set by `Pipeline::uniforms`.
    pub shading: [f32; 4],
    /// Arena bound to each slot of the fused finish pass (set by `encode`).
    pub arena_slots: [u32; FINISH_SLOTS],
    /// 1 / the intensity shown at full brightness when colouring by intensity.
    pub intensity_scale: f32,
    /// `FILTER_*` bits: which of the filters below apply.
    pub filters: u32,
    pub return_lo: u32,
    pub return_hi: u32,
    /// Intensity range (raw), then elevation range relative to the anchor.
    pub ranges: [f32; 4],
    /// Classes shown: bit c of word c / 32.
    pub class_mask: [[u32; 4]; 2],
    /// Box k: minimum at 2k (w 1: hides its inside), maximum at 2k + 1; relative to the anchor.
    pub clip_boxes: [[f32; 4]; 8],
    /// The eye, relative to the anchor, for the back-face culling of the projection.
    pub eye: [f32; 4],
    /// 1: the facing check found the stored normals pointing into the surfaces, and each is
    /// turned before use (`NormalSides::Turned`); 0: as stored.
    pub normals_turned: u32,
    /// The linear depths drawn, from `near` to `far` (`lod::clip_range`): compared as they
    /// are, not through the matrix's depth, which loses the far end in f32 at a large ratio.
    pub near: f32,
    pub far: f32,
    pub pad: [u32; 1],
}

/// The filter bits of `FrameUniforms::filters` (`FILTER_*` in frame.wgsl).
pub const FILTER_CLASSES: u32 = 1;
pub const FILTER_INTENSITY: u32 = 2;
pub const FILTER_ELEVATION: u32 = 4;
pub const FILTER_RETURN: u32 = 8;
pub const FILTER_CLIP: u32 = 16;
/// Points whose attribute word carries `marks::MARK_HIDDEN` are hidden.
pub const FILTER_MARKED: u32 = 32;

/// One node's points inside an arena, as the projection shader reads it (`Range`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct GpuRange {
    pub start: u32,
    pub count: u32,
    pub first_group: u32,
    /// The node's spacing: its level's, or for a leaf the larger of that and the covering
    /// radius of the density its points were measured at (`Tree::sampling`).
    pub spacing: f32,
    /// The node's centre, relative to the anchor.
    pub centre: [f32; 3],
    /// Bit k: the node's child in octant k (`NodeKey::child`) is drawn too; bit 8 + k: the
    /// dataset has that child; bit 16 + k: that child and every node below it are drawn, down
    /// to the leaves (what sizes each point by what the LOD drew where it lies reads them,
    /// `drawn_radius` in frame.wgsl).
    pub children: u32,
}

/// Threads per projection workgroup (`GROUP_SIZE` in frame.wgsl).
pub const GROUP_SIZE: u32 = 256;
/// The pixel value of a depth or key plane where no point landed (`EMPTY` in frame.wgsl).
pub const EMPTY: u32 = u32::MAX;
const MAX_GROUPS_X: u32 = 65535;
/// Arenas the fused finish pass binds at once (two storage buffers each).
pub const FINISH_SLOTS: usize = 4;

/// Everything one frame draws.
pub struct FrameDraw<'a> {
    pub uniforms: &'a FrameUniforms,
    pub arenas: &'a [ArenaDraw],
    pub allow_fused: bool,
    /// Take the two-pass 32-bit projection even where 64-bit atomics are available (to
    /// compare both paths on the same resident nodes).
    pub force_int32: bool,
    /// The pipeline's fused finish and its pass name, where it has one.
    pub fused: Option<(&'a FusedFinish, &'static str)>,
    /// Skip the points whose normal faces away from the eye (the arenas hold the Normals
    /// stream, and the dataset's normals face outwards).
    pub cull_back_faces: bool,
    /// Resolve the colour plane (the pipeline reads it).
    pub resolve_colours: bool,
    /// Unpack the 64-bit keys into the depth and index planes (the pipeline reads them; the
    /// colour resolve does in any case).
    pub unpack_planes: bool,
}

/// What one arena draws this frame.
pub struct ArenaDraw {
    pub arena: u32,
    pub ranges: Vec<GpuRange>,
}

/// The projection's compiled passes.
pub struct Projection {
    int64: bool,
    clear: wgpu::ComputePipeline,
    plain: ProjectPasses,
    /// The same passes culling back faces by the Normals stream.
    culling: ProjectPasses,
    unpack: Option<wgpu::ComputePipeline>,
    resolve: wgpu::ComputePipeline,
}

/// Every module the projection compiles, as it composes them: the projection passes once
/// drawing every point and once culling back faces (`culled` labels).
pub fn shaders(int64: bool) -> Vec<ShaderSource> {
    let mut s = vec![
        ShaderSource::new("clear", &[CLEAR_WGSL]),
        ShaderSource::new("resolve", &[COLOUR_WGSL, RESOLVE_WGSL]),
    ];
    for cull in [false, true] {
        let label = |plain: &'static str, culling: &'static str| if cull { culling } else { plain };
        s.push(project_source(
            label("project depth32", "project depth32 culled"),
            EMIT_DEPTH32_WGSL,
            cull,
        ));
        s.push(project_source(
            label("project index32", "project index32 culled"),
            EMIT_INDEX32_WGSL,
            cull,
        ));
        if int64 {
            s.push(project_source(
                label("project int64", "project int64 culled"),
                EMIT_INT64_WGSL,
                cull,
            ));
        }
    }
    if int64 {
        s.push(ShaderSource::new("unpack", &[UNPACK_WGSL]));
    }
    s.push(count::count_source());
    s.extend(facing::facing_sources());
    s
}

/// The projection pass with `emit`, culling back faces or not.
fn project_source(label: &'static str, emit: &'static str, cull: bool) -> ShaderSource {
    let culling: &[&'static str] = if cull {
        &[OCT16_WGSL, CULL_WGSL]
    } else {
        &[OCT16_WGSL, NO_CULL_WGSL]
    };
    let mut parts = vec![emit, FILTERS_WGSL, RANGE_SEARCH_WGSL];
    parts.extend_from_slice(culling);
    parts.push(PROJECT_WGSL);
    ShaderSource::new(label, &parts)
}

fn compile(ctx: &GpuContext, label: &str) -> Option<wgpu::ComputePipeline> {
    shaders(ctx.int64_atomics)
        .into_iter()
        .find(|s| s.label == label)
        .map(|s| s.compute(&ctx.device, None))
}

/// The projection passes of one culling rule.
struct ProjectPasses {
    project64: Option<wgpu::ComputePipeline>,
    depth32: wgpu::ComputePipeline,
    index32: wgpu::ComputePipeline,
}

impl ProjectPasses {
    fn new(ctx: &GpuContext, cull: bool) -> Result<ProjectPasses, crate::ViewerError> {
        let suffix = if cull { " culled" } else { "" };
        let need = |label: String| {
            compile(ctx, &label)
                .ok_or_else(|| crate::ViewerError::Gpu(format!("no shader named {label}")))
        };
        Ok(ProjectPasses {
            project64: compile(ctx, &format!("project int64{suffix}")),
            depth32: need(format!("project depth32{suffix}"))?,
            index32: need(format!("project index32{suffix}"))?,
        })
    }
}

impl Projection {
    pub fn new(ctx: &GpuContext) -> Result<Projection, crate::ViewerError> {
        let need = |label: &str| {
            compile(ctx, label)
                .ok_or_else(|| crate::ViewerError::Gpu(format!("no shader named {label}")))
        };
        Ok(Projection {
            int64: ctx.int64_atomics,
            clear: need("clear")?,
            plain: ProjectPasses::new(ctx, false)?,
            culling: ProjectPasses::new(ctx, true)?,
            unpack: compile(ctx, "unpack"),
            resolve: need("resolve")?,
        })
    }

    /// The buffers a `width` x `height` screen needs, for the limits check.
    pub fn screen_buffers(&self, width: u32, height: u32) -> Vec<ScreenBuffer> {
        Screen::buffers(self.int64, width, height)
    }

    pub fn screen(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        width: u32,
        height: u32,
        previous: bool,
    ) -> Screen {
        Screen::new(device, queue, self.int64, width, height, previous)
    }

    #[allow(clippy::too_many_arguments)]
    /// Encodes clear and projection, then the fused finish where `fused` is given and the
    /// frame allows it (returns true: the output image is written), else unpack into the depth
    /// plane and, where the pipeline reads it, resolve the colour plane (returns false: the
    /// pipeline shades).
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        screen: &Screen,
        cache: &NodeCache,
        frame: &FrameDraw,
        count: &mut DrawnCount,
        timer: &mut Timer,
    ) -> bool {
        let draws = frame.arenas;
        let keys = screen.keys.as_ref().filter(|_| !frame.force_int32);
        let fused = frame
            .fused
            .and_then(|(f, name)| {
                let pipe = if keys.is_some() || screen.keys.is_none() {
                    f.finish.as_ref()
                } else {
                    f.finish32.as_ref()
                };
                pipe.map(|p| (p, name))
            })
            .filter(|_| frame.allow_fused && (1..=FINISH_SLOTS).contains(&draws.len()));
        let mut uniforms = *frame.uniforms;
        for (k, slot) in uniforms.arena_slots.iter_mut().enumerate() {
            *slot = draws.get(k).map_or(u32::MAX, |d| d.arena);
        }
        let device = &ctx.device;
        ctx.queue
            .write_buffer(&screen.uniforms, 0, bytemuck::bytes_of(&uniforms));
        let arena_groups: Vec<ArenaGroup> = draws
            .iter()
            .map(|d| ArenaGroup::new(device, d, GROUP_SIZE))
            .collect();
        let (gx, gy) = pixel_groups(screen.width, screen.height);

        // Clear.
        {
            let targets: Vec<&wgpu::Buffer> = match keys {
                Some(k) => vec![k],
                None => vec![&screen.depths, &screen.indices],
            };
            let timestamp_writes = timer.pass(encoder, "clear");
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("clear"),
                timestamp_writes,
            });
            pass.set_pipeline(&self.clear);
            for t in targets {
                let words = (t.size() / 4) as u32;
                let bg = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("clear"),
                    layout: &self.clear.get_bind_group_layout(0),
                    entries: &[wgpu::BindGroupEntry {
                        binding: 0,
                        resource: t.as_entire_binding(),
                    }],
                });
                pass.set_bind_group(0, &bg, &[]);
                let (x, y) = split_groups(words.div_ceil(GROUP_SIZE));
                pass.dispatch_workgroups(x, y, 1);
            }
        }

        // Projection.
        let passes = if frame.cull_back_faces {
            &self.culling
        } else {
            &self.plain
        };
        let mut project =
            |name: &str, pipe: &wgpu::ComputePipeline, frame_buffers: &[&wgpu::Buffer]| {
                let fb = frame_bind(device, screen, pipe, frame_buffers);
                let timestamp_writes = timer.pass(encoder, name);
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(name),
                    timestamp_writes,
                });
                pass.set_pipeline(pipe);
                pass.set_bind_group(0, &fb, &[]);
                for g in &arena_groups {
                    if g.groups == 0 {
                        continue;
                    }
                    let bound = project_arena_bind(device, cache, pipe, g, frame.cull_back_faces);
                    let Some(bound) = bound else { continue };
                    pass.set_bind_group(1, &bound, &[]);
                    let (x, y) = split_groups(g.groups);
                    pass.dispatch_workgroups(x, y, 1);
                }
            };
        match (&passes.project64, keys) {
            (Some(p64), Some(keys)) => project("project", p64, &[keys]),
            _ => {
                project("project_depth", &passes.depth32, &[&screen.depths]);
                project(
                    "project_index",
                    &passes.index32,
                    &[&screen.depths, &screen.indices],
                );
            }
        }
        // Without a filter every point of the drawn nodes is drawn: nothing to count.
        if uniforms.filters != 0 {
            count.encode(device, encoder, screen, cache, &arena_groups, timer);
        }
        if let Some((finish, name)) = fused {
            bind::encode_fused(
                device, encoder, screen, cache, draws, keys, finish, name, timer,
            );
            return true;
        }
        // The colour resolve reads the planes too.
        let planes = frame.unpack_planes || frame.resolve_colours;
        if let (Some(unpack), Some(keys), true) = (&self.unpack, keys, planes) {
            let fb = frame_bind(
                device,
                screen,
                unpack,
                &[keys, &screen.depths, &screen.indices],
            );
            let timestamp_writes = timer.pass(encoder, "unpack");
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("unpack"),
                timestamp_writes,
            });
            pass.set_pipeline(unpack);
            pass.set_bind_group(0, &fb, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }

        if !frame.resolve_colours {
            return false;
        }
        // Resolve, per arena.
        let fb = frame_bind(
            device,
            screen,
            &self.resolve,
            &[&screen.depths, &screen.indices, &screen.colours],
        );
        let timestamp_writes = timer.pass(encoder, "resolve");
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("resolve"),
            timestamp_writes,
        });
        pass.set_pipeline(&self.resolve);
        pass.set_bind_group(0, &fb, &[]);
        for g in &arena_groups {
            if g.groups == 0 {
                continue;
            }
            pass.set_bind_group(1, &arena_bind(device, cache, &self.resolve, g, true), &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        false
    }
}

/// A pass that resolves each pixel's point, colours and shades it in one go, for frames whose
/// points lie in at most `FINISH_SLOTS` arenas. A pipeline gives the shading as a WGSL
/// function `shade_pixel(id: vec2<u32>, d: u32, rgb: vec3<f32>) -> vec3<f32>`.
pub struct FusedFinish {
    finish: Option<wgpu::ComputePipeline>,
    /// The variant reading the 32-bit planes on a 64-bit device (for `force_int32`).
    finish32: Option<wgpu::ComputePipeline>,
}

impl FusedFinish {
    /// Every module `new` compiles for `label` and `shading`; none where the adapter allows
    /// too few storage buffers per stage (then frames take the separate passes).
    pub fn shaders(
        int64: bool,
        fits: bool,
        label: &'static str,
        shading: &[&'static str],
    ) -> Vec<ShaderSource> {
        if !fits {
            return Vec::new();
        }
        let with_keys = |label, keys| {
            let mut parts = vec![keys, COLOUR_WGSL];
            parts.extend_from_slice(shading);
            parts.push(FINISH_WGSL);
            ShaderSource::new(label, &parts)
        };
        let keys = if int64 {
            KEYS_INT64_WGSL
        } else {
            KEYS_INT32_WGSL
        };
        let mut s = vec![with_keys(label, keys)];
        if int64 {
            s.push(with_keys(label, KEYS_INT32_WGSL));
        }
        s
    }

    pub fn new(ctx: &GpuContext, label: &'static str, shading: &[&'static str]) -> FusedFinish {
        let fits = fused_fits(&ctx.device);
        let mut compiled = FusedFinish::shaders(ctx.int64_atomics, fits, label, shading)
            .into_iter()
            .map(|s| s.compute(&ctx.device, None));
        FusedFinish {
            finish: compiled.next(),
            finish32: compiled.next(),
        }
    }
}

/// Whether the adapter binds enough storage buffers per stage for the fused finish.
pub fn fused_fits(device: &wgpu::Device) -> bool {
    device.limits().max_storage_buffers_per_shader_stage as usize >= 2 * FINISH_SLOTS + 2
}

/// One full-screen pass that shades the resolved depth and colour planes into the output,
/// with a pipeline's `shade_pixel` (the separate-pass counterpart of `FusedFinish`).
pub struct PlaneShading {
    pipe: wgpu::ComputePipeline,
}

impl PlaneShading {
    pub fn shader(label: &'static str, shading: &[&'static str]) -> ShaderSource {
        let mut parts = shading.to_vec();
        parts.insert(0, SHADE_PLANES_WGSL);
        ShaderSource::new(label, &parts)
    }

    pub fn new(ctx: &GpuContext, label: &'static str, shading: &[&'static str]) -> PlaneShading {
        PlaneShading {
            pipe: PlaneShading::shader(label, shading).compute(&ctx.device, None),
        }
    }

    pub fn encode(
        &self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        screen: &Screen,
        name: &str,
        timer: &mut Timer,
    ) {
        let view = screen.output.create_view(&Default::default());
        let bg = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(name),
            layout: &self.pipe.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: screen.uniforms.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: screen.depths.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: screen.colours.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
            ],
        });
        let timestamp_writes = timer.pass(encoder, name);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(name),
            timestamp_writes,
        });
        pass.set_pipeline(&self.pipe);
        pass.set_bind_group(0, &bg, &[]);
        let (gx, gy) = pixel_groups(screen.width, screen.height);
        pass.dispatch_workgroups(gx, gy, 1);
    }
}

/// Pixels on a side of a full-screen pass's workgroup (`@workgroup_size(16, 16)`).
pub const PIXEL_GROUP: u32 = 16;

/// Workgroups of `PIXEL_GROUP`² pixels covering a `width` x `height` image.
pub fn pixel_groups(width: u32, height: u32) -> (u32, u32) {
    (width.div_ceil(PIXEL_GROUP), height.div_ceil(PIXEL_GROUP))
}

/// Spreads `groups` workgroups over x and y within the per-dimension limit.
pub fn split_groups(groups: u32) -> (u32, u32) {
    if groups <= MAX_GROUPS_X {
        (groups.max(1), 1)
    } else {
        (MAX_GROUPS_X, groups.div_ceil(MAX_GROUPS_X))
    }
}
