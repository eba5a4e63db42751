//! Bind groups of the projection's passes: the frame's planes, each arena's points and range
//! table, and the fused finish pass that binds up to four arenas at once.

use super::{ArenaDraw, FINISH_SLOTS, GpuRange, Screen, pixel_groups};
use crate::gpu::cache::NodeCache;
use crate::gpu::timing::Timer;
use crate::pipelines::PointStream;
use wgpu::util::DeviceExt;

/// One arena's range table on the GPU and the workgroups its points take.
pub struct ArenaGroup {
    pub ranges: wgpu::Buffer,
    pub arena: u32,
    pub groups: u32,
}

impl ArenaGroup {
    pub fn new(device: &wgpu::Device, d: &ArenaDraw, group_size: u32) -> ArenaGroup {
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
            groups += r.count.div_ceil(group_size);
        }
        let ranges = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("ranges"),
            contents: bytemuck::cast_slice(&table),
            usage: wgpu::BufferUsages::STORAGE,
        });
        ArenaGroup {
            ranges,
            arena: d.arena,
            groups,
        }
    }
}

pub fn arena_bind(
    device: &wgpu::Device,
    cache: &NodeCache,
    pipe: &wgpu::ComputePipeline,
    g: &ArenaGroup,
    with_attributes: bool,
) -> wgpu::BindGroup {
    let a = &cache.arenas[g.arena as usize];
    let mut entries = vec![
        wgpu::BindGroupEntry {
            binding: 0,
            resource: a.points.as_entire_binding(),
        },
        wgpu::BindGroupEntry {
            binding: 1,
            resource: g.ranges.as_entire_binding(),
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
}

/// Group 1 of the culling projection: points, ranges, attributes and the Normals stream;
/// `None` where the arena holds no normals (the renderer culls only where the pipeline
/// declared the stream).
pub fn arena_bind_with_normals(
    device: &wgpu::Device,
    cache: &NodeCache,
    pipe: &wgpu::ComputePipeline,
    g: &ArenaGroup,
) -> Option<wgpu::BindGroup> {
    let a = cache.arenas.get(g.arena as usize)?;
    let normals = a.stream(PointStream::Normals)?;
    let entries: Vec<wgpu::BindGroupEntry> = [&a.points, &g.ranges, &a.attributes, normals]
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: b.as_entire_binding(),
        })
        .collect();
    Some(device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("arena with normals"),
        layout: &pipe.get_bind_group_layout(1),
        entries: &entries,
    }))
}

/// Group 0: the frame uniforms, then `buffers` from binding 1 on.
pub fn frame_bind(
    device: &wgpu::Device,
    screen: &Screen,
    pipe: &wgpu::ComputePipeline,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
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
}

/// The fused finish: per pixel, fetch the nearest point from its arena, colour, shade, write.
#[allow(clippy::too_many_arguments)]
pub fn encode_fused(
    device: &wgpu::Device,
    encoder: &mut wgpu::CommandEncoder,
    screen: &Screen,
    cache: &NodeCache,
    draws: &[ArenaDraw],
    keys: Option<&wgpu::Buffer>,
    finish: &wgpu::ComputePipeline,
    name: &str,
    timer: &mut Timer,
) {
    let Some(first) = draws.first() else { return };
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
            let a = &cache.arenas[draws.get(k).unwrap_or(first).arena as usize];
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
    let timestamp_writes = timer.pass(encoder, name);
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(name),
        timestamp_writes,
    });
    pass.set_pipeline(finish);
    pass.set_bind_group(0, &fb, &[]);
    pass.set_bind_group(1, &ab, &[]);
    let (gx, gy) = pixel_groups(screen.width, screen.height);
    pass.dispatch_workgroups(gx, gy, 1);
}
