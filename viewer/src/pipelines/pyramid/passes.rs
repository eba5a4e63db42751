//! The passes of paper 003 (Bouchiba, Deschaud, Goulette 2018), run on the depth and colour
//! planes the projection and resolve passes leave: a min-depth point pyramid, the pyramidal
//! hidden-point removal, pull-push filling of depth and colour, a normal per level of the
//! filled depth pyramid, and deferred headlight shading.

use super::hpr::HprShape;
use super::uniforms::{PyramidFrame, PyramidUniforms, level_table};
use crate::ViewerError;
use crate::gpu::GpuContext;
use crate::gpu::async_readback::AsyncReadback;
use crate::gpu::readback::read_buffer;
use crate::gpu::timing::Timer;
use crate::pipelines::LIGHTING_WGSL;
use crate::pipelines::ScreenBuffer;
use crate::pipelines::edl::EDL_WGSL;
use crate::pipelines::projection::pixel_groups;
use crate::pipelines::shader::ShaderSource;
use wgpu::util::DeviceExt;

pub(super) const COMMON_WGSL: &str = include_str!("pyramid.wgsl");
const NOISE_WGSL: &str = include_str!("pyramid_noise.wgsl");
const HPR_WGSL: &str = include_str!("pyramid_hpr.wgsl");

/// Bins of the depth-noise histogram (`NOISE_BINS` in pyramid_noise.wgsl); the noise scale
/// and the deviation follow them in the same buffer, then the stored normals' histogram and
/// the level they are averaged at.
pub const NOISE_BINS: u64 = 80;
const NOISE_BYTES: u64 = (2 * NOISE_BINS + 3) * 4;
/// Where the noise estimate leaves the stored normals' level (`STORED_LEVEL_AT`).
const STORED_LEVEL_AT: u64 = (2 * NOISE_BINS + 2) * 4;
/// Where the noise estimate leaves σ: after the bins and the noise scale.
const NOISE_SIGMA_AT: u64 = (NOISE_BINS + 1) * 4;

/// The compiled passes, shared by every viewport size.
pub struct PyramidPasses {
    frame_layout: wgpu::BindGroupLayout,
    data_layout: wgpu::BindGroupLayout,
    /// The noise passes read few buffers; their own layout keeps every layout within eight
    /// storage buffers (the least adapters allow).
    noise_layout: wgpu::BindGroupLayout,
    noise_histogram: wgpu::ComputePipeline,
    noise_estimate: wgpu::ComputePipeline,
    base: wgpu::ComputePipeline,
    down: wgpu::ComputePipeline,
    hpr: wgpu::ComputePipeline,
    hpr_shape: HprShape,
    pull: wgpu::ComputePipeline,
    push: wgpu::ComputePipeline,
    normals: wgpu::ComputePipeline,
    shade: wgpu::ComputePipeline,
}

/// The pyramids for one viewport size.
pub struct PyramidTargets {
    pub width: u32,
    pub height: u32,
    /// Per level: offset into the pyramid buffers, width, height.
    pub(super) levels: Vec<[u32; 3]>,
    pts: wgpu::Buffer,
    fill: wgpu::Buffer,
    /// Level 0 holds the filled colour each pixel is shaded with.
    pub fill_colour: wgpu::Buffer,
    /// With `stored_normals`, level 0 seeded by `stored::StoredNormals`.
    pub(super) normals: wgpu::Buffer,
    labels: wgpu::Buffer,
    /// The depth-noise histogram and the estimate drawn from it.
    noise: wgpu::Buffer,
    /// Per pixel (depth bits or EMPTY, octahedral normal), for readback.
    pub surface: wgpu::Buffer,
    pub(super) params: wgpu::Buffer,
    level_uniforms: Vec<wgpu::Buffer>,
}

/// The pixel buffers of the screen that the pyramid reads and writes.
pub struct PyramidInputs<'a> {
    pub frame_uniforms: &'a wgpu::Buffer,
    pub depths: &'a wgpu::Buffer,
    pub colours: &'a wgpu::Buffer,
    pub output: &'a wgpu::Texture,
}

fn uniform_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

impl PyramidTargets {
    /// The depth noise of the last frame's visible points, as a deviation in dataset units
    /// (0 where too few neighbouring points were visible to tell). Waits for the GPU.
    pub fn read_depth_noise(&self, ctx: &GpuContext) -> Result<f32, ViewerError> {
        let bytes = read_buffer(ctx, &self.noise, NOISE_BYTES)?;
        bytes
            .get(NOISE_SIGMA_AT as usize..)
            .and_then(depth_noise_from)
            .ok_or_else(|| ViewerError::Gpu("the depth-noise readback came back short".into()))
    }

    /// Records a copy of this frame's depth noise into `readback`, if it is free, for the
    /// window, which must not wait for it; `depth_noise_from` reads what arrives.
    pub fn record_depth_noise(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        readback: &mut AsyncReadback,
    ) {
        readback.record(encoder, &self.noise, NOISE_SIGMA_AT, 4);
    }
}

/// The depth noise in the first four bytes of a readback of the noise estimate's σ.
pub fn depth_noise_from(bytes: &[u8]) -> Option<f32> {
    let word = <[u8; 4]>::try_from(bytes.get(..4)?).ok()?;
    Some(f32::from_le_bytes(word))
}

/// Every module the pyramid compiles, as it composes them.
pub fn shaders() -> Vec<ShaderSource> {
    let pass = |label, part| ShaderSource::new(label, &[COMMON_WGSL, part]);
    vec![
        ShaderSource::new("noise histogram", &[COMMON_WGSL, NOISE_WGSL]).with_entry("histogram"),
        ShaderSource::new("noise estimate", &[COMMON_WGSL, NOISE_WGSL]).with_entry("estimate"),
        pass("pyramid base", include_str!("pyramid_base.wgsl")),
        pass("pyramid down", include_str!("pyramid_down.wgsl")),
        ShaderSource::new(
            HprShape::Pixel.module(),
            &[
                COMMON_WGSL,
                HPR_WGSL,
                include_str!("pyramid_hpr_pixel.wgsl"),
            ],
        ),
        ShaderSource::new(
            HprShape::Block.module(),
            &[
                COMMON_WGSL,
                HPR_WGSL,
                include_str!("pyramid_hpr_block.wgsl"),
            ],
        ),
        pass("pull", include_str!("pyramid_pull.wgsl")),
        pass("push", include_str!("pyramid_push.wgsl")),
        pass("normals", include_str!("pyramid_normals.wgsl")),
        ShaderSource::new(
            "pyramid shade",
            &[
                COMMON_WGSL,
                LIGHTING_WGSL,
                EDL_WGSL,
                include_str!("pyramid_shade.wgsl"),
            ],
        ),
    ]
}

impl PyramidPasses {
    pub fn new(device: &wgpu::Device, hpr_shape: HprShape) -> Result<PyramidPasses, ViewerError> {
        let frame_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("pyramid frame"),
            entries: &[uniform_entry(0), uniform_entry(1), uniform_entry(2)],
        });
        let mut data_entries = vec![storage_entry(0, true), storage_entry(1, true)];
        data_entries.extend((2..8).map(|b| storage_entry(b, false)));
        data_entries.push(wgpu::BindGroupLayoutEntry {
            binding: 8,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::StorageTexture {
                access: wgpu::StorageTextureAccess::WriteOnly,
                format: wgpu::TextureFormat::Rgba8Unorm,
                view_dimension: wgpu::TextureViewDimension::D2,
            },
            count: None,
        });
        let data_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("pyramid data"),
            entries: &data_entries,
        });
        let noise_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("pyramid noise"),
            entries: &[
                storage_entry(0, true),
                storage_entry(5, false),
                storage_entry(6, false),
                storage_entry(9, false),
            ],
        });
        let pipeline_layout = |groups: &[Option<&wgpu::BindGroupLayout>]| {
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("pyramid"),
                bind_group_layouts: groups,
                immediate_size: 0,
            })
        };
        let layout = pipeline_layout(&[Some(&frame_layout), Some(&data_layout)]);
        let noise_pipeline_layout = pipeline_layout(&[Some(&frame_layout), Some(&noise_layout)]);
        let compile = |label: &str, layout: &wgpu::PipelineLayout| {
            shaders()
                .into_iter()
                .find(|s| s.label == label)
                .map(|s| s.compute(device, Some(layout)))
                .ok_or_else(|| ViewerError::Gpu(format!("no pyramid shader named {label}")))
        };
        let make = |label: &str| compile(label, &layout);
        Ok(PyramidPasses {
            noise_histogram: compile("noise histogram", &noise_pipeline_layout)?,
            noise_estimate: compile("noise estimate", &noise_pipeline_layout)?,
            noise_layout,
            base: make("pyramid base")?,
            down: make("pyramid down")?,
            hpr: make(hpr_shape.module())?,
            hpr_shape,
            pull: make("pull")?,
            push: make("push")?,
            normals: make("normals")?,
            shade: make("pyramid shade")?,
            frame_layout,
            data_layout,
        })
    }

    /// The buffers `targets` creates for a `width` x `height` screen.
    pub fn screen_buffers(width: u32, height: u32) -> Vec<ScreenBuffer> {
        let cells = level_table(width, height)
            .last()
            .map_or(0, |l| l[0] as u64 + l[1] as u64 * l[2] as u64);
        let pixels = width as u64 * height as u64;
        let b = |label, bytes| ScreenBuffer { label, bytes };
        vec![
            b("point pyramid", cells * 8),
            b("pull-push pyramid", cells * 8),
            b("pull-push colours", cells * 4),
            b("normal pyramid", cells * 4),
            b("HPR labels", pixels * 4),
            b("surface", pixels * 8),
        ]
    }

    pub fn targets(&self, device: &wgpu::Device, width: u32, height: u32) -> PyramidTargets {
        let levels = level_table(width, height);
        let offset = levels.last().map_or(0, |l| l[0] + l[1] * l[2]);
        let cells = offset as u64;
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
        let uniform = |label: &str, bytes: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        // Each level's index never changes: written once here, not every frame.
        let level_uniforms = (0..levels.len() as u32)
            .map(|i| {
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("pyramid level"),
                    contents: bytemuck::cast_slice(&[i, 0, 0, 0]),
                    usage: wgpu::BufferUsages::UNIFORM,
                })
            })
            .collect();
        PyramidTargets {
            width,
            height,
            pts: buffer("point pyramid", cells * 8),
            fill: buffer("pull-push pyramid", cells * 8),
            fill_colour: buffer("pull-push colours", cells * 4),
            normals: buffer("normal pyramid", cells * 4),
            labels: buffer("hpr labels", pixels * 4),
            noise: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("depth noise"),
                size: NOISE_BYTES,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            surface: buffer("surface", pixels * 8),
            params: uniform(
                "pyramid uniforms",
                std::mem::size_of::<PyramidUniforms>() as u64,
            ),
            level_uniforms,
            levels,
        }
    }

    /// Encodes the pyramid passes after projection and resolve; they write the output image.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        t: &PyramidTargets,
        inputs: &PyramidInputs,
        frame: &PyramidFrame,
        timer: &mut Timer,
    ) {
        let params = PyramidUniforms::new(t, frame);
        queue.write_buffer(&t.params, 0, bytemuck::bytes_of(&params));
        let frame_groups: Vec<wgpu::BindGroup> = t
            .level_uniforms
            .iter()
            .map(|u| {
                device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("pyramid frame"),
                    layout: &self.frame_layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: inputs.frame_uniforms.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: t.params.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: u.as_entire_binding(),
                        },
                    ],
                })
            })
            .collect();
        let view = inputs.output.create_view(&Default::default());
        let buffers = [
            inputs.depths,
            inputs.colours,
            &t.pts,
            &t.fill,
            &t.fill_colour,
            &t.normals,
            &t.labels,
            &t.surface,
        ];
        let mut entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        entries.push(wgpu::BindGroupEntry {
            binding: 8,
            resource: wgpu::BindingResource::TextureView(&view),
        });
        let data = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("pyramid data"),
            layout: &self.data_layout,
            entries: &entries,
        });
        let noise_data = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("pyramid noise"),
            layout: &self.noise_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: inputs.depths.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: t.normals.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 6,
                    resource: t.labels.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 9,
                    resource: t.noise.as_entire_binding(),
                },
            ],
        });
        let level_groups = |l: usize| {
            let [_, w, h] = t.levels[l];
            pixel_groups(w, h)
        };
        // Each dispatch: the level it works on, and its workgroups.
        let run = |encoder: &mut wgpu::CommandEncoder,
                   timer: &mut Timer,
                   name: &str,
                   pipe: &wgpu::ComputePipeline,
                   group: &wgpu::BindGroup,
                   steps: &mut dyn Iterator<Item = (usize, (u32, u32))>| {
            let timestamp_writes = timer.pass(encoder, name);
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(name),
                timestamp_writes,
            });
            pass.set_pipeline(pipe);
            pass.set_bind_group(1, group, &[]);
            for (l, (x, y)) in steps {
                pass.set_bind_group(0, &frame_groups[l], &[]);
                pass.dispatch_workgroups(x, y, 1);
            }
        };
        let levels = t.levels.len();
        // Level 0 is the full screen.
        let at = |l: usize| (l, level_groups(l));
        let (e, tm) = (encoder, timer);
        run(
            e,
            tm,
            "pyramid",
            &self.base,
            &data,
            &mut [at(0)].into_iter(),
        );
        run(
            e,
            tm,
            "pyramid",
            &self.down,
            &data,
            &mut (1..levels).map(at),
        );
        // A workgroup is 8x8 invocations, each labelling a pixel or a block.
        let [_, w0, h0] = t.levels[0];
        let group_side = 8 * self.hpr_shape.side();
        let hpr_groups = (0, (w0.div_ceil(group_side), h0.div_ceil(group_side)));
        run(
            e,
            tm,
            "hpr",
            &self.hpr,
            &data,
            &mut [hpr_groups].into_iter(),
        );
        // The noise estimate reaches the shading's uniforms by a copy on the GPU: the frame
        // never waits for it.
        e.clear_buffer(&t.noise, 0, None);
        let histogram = &self.noise_histogram;
        run(
            e,
            tm,
            "noise",
            histogram,
            &noise_data,
            &mut [at(0)].into_iter(),
        );
        let estimate = &self.noise_estimate;
        run(
            e,
            tm,
            "noise",
            estimate,
            &noise_data,
            &mut [(0, (1, 1))].into_iter(),
        );
        let noise_field = std::mem::offset_of!(PyramidUniforms, noise_scale) as u64;
        e.copy_buffer_to_buffer(&t.noise, NOISE_BINS * 4, &t.params, noise_field, 4);
        let level_field = std::mem::offset_of!(PyramidUniforms, stored_level) as u64;
        e.copy_buffer_to_buffer(&t.noise, STORED_LEVEL_AT, &t.params, level_field, 4);
        run(e, tm, "pull", &self.pull, &data, &mut (1..levels).map(at));
        run(
            e,
            tm,
            "push",
            &self.push,
            &data,
            &mut (0..levels).rev().map(at),
        );
        // Stored normals came through the pull-push: none to estimate.
        if !frame.stored_normals {
            run(
                e,
                tm,
                "normals",
                &self.normals,
                &data,
                &mut (0..levels).map(at),
            );
        }
        run(
            e,
            tm,
            "pyramid shade",
            &self.shade,
            &data,
            &mut [at(0)].into_iter(),
        );
    }
}

#[cfg(test)]
#[path = "hpr_tests.rs"]
mod hpr_tests;
