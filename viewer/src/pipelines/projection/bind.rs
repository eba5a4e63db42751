//! Bind groups of the projection's passes: the frame's planes, each arena's points and range
//! table, and the fused finish pass that binds up to four arenas at once.

use super::{ArenaDraw, FINISH_SLOTS, GpuRange, Screen, pixel_groups};
use crate::gpu::cache::NodeCache;
use crate::gpu::timing::Timer;
use crate::pipelines::PointStream;
use bytemuck::Zeroable;
use wgpu::util::DeviceExt;

/// One arena's range table on the GPU and the workgroups its points take.
pub struct ArenaGroup {
    pub ranges: wgpu::Buffer,
    pub arena: u32,
    pub groups: u32,
}

/// The range table of arena `arena` (a header row: start = arena, count = rows; then each range
/// with the first workgroup of its points) and the workgroups of `group_size` all its points
/// take. The rows are in the order of their starts, and so of their first workgroups: a pass
/// finds a row by either with one binary search (range_search.wgsl).
pub fn range_table(arena: u32, ranges: &[GpuRange], group_size: u32) -> (Vec<GpuRange>, u32) {
    let mut sorted = ranges.to_vec();
    sorted.sort_by_key(|r| r.start);
    let mut table = Vec::with_capacity(ranges.len() + 1);
    table.push(GpuRange {
        start: arena,
        count: ranges.len() as u32,
        ..GpuRange::zeroed()
    });
    let mut groups = 0u32;
    for r in &sorted {
        table.push(GpuRange {
            first_group: groups,
            ..*r
        });
        groups += r.count.div_ceil(group_size);
    }
    (table, groups)
}

impl ArenaGroup {
    pub fn new(device: &wgpu::Device, d: &ArenaDraw, group_size: u32) -> ArenaGroup {
        let (table, groups) = range_table(d.arena, &d.ranges, group_size);
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

/// Group 1 of the projection: points, ranges, attributes, the Normals and the Radius stream (the
/// points again where the arena holds none: the frame's footprint is then 0, and only the
/// culling reads the normals). `None` where it culls and the arena holds no normals (the
/// renderer culls only where the pipeline declared the stream).
pub fn project_arena_bind(
    device: &wgpu::Device,
    cache: &NodeCache,
    pipe: &wgpu::ComputePipeline,
    g: &ArenaGroup,
    cull: bool,
) -> Option<wgpu::BindGroup> {
    let a = cache.arenas.get(g.arena as usize)?;
    let normals = match a.stream(PointStream::Normals) {
        Some(n) => n,
        None if cull => return None,
        None => &a.points,
    };
    let radii = a.stream(PointStream::Radius).unwrap_or(&a.points);
    let buffers = [
        (0, &a.points),
        (1, &g.ranges),
        (2, &a.attributes),
        (3, normals),
        (4, radii),
    ];
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .into_iter()
        .map(|(binding, b)| wgpu::BindGroupEntry {
            binding,
            resource: b.as_entire_binding(),
        })
        .collect();
    Some(device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("projected arena"),
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
