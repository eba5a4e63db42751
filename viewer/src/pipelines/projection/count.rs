//! The count of points drawn while a filter is set: a pass over the drawn ranges applying the
//! frame's filters (count.wgsl), read back without stalling the frame (`AsyncReadback`).

use super::bind::{arena_bind, frame_bind};
use super::{ArenaGroup, FILTERS_WGSL, RANGE_SEARCH_WGSL, Screen, split_groups};
use crate::gpu::async_readback::AsyncReadback;
use crate::gpu::cache::NodeCache;
use crate::gpu::timing::Timer;
use crate::pipelines::shader::ShaderSource;

const COUNT_WGSL: &str = include_str!("count.wgsl");

/// The module the count pass compiles.
pub fn count_source() -> ShaderSource {
    ShaderSource::new(
        "count drawn",
        &[FILTERS_WGSL, RANGE_SEARCH_WGSL, COUNT_WGSL],
    )
}

pub struct DrawnCount {
    pipe: wgpu::ComputePipeline,
    counter: wgpu::Buffer,
    readback: AsyncReadback,
    /// The filters' generation of the count in flight.
    in_flight: u64,
    /// The latest count read back, with the generation of the filters it counted for.
    last: Option<(u64, u64)>,
    /// The generation of the filters of the frames encoded now.
    generation: u64,
}

impl DrawnCount {
    pub fn new(device: &wgpu::Device) -> DrawnCount {
        use wgpu::BufferUsages as U;
        DrawnCount {
            pipe: count_source().compute(device, None),
            counter: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("drawn count"),
                size: 4,
                usage: U::STORAGE | U::COPY_SRC | U::COPY_DST,
                mapped_at_creation: false,
            }),
            readback: AsyncReadback::new(device, "drawn count readback", 4),
            in_flight: 0,
            last: None,
            generation: 0,
        }
    }

    /// The filters changed: counts made for the earlier ones are not reported any more.
    pub fn filters_changed(&mut self) {
        self.generation += 1;
    }

    /// Counts the filtered points of `groups` and records the count's copy, unless the
    /// previous copy is still being read (the count would have nowhere to go).
    pub fn encode(
        &mut self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        screen: &Screen,
        cache: &NodeCache,
        groups: &[ArenaGroup],
        timer: &mut Timer,
    ) {
        if !self.readback.is_idle() {
            return;
        }
        encoder.clear_buffer(&self.counter, 0, None);
        {
            let fb = frame_bind(device, screen, &self.pipe, &[&self.counter]);
            let timestamp_writes = timer.pass(encoder, "count drawn");
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("count drawn"),
                timestamp_writes,
            });
            pass.set_pipeline(&self.pipe);
            pass.set_bind_group(0, &fb, &[]);
            for g in groups.iter().filter(|g| g.groups > 0) {
                pass.set_bind_group(1, &arena_bind(device, cache, &self.pipe, g, true), &[]);
                let (x, y) = split_groups(g.groups);
                pass.dispatch_workgroups(x, y, 1);
            }
        }
        if self.readback.record(encoder, &self.counter, 0, 4) {
            self.in_flight = self.generation;
        }
    }

    /// The frame it recorded a count in was never submitted (an error on the way).
    pub fn abandon(&mut self) {
        self.readback.abandon();
    }

    /// After the frame's submit: starts reading the count it recorded.
    pub fn after_submit(&mut self) {
        self.readback.after_submit();
    }

    /// The latest count read back for the current filters (taking in one that has arrived),
    /// `None` before any.
    pub fn latest(&mut self) -> Option<u64> {
        if let Some(bytes) = self.readback.take()
            && let Some(word) = bytes.get(..4).and_then(|b| <[u8; 4]>::try_from(b).ok())
        {
            self.last = Some((self.in_flight, u32::from_le_bytes(word) as u64));
        }
        self.last
            .filter(|(generation, _)| *generation == self.generation)
            .map(|(_, n)| n)
    }
}
