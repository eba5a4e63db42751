//! The facing check (facing.wgsl): whether the stored normals point out of the surfaces this
//! view shows, into them, or either way. Culling, the marks of back faces and the curved
//! surfels' bend all take the side it finds. Normals kept from the inputs carry no guarantee:
//! a mesh wound the other way, or a scan whose normals were turned away from its scanner,
//! points every normal inwards. No rule about a dataset tells which (an indoor scan's normals
//! point into the room, a statue's out of it), but a view does: the near side of a surface
//! is the one it shows. The check runs when the view or its nodes change, on a sample of the
//! drawn points; it is read back without stalling the frame, and its verdict changes only on
//! clear evidence.

use super::bind::frame_bind;
use super::{
    ArenaDraw, ArenaGroup, FILTERS_WGSL, GROUP_SIZE, OCT16_WGSL, RANGE_SEARCH_WGSL, Screen,
    split_groups,
};
use crate::gpu::async_readback::AsyncReadback;
use crate::gpu::cache::NodeCache;
use crate::gpu::timing::Timer;
use crate::pipelines::PointStream;
use crate::pipelines::shader::ShaderSource;

const FACING_WGSL: &str = include_str!("facing.wgsl");
/// Every STRIDE-th point of a drawn range is sampled (`STRIDE` in facing.wgsl).
const STRIDE: u32 = 4;
/// Pixels on a side of a cell (`CELL` in facing.wgsl).
const CELL: u32 = 4;
/// The timed pass.
pub const FACING_PASS: &str = "facing check";
/// Cells with one side clearly in front fewer than this: the view says nothing of
/// the normals (a terrain seen from above shows almost no side turned away).
const MIN_CELLS: u64 = 16;
/// The tallies' words (`tallies` in facing.wgsl).
const TALLY_BYTES: u64 = 8;

/// The modules the check compiles: the sample of the drawn points, then the count of cells.
pub fn facing_sources() -> [ShaderSource; 2] {
    let parts = [FILTERS_WGSL, RANGE_SEARCH_WGSL, OCT16_WGSL, FACING_WGSL];
    [
        ShaderSource::new("facing sample", &parts)
            .with_entry("sample")
            .with_constant("STRIDE", STRIDE as f64),
        ShaderSource::new("facing tally", &parts).with_entry("tally"),
    ]
}

/// Which side of the surfaces the stored normals point to, as the views so far show it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum NormalSides {
    /// Out of them, as stored.
    #[default]
    AsStored,
    /// Into them: each is turned before it is used.
    Turned,
    /// Either way: they mark no side (nothing is culled, no face is a back face).
    Mixed,
}

impl NormalSides {
    /// The normals tell a surface's sides apart.
    pub fn mark_sides(self) -> bool {
        self != NormalSides::Mixed
    }

    pub fn name(self) -> &'static str {
        match self {
            NormalSides::AsStored => "as stored",
            NormalSides::Turned => "turned",
            NormalSides::Mixed => "mixed",
        }
    }
}

/// What a check counted: the cells holding both sides where the side facing the eye lay
/// clearly in front, and where the side turned away did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tallies {
    pub towards_in_front: u32,
    pub away_in_front: u32,
}

/// The shares of cells with the side turned away in front that say each verdict clearly.
const AS_STORED: std::ops::RangeInclusive<f64> = 0.0..=0.25;
const MIXED: std::ops::RangeInclusive<f64> = 0.4..=0.6;
const TURNED: std::ops::RangeInclusive<f64> = 0.75..=1.0;

/// The verdict after a view that counted `t`, `now` the verdict so far (none before the
/// first view that says anything). Between the clear shares it stays, so that one view's
/// noise does not flip the picture back and forth; with no verdict to keep, it is the one
/// whose clear shares lie nearest.
pub fn verdict(now: Option<NormalSides>, t: Tallies) -> Option<NormalSides> {
    let both = t.towards_in_front as u64 + t.away_in_front as u64;
    if both < MIN_CELLS {
        return now;
    }
    let away = t.away_in_front as f64 / both as f64;
    let clear = [
        (AS_STORED, NormalSides::AsStored),
        (MIXED, NormalSides::Mixed),
        (TURNED, NormalSides::Turned),
    ];
    if let Some((_, sides)) = clear.iter().find(|(shares, _)| shares.contains(&away)) {
        return Some(*sides);
    }
    if now.is_some() {
        return now;
    }
    let off =
        |shares: &std::ops::RangeInclusive<f64>| (shares.start() - away).max(away - shares.end());
    clear
        .iter()
        .min_by(|a, b| off(&a.0).total_cmp(&off(&b.0)))
        .map(|(_, sides)| *sides)
}

pub struct FacingCheck {
    sample: wgpu::ComputePipeline,
    tally: wgpu::ComputePipeline,
    /// Three words per cell, and the screen size they were made for.
    cells: Option<(wgpu::Buffer, u32, u32)>,
    tallies: wgpu::Buffer,
    readback: AsyncReadback,
    /// The view whose check is in flight.
    in_flight: Option<u64>,
    /// The view whose check the verdict took in last.
    checked: Option<u64>,
    /// None until a view says anything (the normals are then taken as stored).
    sides: Option<NormalSides>,
}

impl FacingCheck {
    pub fn new(device: &wgpu::Device) -> FacingCheck {
        use wgpu::BufferUsages as U;
        let [sample, tally] = facing_sources().map(|s| s.compute(device, None));
        FacingCheck {
            sample,
            tally,
            cells: None,
            tallies: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("facing tallies"),
                size: TALLY_BYTES,
                usage: U::STORAGE | U::COPY_SRC | U::COPY_DST,
                mapped_at_creation: false,
            }),
            readback: AsyncReadback::new(device, "facing tallies readback", TALLY_BYTES),
            in_flight: None,
            checked: None,
            sides: None,
        }
    }

    pub fn sides(&self) -> NormalSides {
        self.sides.unwrap_or_default()
    }

    /// Whether the verdict has taken in the check of view `key`.
    pub fn settled(&self, key: u64) -> bool {
        self.checked == Some(key)
    }

    /// Checks view `key` (the arenas `draws` seen through the frame's uniforms), unless it
    /// was checked already or the previous check is still being read.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &mut self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        screen: &Screen,
        cache: &NodeCache,
        draws: &[ArenaDraw],
        key: u64,
        timer: &mut Timer,
    ) {
        if self.checked == Some(key) || !self.readback.is_idle() {
            return;
        }
        let cells = self.cells_for(device, screen.width, screen.height);
        encoder.clear_buffer(&cells, 0, None);
        encoder.clear_buffer(&self.tallies, 0, None);
        {
            let timestamp_writes = timer.pass(encoder, FACING_PASS);
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(FACING_PASS),
                timestamp_writes,
            });
            pass.set_pipeline(&self.sample);
            pass.set_bind_group(0, &frame_bind(device, screen, &self.sample, &[&cells]), &[]);
            for d in draws {
                let Some(arena) = cache.arenas.get(d.arena as usize) else {
                    continue;
                };
                let Some(normals) = arena.stream(PointStream::Normals) else {
                    continue;
                };
                let g = ArenaGroup::new(device, d, GROUP_SIZE * STRIDE);
                if g.groups == 0 {
                    continue;
                }
                let buffers = [&arena.points, &g.ranges, &arena.attributes, normals];
                let entries: Vec<wgpu::BindGroupEntry> = buffers
                    .iter()
                    .enumerate()
                    .map(|(binding, b)| wgpu::BindGroupEntry {
                        binding: binding as u32,
                        resource: b.as_entire_binding(),
                    })
                    .collect();
                let bound = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("facing sample"),
                    layout: &self.sample.get_bind_group_layout(1),
                    entries: &entries,
                });
                pass.set_bind_group(1, &bound, &[]);
                let (x, y) = split_groups(g.groups);
                pass.dispatch_workgroups(x, y, 1);
            }
            pass.set_pipeline(&self.tally);
            let fb = frame_bind(device, screen, &self.tally, &[&cells, &self.tallies]);
            pass.set_bind_group(0, &fb, &[]);
            let count = screen.width.div_ceil(CELL) * screen.height.div_ceil(CELL);
            let (x, y) = split_groups(count.div_ceil(GROUP_SIZE));
            pass.dispatch_workgroups(x, y, 1);
        }
        if self.readback.record(encoder, &self.tallies, 0, TALLY_BYTES) {
            self.in_flight = Some(key);
        }
    }

    /// The cells of a `width` x `height` screen, made anew when the size changes.
    fn cells_for(&mut self, device: &wgpu::Device, width: u32, height: u32) -> wgpu::Buffer {
        if let Some((buffer, w, h)) = &self.cells
            && (*w, *h) == (width, height)
        {
            return buffer.clone();
        }
        let count = width.div_ceil(CELL) as u64 * height.div_ceil(CELL) as u64;
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("facing cells"),
            size: count * 12,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        self.cells = Some((buffer.clone(), width, height));
        buffer
    }

    /// After the frame's submit: starts reading the check it recorded.
    pub fn after_submit(&mut self) {
        self.readback.after_submit();
    }

    /// Takes in a check that has arrived (after polling the device).
    pub fn take(&mut self) {
        let Some(bytes) = self.readback.take() else {
            return;
        };
        let word = |k: usize| {
            bytes
                .get(4 * k..4 * k + 4)
                .and_then(|b| <[u8; 4]>::try_from(b).ok())
                .map_or(0, u32::from_le_bytes)
        };
        let tallies = Tallies {
            towards_in_front: word(0),
            away_in_front: word(1),
        };
        self.sides = verdict(self.sides, tallies);
        self.checked = self.in_flight.take();
    }

    /// The frame it recorded a check in was never submitted (an error on the way).
    pub fn abandon(&mut self) {
        self.readback.abandon();
        self.in_flight = None;
    }
}

#[cfg(test)]
mod tests {
    use super::{NormalSides, Tallies, verdict};

    #[test]
    fn the_verdict_follows_the_side_in_front_and_holds_between_clear_shares() {
        use NormalSides::*;
        let v = |now, towards_in_front, away_in_front| {
            let t = Tallies {
                towards_in_front,
                away_in_front,
            };
            verdict(Some(now), t).unwrap_or(now)
        };
        // The near side faces the eye: as stored, whatever came before.
        assert_eq!(v(Turned, 950, 50), AsStored);
        // The near side turns away: the normals point into the surfaces.
        assert_eq!(v(AsStored, 40, 960), Turned);
        // Half and half: they mark no side.
        assert_eq!(v(AsStored, 500, 500), Mixed);
        // Between the clear shares, and with too few cells, the verdict stays.
        assert_eq!(v(Turned, 350, 650), Turned);
        assert_eq!(v(AsStored, 350, 650), AsStored);
        assert_eq!(v(Mixed, 680, 320), Mixed);
        assert_eq!(v(Turned, 0, 3), Turned);
        assert!(!Mixed.mark_sides());
        // The first view that says anything decides alone: between the clear shares, the
        // nearest.
        let first = |towards_in_front, away_in_front| {
            let t = Tallies {
                towards_in_front,
                away_in_front,
            };
            verdict(None, t)
        };
        assert_eq!(first(0, 3), None);
        assert_eq!(first(630, 370), Some(Mixed));
        assert_eq!(first(700, 300), Some(AsStored));
        assert_eq!(first(370, 630), Some(Mixed));
        assert_eq!(first(300, 700), Some(Turned));
        assert_eq!(first(500, 500), Some(Mixed));
    }
}
