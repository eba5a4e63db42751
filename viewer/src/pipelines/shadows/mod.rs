//! Point shadow textures (paper 004, section 6), a per-point stream any pipeline can shade
//! with: per light sample, the drawn points and those the light's own view selected
//! (`Pipeline::extra_view`) are splatted into a light map along the light, its occluded pixels
//! filled, and every point within Δd of the front layer counted lit, in a per-point stream
//! beside the node arenas. Soft shadows average samples spread over an area light
//! (Monte-Carlo). The counts are kept between frames and added to progressively (one sample a
//! frame while the view moves, the rest once it stops); they start again when the light, the
//! parameters, the point filters or the drawn points change. `filters` shades its layers with
//! them and `pyramid` carries them through its pull-push; both take the parameters below.

use crate::ViewerError;
use crate::gpu::timing::Timer;
use crate::pipelines::filters::{MASKS_WGSL, bind};
use crate::pipelines::params::{ParamSpec, ParamValue, ParamValues, ResolvedParams, Scale};
use crate::pipelines::projection::{
    ArenaGroup, FILTERS_WGSL, GROUP_SIZE, OCT16_WGSL, RANGE_SEARCH_WGSL, pixel_groups,
    plane_buffer, split_groups,
};
use crate::pipelines::shader::ShaderSource;
use crate::pipelines::{PipelineFrame, PipelineInfo, PointStream};
use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use std::hash::{Hash, Hasher};

/// d~ in point spacings of the nodes drawn, where a pipeline leaves it automatic: the depth
/// noise of real scans exceeds one spacing, and at one spacing the occluded fill keeps trading
/// noisy depths between neighbours (16 iterations on the bunny scans against 7 at four
/// spacings). It also sets the light map's pixel: d~ / DTILDE_SPACINGS.
pub const DTILDE_SPACINGS: u32 = 4;

/// A parameter without an automatic value (shared with the filters' own table).
pub(crate) const fn param(
    name: &'static str,
    help: &'static str,
    default: f32,
    min: f32,
    max: f32,
    scale: Scale,
) -> ParamSpec {
    ParamSpec {
        name,
        help,
        default,
        min,
        max,
        scale,
        auto: None,
    }
}

/// The light and shadow parameters, the same in every pipeline that takes them: the direction
/// towards a light fixed in the world (`light=X,Y,Z`; 0,0,0 the headlight), then the shadows.
pub const PARAMS: [ParamSpec; 7] = [
    param(
        "light.x",
        "direction towards a light fixed in the world, x (0,0,0: the headlight; light=X,Y,Z takes any length)",
        0.0,
        -1.0,
        1.0,
        Scale::Linear,
    ),
    param(
        "light.y",
        "direction towards the light, y",
        0.0,
        -1.0,
        1.0,
        Scale::Linear,
    ),
    param(
        "light.z",
        "direction towards the light, z",
        0.0,
        -1.0,
        1.0,
        Scale::Linear,
    ),
    param(
        "shadows",
        "point shadow textures: hard from a point light, soft from an area light",
        0.0,
        0.0,
        2.0,
        Scale::Choice(&["off", "hard", "soft"]),
    ),
    param(
        "shadow_samples",
        "light samples of soft shadows (Monte-Carlo over the area light)",
        16.0,
        1.0,
        64.0,
        Scale::Integer,
    ),
    param(
        "light_size",
        "the area light's angular diameter, degrees (soft shadows)",
        5.0,
        0.0,
        45.0,
        Scale::Linear,
    ),
    param(
        "shadow_budget",
        "points the light's own view loads for casters outside the camera's view",
        2e6,
        1e5,
        1e8,
        Scale::Log,
    ),
];

/// `shadows`: off, hard, soft.
const SHADOWS_OFF: u32 = 0;
const SHADOWS_HARD: u32 = 1;

fn value(params: &ResolvedParams, name: &str) -> f32 {
    let default = PARAMS
        .iter()
        .find(|p| p.name == name)
        .map_or(0.0, |p| p.default);
    params.get_or(name, default)
}

/// The unit direction towards a light fixed in the world, `None` for the headlight.
pub fn world_light(params: &ResolvedParams) -> Option<Vec3> {
    Vec3::new(
        value(params, "light.x"),
        value(params, "light.y"),
        value(params, "light.z"),
    )
    .try_normalize()
}

/// Whether the frame asks for shadows.
pub fn on(params: &ResolvedParams) -> bool {
    value(params, "shadows") as u32 != SHADOWS_OFF
}

/// The per-point streams `pipeline` needs with `values`: its own, and the normals and lit
/// counts while it casts shadows, so that a pipeline that can shade shadows holds no stream
/// for them while they are off.
pub fn streams(pipeline: &PipelineInfo, values: &ParamValues) -> Vec<PointStream> {
    let mut wanted = pipeline.streams.to_vec();
    let shadows = pipeline.params.iter().find(|p| p.name == "shadows");
    let casting = shadows.is_some_and(|spec| match values.get(pipeline, spec) {
        ParamValue::Value(v) => v as u32 != SHADOWS_OFF,
        ParamValue::Auto => false,
    });
    if casting {
        for s in [PointStream::Normals, LIT_STREAM] {
            if !wanted.contains(&s) {
                wanted.push(s);
            }
        }
    }
    wanted
}

/// The light's own view, for `Pipeline::extra_view`: `None` without shadows.
pub fn extra_view(
    params: &ResolvedParams,
    camera: &crate::Camera,
    bounds: [Vec3; 2],
) -> Option<(crate::Camera, u64)> {
    if !on(params) {
        return None;
    }
    let forward = (camera.target - camera.eye).normalize_or(Vec3::NEG_Z);
    let light = world_light(params).unwrap_or(-forward);
    Some((
        light_camera(light, bounds),
        value(params, "shadow_budget") as u64,
    ))
}

/// What `frame` asks of the shadows, `None` where they are off; `forward`: the camera's view
/// direction (the headlight's light comes from the eye, so shadows hide behind their casters).
pub fn setup(frame: &PipelineFrame, forward: Vec3, dtilde: f32) -> Option<ShadowSetup> {
    let mode = value(frame.params, "shadows") as u32;
    if mode == SHADOWS_OFF {
        return None;
    }
    Some(ShadowSetup {
        samples: if mode == SHADOWS_HARD {
            1
        } else {
            value(frame.params, "shadow_samples") as u32
        },
        light: world_light(frame.params).unwrap_or(-forward),
        light_size: value(frame.params, "light_size").to_radians(),
        dtilde,
        normals: frame.has_normals,
        bounds: frame.bounds,
    })
}

const SHADOW_UNIFORMS_WGSL: &str = include_str!("shadow_uniforms.wgsl");
const SHADOW_WGSL: &str = include_str!("shadow.wgsl");
const SHADOW_FILL_WGSL: &str = include_str!("shadow_fill.wgsl");

/// The light map's side at most, in pixels.
pub const MAX_MAP: u32 = 2048;
const MIN_MAP: u32 = 64;
/// Occluded-fill iterations on the light map: its pixels are about a point spacing, so the gaps
/// it must close are a pixel or two across.
const FILL_ITERATIONS: u32 = 4;
/// Samples one frame computes at most (the uniforms' slots).
const SAMPLES_PER_FRAME: u64 = 64;
const SLOT: u64 = 256;
/// The per-point stream of lit counts.
pub const LIT_STREAM: PointStream = PointStream::Kept {
    name: "lit share",
    bytes: 4,
};

/// One light sample's uniforms, laid out as `Shadow` in shadow_uniforms.wgsl.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub struct ShadowUniforms {
    pub light: [f32; 4],
    pub u_axis: [f32; 4],
    pub v_axis: [f32; 4],
    pub width: u32,
    pub height: u32,
    pub dtilde: f32,
    pub normals: u32,
}

/// Every module the shadows compile.
pub fn shaders() -> Vec<ShaderSource> {
    let points = [
        SHADOW_UNIFORMS_WGSL,
        FILTERS_WGSL,
        RANGE_SEARCH_WGSL,
        OCT16_WGSL,
        SHADOW_WGSL,
    ];
    vec![
        ShaderSource::new("shadow splat", &points).with_entry("splat"),
        ShaderSource::new("shadow mark", &points).with_entry("mark"),
        ShaderSource::new(
            "shadow fill",
            &[SHADOW_UNIFORMS_WGSL, MASKS_WGSL, SHADOW_FILL_WGSL],
        ),
        ShaderSource::new(
            "shadow clear",
            &[SHADOW_UNIFORMS_WGSL, MASKS_WGSL, SHADOW_FILL_WGSL],
        )
        .with_entry("clear"),
    ]
}

/// What the frame asks of the shadows.
#[derive(Debug, Clone, Copy)]
pub struct ShadowSetup {
    /// Light samples in all: 1 for hard shadows.
    pub samples: u32,
    /// Unit direction towards the light's centre.
    pub light: Vec3,
    /// The area light's angular diameter, radians (0: a point light).
    pub light_size: f32,
    pub dtilde: f32,
    pub normals: bool,
    /// The dataset's bounds, relative to the anchor.
    pub bounds: [Vec3; 2],
}

/// The compiled passes and what is kept between frames.
pub struct Shadows {
    splat: wgpu::ComputePipeline,
    mark: wgpu::ComputePipeline,
    fill: wgpu::ComputePipeline,
    clear: wgpu::ComputePipeline,
    maps: Option<[wgpu::Buffer; 2]>,
    uniforms: wgpu::Buffer,
    /// What the kept counts were made for.
    key: Option<u64>,
    /// Samples summed in the kept counts.
    done: u32,
    last_view: Option<glam::Mat4>,
}

impl Shadows {
    pub fn new(device: &wgpu::Device) -> Result<Shadows, ViewerError> {
        let mut compiled = shaders().into_iter().map(|s| s.compute(device, None));
        let mut next = || {
            compiled
                .next()
                .ok_or_else(|| ViewerError::Gpu("a shadow shader is missing".into()))
        };
        Ok(Shadows {
            splat: next()?,
            mark: next()?,
            fill: next()?,
            clear: next()?,
            maps: None,
            uniforms: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("shadow uniforms"),
                size: SAMPLES_PER_FRAME * SLOT,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            key: None,
            done: 0,
            last_view: None,
        })
    }

    /// Forgets the kept counts (another screen, another pipeline).
    pub fn reset(&mut self) {
        self.key = None;
        self.done = 0;
        self.maps = None;
    }

    /// Adds this frame's samples to the kept counts; returns 1 / the samples summed (0: none).
    pub fn encode(
        &mut self,
        frame: &PipelineFrame,
        encoder: &mut wgpu::CommandEncoder,
        setup: &ShadowSetup,
        timer: &mut Timer,
    ) -> Result<f32, ViewerError> {
        let device = &frame.ctx.device;
        // Every caster (the drawn points and the light's own view) splats; the drawn points
        // are marked.
        let groups = |list: &[crate::pipelines::projection::ArenaDraw]| {
            list.iter()
                .map(|d| {
                    let (a, [normals, lit]) = frame
                        .cache
                        .arena_streams(d.arena, [PointStream::Normals, LIT_STREAM])?;
                    Ok((
                        ArenaGroup::new(device, d, GROUP_SIZE),
                        [&a.points, &a.attributes, normals, lit],
                    ))
                })
                .collect::<Result<Vec<_>, ViewerError>>()
        };
        let casters = groups(frame.casters)?;
        let drawn = groups(frame.arenas)?;
        let key = key_of(frame, setup);
        if self.key != Some(key) {
            for (_, [_, _, _, lit]) in &casters {
                encoder.clear_buffer(lit, 0, None);
            }
            self.key = Some(key);
            self.done = 0;
        }
        let moving = self.last_view.is_some_and(|v| v != frame.view.view);
        self.last_view = Some(frame.view.view);
        let todo = if self.done >= setup.samples {
            0
        } else if moving {
            1
        } else {
            (setup.samples - self.done).min(SAMPLES_PER_FRAME as u32)
        };
        if todo == 0 {
            return Ok(scale(self.done));
        }
        let map = light_map(setup);
        let pixels = map.width as u64 * map.height as u64;
        if self.maps.as_ref().is_none_or(|m| m[0].size() < pixels * 4) {
            self.maps = Some([
                plane_buffer(device, "light map a", pixels * 4),
                plane_buffer(device, "light map b", pixels * 4),
            ]);
        }
        let Some(maps) = &self.maps else {
            return Ok(scale(self.done));
        };
        let mut slots = vec![0u8; (todo as u64 * SLOT) as usize];
        let timestamp_writes = timer.pass(encoder, "shadows");
        // One compute pass for every sample: the splat, fill and mark of each in turn.
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("shadows"),
            timestamp_writes,
        });
        for k in 0..todo {
            let u = map.sample(sample_direction(setup, self.done + k));
            let at = (k as u64 * SLOT) as usize;
            slots[at..at + std::mem::size_of::<ShadowUniforms>()]
                .copy_from_slice(bytemuck::bytes_of(&u));
            let uniform = wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer: &self.uniforms,
                offset: k as u64 * SLOT,
                size: wgpu::BufferSize::new(std::mem::size_of::<ShadowUniforms>() as u64),
            });
            let per_point = |pass: &mut wgpu::ComputePass,
                             pipe: &wgpu::ComputePipeline,
                             map: &wgpu::Buffer,
                             lit: bool| {
                let arenas = if lit { &drawn } else { &casters };
                let frame_group = bind(
                    device,
                    pipe,
                    0,
                    &[
                        (0, uniform.clone()),
                        (1, map.as_entire_binding()),
                        (2, frame.screen.uniforms.as_entire_binding()),
                    ],
                );
                pass.set_pipeline(pipe);
                pass.set_bind_group(0, &frame_group, &[]);
                for (g, [points, attributes, normals, counts]) in arenas {
                    if g.groups == 0 {
                        continue;
                    }
                    let mut entries = vec![
                        (0, points.as_entire_binding()),
                        (1, g.ranges.as_entire_binding()),
                        (2, attributes.as_entire_binding()),
                    ];
                    if lit {
                        entries.push((3, normals.as_entire_binding()));
                        entries.push((4, counts.as_entire_binding()));
                    }
                    pass.set_bind_group(1, &bind(device, pipe, 1, &entries), &[]);
                    let (x, y) = split_groups(g.groups);
                    pass.dispatch_workgroups(x, y, 1);
                }
            };
            let (gx, gy) = pixel_groups(map.width, map.height);
            let full_screen = |pass: &mut wgpu::ComputePass,
                               pipe: &wgpu::ComputePipeline,
                               from: &wgpu::Buffer,
                               to: &wgpu::Buffer| {
                let mut entries = vec![(0, uniform.clone()), (2, to.as_entire_binding())];
                if std::ptr::eq(pipe, &self.fill) {
                    entries.push((1, from.as_entire_binding()));
                }
                pass.set_pipeline(pipe);
                pass.set_bind_group(0, &bind(device, pipe, 0, &entries), &[]);
                pass.dispatch_workgroups(gx, gy, 1);
            };
            full_screen(&mut pass, &self.clear, &maps[1], &maps[0]);
            per_point(&mut pass, &self.splat, &maps[0], false);
            for i in 0..FILL_ITERATIONS as usize {
                full_screen(&mut pass, &self.fill, &maps[i % 2], &maps[1 - i % 2]);
            }
            per_point(
                &mut pass,
                &self.mark,
                &maps[(FILL_ITERATIONS % 2) as usize],
                true,
            );
        }
        drop(pass);
        frame.ctx.queue.write_buffer(&self.uniforms, 0, &slots);
        self.done += todo;
        Ok(scale(self.done))
    }
}

fn scale(done: u32) -> f32 {
    if done == 0 { 0.0 } else { 1.0 / done as f32 }
}

/// What the kept counts depend on: the setup and the drawn ranges.
fn key_of(frame: &PipelineFrame, setup: &ShadowSetup) -> u64 {
    let mut h = std::hash::DefaultHasher::new();
    setup.samples.hash(&mut h);
    for v in [
        setup.light.x,
        setup.light.y,
        setup.light.z,
        setup.light_size,
        setup.dtilde,
    ] {
        v.to_bits().hash(&mut h);
    }
    setup.normals.hash(&mut h);
    // Points the filters hide cast no shadow.
    frame.filters_key.hash(&mut h);
    for list in [frame.arenas, frame.casters] {
        for d in list {
            d.arena.hash(&mut h);
            for r in &d.ranges {
                (r.start, r.count).hash(&mut h);
            }
        }
    }
    h.finish()
}

/// The light map's frame: the plane across the light and its pixel size.
#[derive(Debug, Clone, Copy)]
pub struct LightMap {
    pub width: u32,
    pub height: u32,
    pixel: f32,
    bounds: [Vec3; 2],
    dtilde: f32,
    normals: bool,
}

/// A light map over the bounds with pixels of about a point spacing (d~ / DTILDE_SPACINGS),
/// coarser where the bounds need more than `MAX_MAP` of them. Its extent is the same for every
/// direction of an area light: the bounds' diagonal.
pub fn light_map(setup: &ShadowSetup) -> LightMap {
    let extent = (setup.bounds[1] - setup.bounds[0]).length().max(1e-6);
    let wanted = (setup.dtilde / DTILDE_SPACINGS as f32).max(extent / MAX_MAP as f32);
    let side = ((extent / wanted).ceil() as u32).clamp(MIN_MAP, MAX_MAP);
    LightMap {
        width: side,
        height: side,
        pixel: extent / side as f32,
        bounds: setup.bounds,
        dtilde: setup.dtilde,
        normals: setup.normals,
    }
}

impl LightMap {
    /// The uniforms for light direction `l` (unit, towards the light).
    pub fn sample(&self, l: Vec3) -> ShadowUniforms {
        let (u, v) = l.any_orthonormal_pair();
        let centre = (self.bounds[0] + self.bounds[1]) * 0.5;
        let half = self.width as f32 * self.pixel * 0.5;
        let corners = (0..8).map(|k| {
            Vec3::new(
                if k & 1 == 0 {
                    self.bounds[0].x
                } else {
                    self.bounds[1].x
                },
                if k & 2 == 0 {
                    self.bounds[0].y
                } else {
                    self.bounds[1].y
                },
                if k & 4 == 0 {
                    self.bounds[0].z
                } else {
                    self.bounds[1].z
                },
            )
        });
        let top = corners.map(|c| c.dot(l)).fold(f32::MIN, f32::max);
        let axis = |a: Vec3| {
            let s = a / self.pixel;
            [s.x, s.y, s.z, (centre.dot(a) - half) / self.pixel]
        };
        ShadowUniforms {
            light: [l.x, l.y, l.z, top],
            u_axis: axis(u),
            v_axis: axis(v),
            width: self.width,
            height: self.height,
            dtilde: self.dtilde,
            normals: self.normals as u32,
        }
    }
}

/// A camera for the light's own node selection: far along the light from the bounds' centre,
/// its narrow view just holding them (near enough to the parallel light for the level of
/// detail).
pub fn light_camera(light: Vec3, bounds: [Vec3; 2]) -> crate::Camera {
    let centre = (bounds[0] + bounds[1]) * 0.5;
    let radius = ((bounds[1] - bounds[0]).length() * 0.5).max(1e-6);
    let distance = 20.0 * radius;
    crate::Camera {
        eye: centre + light.normalize_or(Vec3::Z) * distance,
        target: centre,
        fov_y: 2.0 * (1.05 * radius / distance).atan(),
    }
}

/// Sample `k` of the area light: directions over the disc of its angular size, spread evenly
/// (a Fibonacci spiral, the same every time, so that a still picture does not flicker).
pub fn sample_direction(setup: &ShadowSetup, k: u32) -> Vec3 {
    let l = setup.light.normalize_or(Vec3::Z);
    if setup.samples <= 1 || setup.light_size <= 0.0 {
        return l;
    }
    let radius = (setup.light_size * 0.5).tan() * ((k as f32 + 0.5) / setup.samples as f32).sqrt();
    let angle = k as f32 * std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let (u, v) = l.any_orthonormal_pair();
    (l + radius * (angle.cos() * u + angle.sin() * v)).normalize()
}

#[cfg(test)]
mod tests;
