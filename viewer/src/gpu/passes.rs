//! The compute passes every pipeline starts from: clear, projection (64-bit atomicMin, or two
//! 32-bit passes), unpack, per-arena resolve, and the final shading into the output image.

use super::cache::NodeCache;
use super::pyramid::{PyramidFrame, PyramidInputs, PyramidPasses, PyramidTargets};
use super::timing::Timer;
use crate::gpu::GpuContext;
use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

const FRAME_WGSL: &str = include_str!("../../shaders/frame.wgsl");

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
    pub edl_strength: f32,
    pub edl_radius: f32,
    pub background: u32,
    /// Arena bound to each slot of the fused finish pass (set by `encode`).
    pub arena_slots: [u32; 4],
}

/// One node's points inside an arena, as the projection shader reads it.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct GpuRange {
    pub start: u32,
    pub count: u32,
    pub first_group: u32,
    pub spacing: f32,
}

const GROUP_SIZE: u32 = 256;
const MAX_GROUPS_X: u32 = 65535;

pub(crate) fn module(device: &wgpu::Device, label: &str, parts: &[&str]) -> wgpu::ShaderModule {
    let mut src = String::from(FRAME_WGSL);
    for p in parts {
        src.push('\n');
        src.push_str(p);
    }
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(src.into()),
    })
}

fn pipeline(device: &wgpu::Device, label: &str, parts: &[&str]) -> wgpu::ComputePipeline {
    let m = module(device, label, parts);
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: None,
        module: &m,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    })
}

pub struct Passes {
    int64: bool,
    clear: wgpu::ComputePipeline,
    project64: Option<wgpu::ComputePipeline>,
    unpack: Option<wgpu::ComputePipeline>,
    depth32: wgpu::ComputePipeline,
    index32: wgpu::ComputePipeline,
    resolve: wgpu::ComputePipeline,
    shade: wgpu::ComputePipeline,
    /// Resolve and shade in one pass, for frames within `FINISH_SLOTS` arenas; `None` where the
    /// adapter allows too few storage buffers per stage.
    finish: Option<wgpu::ComputePipeline>,
    /// The fused pass reading the 32-bit planes, on a 64-bit device (for `force_int32`).
    finish32: Option<wgpu::ComputePipeline>,
    pyramid: PyramidPasses,
}

/// Arenas the fused finish pass binds at once (two storage buffers each).
const FINISH_SLOTS: usize = 4;

/// The per-pixel buffers and the output image for one viewport size.
pub struct Screen {
    pub width: u32,
    pub height: u32,
    /// The 64-bit (depth, index) per pixel, on the int64 path.
    pub keys: Option<wgpu::Buffer>,
    pub depths: wgpu::Buffer,
    indices: wgpu::Buffer,
    colours: wgpu::Buffer,
    pub output: wgpu::Texture,
    uniforms: wgpu::Buffer,
    /// The pyramid pipeline's buffers, made on its first frame at this size.
    pub pyramid: Option<PyramidTargets>,
}

/// Everything one frame draws.
pub struct FrameDraw<'a> {
    pub uniforms: &'a FrameUniforms,
    pub arenas: &'a [ArenaDraw],
    pub allow_fused: bool,
    /// Take the two-pass 32-bit projection even where 64-bit atomics are available (to
    /// compare both paths on the same resident nodes).
    pub force_int32: bool,
    /// Run the pyramid pipeline after resolve in place of the final shading.
    pub pyramid: Option<PyramidFrame>,
}

/// What one arena draws this frame.
pub struct ArenaDraw {
    pub arena: u32,
    pub ranges: Vec<GpuRange>,
}

impl Passes {
    pub fn new(ctx: &GpuContext) -> Passes {
        let d = &ctx.device;
        let project = include_str!("../../shaders/project.wgsl");
        let colour = include_str!("../../shaders/colour.wgsl");
        let edl = include_str!("../../shaders/edl.wgsl");
        let finish = include_str!("../../shaders/finish.wgsl");
        let fits_finish =
            d.limits().max_storage_buffers_per_shader_stage as usize >= 2 * FINISH_SLOTS + 2;
        let int64 = ctx.int64_atomics;
        Passes {
            int64,
            clear: pipeline(d, "clear", &[include_str!("../../shaders/clear.wgsl")]),
            project64: int64.then(|| {
                pipeline(
                    d,
                    "project int64",
                    &[include_str!("../../shaders/emit_int64.wgsl"), project],
                )
            }),
            unpack: int64
                .then(|| pipeline(d, "unpack", &[include_str!("../../shaders/unpack.wgsl")])),
            depth32: pipeline(
                d,
                "project depth32",
                &[include_str!("../../shaders/emit_depth32.wgsl"), project],
            ),
            index32: pipeline(
                d,
                "project index32",
                &[include_str!("../../shaders/emit_index32.wgsl"), project],
            ),
            resolve: pipeline(
                d,
                "resolve",
                &[colour, include_str!("../../shaders/resolve.wgsl")],
            ),
            shade: pipeline(d, "shade", &[edl, include_str!("../../shaders/shade.wgsl")]),
            finish: fits_finish.then(|| {
                let keys = if int64 {
                    include_str!("../../shaders/keys_int64.wgsl")
                } else {
                    include_str!("../../shaders/keys_int32.wgsl")
                };
                pipeline(d, "finish", &[keys, colour, edl, finish])
            }),
            finish32: (fits_finish && int64).then(|| {
                let keys = include_str!("../../shaders/keys_int32.wgsl");
                pipeline(d, "finish int32", &[keys, colour, edl, finish])
            }),
            pyramid: PyramidPasses::new(d),
        }
    }

    pub fn screen(&self, device: &wgpu::Device, width: u32, height: u32) -> Screen {
        let pixels = width as u64 * height as u64;
        let buffer = |label: &str, bytes: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes.max(16),
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        Screen {
            width,
            height,
            keys: self.int64.then(|| buffer("keys", pixels * 8)),
            depths: buffer("depths", pixels * 4),
            indices: buffer("indices", pixels * 4),
            colours: buffer("colours", pixels * 4),
            output: device.create_texture(&wgpu::TextureDescriptor {
                label: Some("output"),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba8Unorm,
                usage: wgpu::TextureUsages::STORAGE_BINDING
                    | wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            }),
            uniforms: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("frame uniforms"),
                size: std::mem::size_of::<FrameUniforms>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            pyramid: None,
        }
    }

    /// The pyramid pipeline's buffers for `screen`'s size.
    pub fn pyramid_targets(&self, device: &wgpu::Device, screen: &Screen) -> PyramidTargets {
        self.pyramid.targets(device, screen.width, screen.height)
    }

    /// Encodes every pass of one frame. Pass GPU times go to `timer` under their names.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        screen: &Screen,
        cache: &NodeCache,
        frame: &FrameDraw,
        timer: &mut Timer,
    ) {
        let draws = frame.arenas;
        let keys = screen.keys.as_ref().filter(|_| !frame.force_int32);
        let finish = if keys.is_some() || screen.keys.is_none() {
            self.finish.as_ref()
        } else {
            self.finish32.as_ref()
        };
        let fused = finish.filter(|_| {
            frame.allow_fused
                && frame.pyramid.is_none()
                && (1..=FINISH_SLOTS).contains(&draws.len())
        });
        let mut uniforms = *frame.uniforms;
        for (k, slot) in uniforms.arena_slots.iter_mut().enumerate() {
            *slot = draws.get(k).map_or(u32::MAX, |d| d.arena);
        }
        let device = &ctx.device;
        ctx.queue
            .write_buffer(&screen.uniforms, 0, bytemuck::bytes_of(&uniforms));
        let arena_groups: Vec<(wgpu::Buffer, u32, u32)> = draws
            .iter()
            .map(|d| {
                let mut table = Vec::with_capacity(d.ranges.len() + 1);
                table.push(GpuRange {
                    start: d.arena,
                    count: d.ranges.len() as u32,
                    first_group: 0,
                    spacing: 0.0,
                });
                let mut groups = 0u32;
                for r in &d.ranges {
                    table.push(GpuRange {
                        first_group: groups,
                        ..*r
                    });
                    groups += r.count.div_ceil(GROUP_SIZE);
                }
                let buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("ranges"),
                    contents: bytemuck::cast_slice(&table),
                    usage: wgpu::BufferUsages::STORAGE,
                });
                (buf, d.arena, groups)
            })
            .collect();
        let arena_bind = |pipe: &wgpu::ComputePipeline,
                          ranges: &wgpu::Buffer,
                          arena: u32,
                          with_attributes: bool| {
            let a = &cache.arenas[arena as usize];
            let mut entries = vec![
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: a.points.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: ranges.as_entire_binding(),
                },
            ];
            if with_attributes {
                entries.push(wgpu::BindGroupEntry {
                    binding: 2,
                    resource: a.attributes.as_entire_binding(),
                });
            }
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("arena"),
                layout: &pipe.get_bind_group_layout(1),
                entries: &entries,
            })
        };
        let frame_bind = |pipe: &wgpu::ComputePipeline, buffers: &[&wgpu::Buffer]| {
            let mut entries = vec![wgpu::BindGroupEntry {
                binding: 0,
                resource: screen.uniforms.as_entire_binding(),
            }];
            for (i, b) in buffers.iter().enumerate() {
                entries.push(wgpu::BindGroupEntry {
                    binding: i as u32 + 1,
                    resource: b.as_entire_binding(),
                });
            }
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("frame"),
                layout: &pipe.get_bind_group_layout(0),
                entries: &entries,
            })
        };
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
        let mut project =
            |name: &str, pipe: &wgpu::ComputePipeline, frame_buffers: &[&wgpu::Buffer]| {
                let fb = frame_bind(pipe, frame_buffers);
                let timestamp_writes = timer.pass(encoder, name);
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(name),
                    timestamp_writes,
                });
                pass.set_pipeline(pipe);
                pass.set_bind_group(0, &fb, &[]);
                for (ranges, arena, groups) in &arena_groups {
                    if *groups == 0 {
                        continue;
                    }
                    pass.set_bind_group(1, &arena_bind(pipe, ranges, *arena, false), &[]);
                    let (x, y) = split_groups(*groups);
                    pass.dispatch_workgroups(x, y, 1);
                }
            };
        match (&self.project64, keys) {
            (Some(p64), Some(keys)) => project("project", p64, &[keys]),
            _ => {
                project("project_depth", &self.depth32, &[&screen.depths]);
                project(
                    "project_index",
                    &self.index32,
                    &[&screen.depths, &screen.indices],
                );
            }
        }
        if let Some(finish) = fused {
            let view = screen.output.create_view(&Default::default());
            let mut entries = vec![
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: screen.uniforms.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
            ];
            match keys {
                Some(keys) => entries.push(wgpu::BindGroupEntry {
                    binding: 1,
                    resource: keys.as_entire_binding(),
                }),
                None => {
                    entries.push(wgpu::BindGroupEntry {
                        binding: 1,
                        resource: screen.depths.as_entire_binding(),
                    });
                    entries.push(wgpu::BindGroupEntry {
                        binding: 2,
                        resource: screen.indices.as_entire_binding(),
                    });
                }
            }
            let fb = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("finish"),
                layout: &finish.get_bind_group_layout(0),
                entries: &entries,
            });
            // Unused slots repeat the first arena: every binding must hold a buffer.
            let arena_entries: Vec<wgpu::BindGroupEntry> = (0..FINISH_SLOTS)
                .flat_map(|k| {
                    let a = &cache.arenas[draws.get(k).unwrap_or(&draws[0]).arena as usize];
                    [
                        wgpu::BindGroupEntry {
                            binding: 2 * k as u32,
                            resource: a.points.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2 * k as u32 + 1,
                            resource: a.attributes.as_entire_binding(),
                        },
                    ]
                })
                .collect();
            let ab = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("finish arenas"),
                layout: &finish.get_bind_group_layout(1),
                entries: &arena_entries,
            });
            let name = if uniforms.edl_strength > 0.0 {
                "finish+edl"
            } else {
                "finish"
            };
            let timestamp_writes = timer.pass(encoder, name);
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(name),
                timestamp_writes,
            });
            pass.set_pipeline(finish);
            pass.set_bind_group(0, &fb, &[]);
            pass.set_bind_group(1, &ab, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
            return;
        }
        if let (Some(unpack), Some(keys)) = (&self.unpack, keys) {
            let fb = frame_bind(unpack, &[keys, &screen.depths, &screen.indices]);
            let timestamp_writes = timer.pass(encoder, "unpack");
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("unpack"),
                timestamp_writes,
            });
            pass.set_pipeline(unpack);
            pass.set_bind_group(0, &fb, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }

        // Resolve, per arena.
        {
            let fb = frame_bind(
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
            for (ranges, arena, groups) in &arena_groups {
                if *groups == 0 {
                    continue;
                }
                pass.set_bind_group(1, &arena_bind(&self.resolve, ranges, *arena, true), &[]);
                pass.dispatch_workgroups(gx, gy, 1);
            }
        }

        if let (Some(pyramid), Some(targets)) = (&frame.pyramid, &screen.pyramid) {
            self.pyramid.encode(
                device,
                &ctx.queue,
                encoder,
                targets,
                &PyramidInputs {
                    frame_uniforms: &screen.uniforms,
                    depths: &screen.depths,
                    colours: &screen.colours,
                    output: &screen.output,
                },
                pyramid,
                timer,
            );
            return;
        }

        // Shade into the output image.
        {
            let view = screen.output.create_view(&Default::default());
            let bg = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("shade"),
                layout: &self.shade.get_bind_group_layout(0),
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
            let name = if uniforms.edl_strength > 0.0 {
                "edl"
            } else {
                "shade"
            };
            let timestamp_writes = timer.pass(encoder, name);
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(name),
                timestamp_writes,
            });
            pass.set_pipeline(&self.shade);
            pass.set_bind_group(0, &bg, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
    }
}

pub(crate) fn pixel_groups(width: u32, height: u32) -> (u32, u32) {
    (width.div_ceil(16), height.div_ceil(16))
}

/// Spreads `groups` workgroups over x and y within the per-dimension limit.
fn split_groups(groups: u32) -> (u32, u32) {
    if groups <= MAX_GROUPS_X {
        (groups.max(1), 1)
    } else {
        (MAX_GROUPS_X, groups.div_ceil(MAX_GROUPS_X))
    }
}
