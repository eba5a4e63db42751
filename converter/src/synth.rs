//! `strata synth`: deterministic procedural scenes of any size, generated in constant memory.
//!
//! Every point is a pure function of (seed, index), so batches are generated in parallel and
//! the same arguments always give the same file. Scenes sit at UTM-like coordinates
//! (x ~ 500 km, y ~ 4600 km) in metres at 1 mm resolution, like real survey data.

use crate::error::{ConvertError, Result};
use crate::input::las_layout::las_fields;
use crate::writers::{LasChoices, open_writer, write_then_finish};
use rayon::prelude::*;
use std::path::Path;
use strata_format::RowLayout;
use strata_format::number;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scene {
    /// Streets, buildings (roofs and walls), trees and ground.
    City,
    /// Rolling terrain with scattered trees.
    Terrain,
}

impl Scene {
    pub fn parse(s: &str) -> Option<Scene> {
        match s {
            "city" => Some(Scene::City),
            "terrain" => Some(Scene::Terrain),
            _ => None,
        }
    }
}

pub const SCALE: f64 = 0.001;
pub const ORIGIN: [f64; 3] = [500_000.0, 4_600_000.0, 0.0];
/// Points per square metre of ground.
const DENSITY: f64 = 20.0;
const BLOCK: f64 = 60.0;
const TREE_CELL: f64 = 12.0;
const BATCH: u64 = 1 << 20;

/// SplitMix64: a good 64-bit mix, enough for procedural placement.
#[inline]
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A deterministic generator, seeded by a seed and two stream numbers (also used by the
/// quality harness to sample meshes).
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64, a: u64, b: u64) -> Rng {
        Rng(mix(seed ^ mix(a ^ mix(b))))
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = mix(self.0);
        self.0
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Standard normal, by Box-Muller.
    pub fn gaussian(&mut self) -> f64 {
        let u1 = self.unit().max(1e-12);
        let u2 = self.unit();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

struct Building {
    x0: f64,
    y0: f64,
    x1: f64,
    y1: f64,
    height: f64,
    colour: [u16; 3],
}

struct Tree {
    x: f64,
    y: f64,
    radius: f64,
    crown: f64,
}

struct World {
    scene: Scene,
    seed: u64,
    side: f64,
}

impl World {
    fn ground(&self, x: f64, y: f64) -> f64 {
        let hills = match self.scene {
            Scene::City => 3.0,
            Scene::Terrain => 25.0,
        };
        hills * ((x / 310.0).sin() * (y / 270.0).cos())
            + 0.2 * hills * ((x / 47.0 + y / 61.0).sin())
            + 0.4 * ((x / 7.3).sin() * (y / 5.9).sin())
    }

    fn building(&self, bx: i64, by: i64) -> Option<Building> {
        if self.scene != Scene::City {
            return None;
        }
        let mut r = Rng::new(self.seed, 1 + bx as u64, by as u64);
        if r.unit() < 0.2 {
            return None; // a park
        }
        let w = 12.0 + r.unit() * 30.0;
        let d = 12.0 + r.unit() * 30.0;
        let x0 = bx as f64 * BLOCK + 8.0 + r.unit() * (BLOCK - 16.0 - w).max(0.0);
        let y0 = by as f64 * BLOCK + 8.0 + r.unit() * (BLOCK - 16.0 - d).max(0.0);
        let height = 6.0 + r.unit().powi(2) * 60.0;
        let shade = 120 + (r.next_u64() % 100) as u16;
        Some(Building {
            x0,
            y0,
            x1: x0 + w,
            y1: y0 + d,
            height,
            colour: [shade * 256, (shade - 20) * 256, (shade - 40) * 256],
        })
    }

    fn tree(&self, tx: i64, ty: i64) -> Option<Tree> {
        let mut r = Rng::new(self.seed, 7 + tx as u64, 11 + ty as u64);
        let p = match self.scene {
            Scene::City => 0.25,
            Scene::Terrain => 0.45,
        };
        if r.unit() > p {
            return None;
        }
        let x = (tx as f64 + 0.2 + 0.6 * r.unit()) * TREE_CELL;
        let y = (ty as f64 + 0.2 + 0.6 * r.unit()) * TREE_CELL;
        if let Some(b) = self.building((x / BLOCK).floor() as i64, (y / BLOCK).floor() as i64)
            && x > b.x0 - 6.0
            && x < b.x1 + 6.0
            && y > b.y0 - 6.0
            && y < b.y1 + 6.0
        {
            return None;
        }
        Some(Tree {
            x,
            y,
            radius: 2.0 + 3.0 * r.unit(),
            crown: 5.0 + 6.0 * r.unit(),
        })
    }

    /// Point `i`: position (local metres) and attributes.
    fn point(&self, i: u64) -> ([f64; 3], u8, [u16; 3], u16, u8, u8) {
        let mut r = Rng::new(self.seed, i, 0xC0FFEE);
        let pick = r.unit();
        // Walls: a random block's building, a random side.
        if self.scene == Scene::City && pick < 0.15 {
            let blocks = (self.side / BLOCK).ceil().max(1.0) as u64;
            let bx = (r.next_u64() % blocks) as i64;
            let by = (r.next_u64() % blocks) as i64;
            if let Some(b) = self.building(bx, by) {
                let t = r.unit();
                let (x, y) = match r.next_u64() % 4 {
                    0 => (b.x0 + t * (b.x1 - b.x0), b.y0),
                    1 => (b.x0 + t * (b.x1 - b.x0), b.y1),
                    2 => (b.x0, b.y0 + t * (b.y1 - b.y0)),
                    _ => (b.x1, b.y0 + t * (b.y1 - b.y0)),
                };
                let g = self.ground((b.x0 + b.x1) / 2.0, (b.y0 + b.y1) / 2.0);
                let z = g + r.unit() * b.height;
                let c = [
                    b.colour[0] / 2 + 20000,
                    b.colour[1] / 2 + 18000,
                    b.colour[2] / 2 + 16000,
                ];
                return ([x, y, z], 6, c, 900 + (r.next_u64() % 400) as u16, 1, 1);
            }
        }
        let x = r.unit() * self.side;
        let y = r.unit() * self.side;
        let g = self.ground(x, y);
        if let Some(b) = self.building((x / BLOCK).floor() as i64, (y / BLOCK).floor() as i64)
            && x >= b.x0
            && x <= b.x1
            && y >= b.y0
            && y <= b.y1
        {
            let gc = self.ground((b.x0 + b.x1) / 2.0, (b.y0 + b.y1) / 2.0);
            return (
                [x, y, gc + b.height],
                6,
                b.colour,
                1500 + (r.next_u64() % 500) as u16,
                1,
                1,
            );
        }
        let (tx, ty) = (
            (x / TREE_CELL).floor() as i64,
            (y / TREE_CELL).floor() as i64,
        );
        if let Some(t) = self.tree(tx, ty) {
            let d2 = (x - t.x).powi(2) + (y - t.y).powi(2);
            if d2 < t.radius * t.radius && r.unit() < 0.8 {
                let h = (t.radius * t.radius - d2).sqrt();
                let gt = self.ground(t.x, t.y);
                let top = r.unit() < 0.7;
                let z = gt + t.crown + if top { h } else { -h * 0.6 };
                let green = 90 + (r.next_u64() % 80) as u16;
                let ret = if top { 1 } else { 2 };
                return (
                    [x, y, z],
                    if t.crown > 7.0 { 5 } else { 4 },
                    [30 * 256, green * 256, 40 * 256],
                    400 + (r.next_u64() % 300) as u16,
                    ret,
                    2,
                );
            }
        }
        let asphalt = self.scene == Scene::City && ((x % BLOCK) < 8.0 || (y % BLOCK) < 8.0);
        let c = if asphalt {
            let v = 70 + (r.next_u64() % 30) as u16;
            [v * 256, v * 256, v * 256]
        } else {
            let v = (r.next_u64() % 40) as u16;
            [(110 + v) * 256, (130 + v) * 256, (70 + v / 2) * 256]
        };
        ([x, y, g], 2, c, 600 + (r.next_u64() % 600) as u16, 1, 1)
    }
}

/// The attribute layout synth writes: that of LAS point format 3, its GPS times adjusted
/// standard time (the header said GPS week time, which cannot pass 604 800 s; the scenes'
/// times start at 10^8 s).
pub fn synth_layout() -> RowLayout {
    let mut attributes = las_fields(3, &[]).0;
    for a in attributes.iter_mut().filter(|a| a.name == "gps_time") {
        a.time_base = Some(strata_format::TimeBase::GpsAdjustedStandard);
    }
    RowLayout::new(attributes)
}

/// Refuses a scene the disk under `output` cannot hold, before writing any of it (10^12
/// points ran on for hours towards 34 TB). LAZ is counted at a tenth of its rows, less than
/// any scene of ours compresses to, so that only what cannot fit is refused; PLY at its rows
/// with the position as three doubles where a row holds three 32-bit integers.
fn check_room(output: &Path, points: u64, stride: usize) -> Result<()> {
    let is = |ext: &str| {
        output
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case(ext))
    };
    let per_point = if is("laz") {
        stride as f64 / 10.0
    } else if is("ply") {
        (stride + 12) as f64
    } else {
        stride as f64
    };
    crate::disk::check_space(&[(output, (points as f64 * per_point) as u64)])
}

/// Writes `points` points of `scene` to `output` (.las, .laz or .ply), each moved by isotropic
/// Gaussian noise of deviation `noise` metres (a scanner's ranging noise) when above 0.
pub fn synth(
    output: &Path,
    points: u64,
    scene: Scene,
    seed: u64,
    noise: f64,
    overwrite: bool,
) -> Result<()> {
    if points == 0 {
        return Err(ConvertError::Usage("--points must be at least 1".into()));
    }
    if !(noise >= 0.0 && noise.is_finite()) {
        return Err(ConvertError::Usage(format!(
            "--noise {} is not a deviation in metres (0 or more)",
            number(noise)
        )));
    }
    // No scanner is that noisy, and far larger deviations would leave the 32-bit positions
    // (their tails were clamped to the grid's edge).
    const MAX_NOISE: f64 = 1000.0;
    if noise > MAX_NOISE {
        return Err(ConvertError::Usage(format!(
            "--noise {} is more than the {MAX_NOISE} m a synthetic scan may take",
            number(noise)
        )));
    }
    let layout = synth_layout();
    check_room(output, points, layout.stride)?;
    let world = World {
        scene,
        seed,
        side: (points as f64 / DENSITY).sqrt().max(10.0),
    };
    let writer = open_writer(
        output,
        &layout,
        [SCALE; 3],
        ORIGIN,
        points,
        overwrite,
        LasChoices::default(),
    )?;
    let off = |n: &str| layout.range_of(n).map_or(0, |r| r.start);
    let (o_int, o_ret, o_nret, o_class, o_gps, o_rgb, o_psid) = (
        off("intensity"),
        off("return_number"),
        off("number_of_returns"),
        off("classification"),
        off("gps_time"),
        off("rgb"),
        off("point_source_id"),
    );
    // A failed write leaves no partial file beside the output.
    write_then_finish(writer, output, |writer| {
        let stride = layout.stride;
        let mut start = 0u64;
        let mut rows = Vec::new();
        while start < points {
            let n = BATCH.min(points - start);
            rows.clear();
            rows.resize(n as usize * stride, 0);
            rows.par_chunks_mut(stride)
                .enumerate()
                .for_each(|(k, row)| {
                    let i = start + k as u64;
                    let (mut p, class, rgb, intensity, ret, nret) = world.point(i);
                    let strip = (p[1] / 250.0).floor().max(0.0) as u16;
                    if noise > 0.0 {
                        // A stream of its own: the noiseless scene stays the same file.
                        let mut r = Rng::new(seed, i, 0x4015E);
                        for c in &mut p {
                            *c += noise * r.gaussian();
                        }
                    }
                    for a in 0..3 {
                        let q = (p[a] / SCALE).round() as i32;
                        row[a * 4..a * 4 + 4].copy_from_slice(&q.to_le_bytes());
                    }
                    row[o_int..o_int + 2].copy_from_slice(&intensity.to_le_bytes());
                    row[o_ret] = ret;
                    row[o_nret] = nret;
                    row[o_class] = class;
                    let gps = 1.0e8 + i as f64 * 1e-5;
                    row[o_gps..o_gps + 8].copy_from_slice(&gps.to_le_bytes());
                    for c in 0..3 {
                        row[o_rgb + 2 * c..o_rgb + 2 * c + 2]
                            .copy_from_slice(&rgb[c].to_le_bytes());
                    }
                    row[o_psid..o_psid + 2].copy_from_slice(&strip.to_le_bytes());
                });
            writer.write_rows(&rows)?;
            start += n;
        }
        Ok(points)
    })
    .map(|_| ())
}
