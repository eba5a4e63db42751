//! The ground truth: a mesh drawn with wgpu triangles under the viewer's camera into its albedo
//! (unlit colour), the same lit by the shared headlight Blinn-Phong (or, for a pipeline given a
//! light fixed in the world, the shared Blinn-Phong from that direction), and a surface image
//! (view-space normal and linear depth per pixel). `lit_as` gives the reference for a
//! pipeline's own lighting, so that no pipeline is scored against a light it does not use.

use super::mesh::Mesh;
use bytemuck::{Pod, Zeroable};
use glam::Mat4;
use strata_viewer::gpu::GpuContext;
use strata_viewer::gpu::readback::read_texture;
use strata_viewer::pipelines::{LIGHTING_WGSL, Lighting};
use wgpu::util::DeviceExt;

const SHADER: &str = r#"
struct Uniforms {
    view_proj: mat4x4<f32>,
    view: mat4x4<f32>,
    // View-space direction towards a light fixed in the world; w = 0: the headlight.
    light: vec4<f32>,
    width: u32,
}
@group(0) @binding(0) var<uniform> u: Uniforms;
@group(0) @binding(1) var albedo_map: texture_2d<f32>;
@group(0) @binding(2) var albedo_sampler: sampler;

struct In {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) colour: vec3<f32>,
    @location(3) uv: vec2<f32>,
}

struct Out {
    @builtin(position) clip: vec4<f32>,
    @location(0) view_pos: vec3<f32>,
    @location(1) view_normal: vec3<f32>,
    @location(2) colour: vec3<f32>,
    @location(3) uv: vec2<f32>,
}

@vertex
fn vs(v: In) -> Out {
    var o: Out;
    o.clip = u.view_proj * vec4<f32>(v.position, 1.0);
    o.view_pos = (u.view * vec4<f32>(v.position, 1.0)).xyz;
    o.view_normal = (u.view * vec4<f32>(v.normal, 0.0)).xyz;
    o.colour = v.colour;
    o.uv = v.uv;
    return o;
}

struct Targets {
    @location(0) colour: vec4<f32>,
    @location(1) surface: vec4<f32>,
    @location(2) albedo: vec4<f32>,
}

@fragment
fn fs(f: Out) -> Targets {
    return shade(f);
}

// Depth peeling of the mesh (paper 004's reference for transparency): front faces only (the
// normals face out, as the points' do), behind the layer before at this pixel.
@group(0) @binding(3) var<storage, read> previous: array<f32>;

@fragment
fn fs_peel(f: Out) -> Targets {
    if dot(f.view_normal, -f.view_pos) < 0.0 {
        discard;
    }
    let before = previous[u32(f.clip.y) * u.width + u32(f.clip.x)];
    if -f.view_pos.z <= before * (1.0 + 1e-4) {
        discard;
    }
    return shade(f);
}

fn shade(f: Out) -> Targets {
    let albedo = f.colour * textureSample(albedo_map, albedo_sampler, vec2<f32>(f.uv.x, 1.0 - f.uv.y)).rgb;
    var n = normalize(f.view_normal);
    let v = normalize(-f.view_pos);
    if dot(n, v) < 0.0 {
        n = -n;
    }
    var t: Targets;
    var lit = headlight(albedo, n, v);
    if u.light.w > 0.5 {
        lit = phong(albedo, n, v, normalize(u.light.xyz), 1.0);
    }
    t.colour = vec4<f32>(clamp(lit, vec3<f32>(0.0), vec3<f32>(1.0)), 1.0);
    t.surface = vec4<f32>(n, -f.view_pos.z);
    t.albedo = vec4<f32>(clamp(albedo, vec3<f32>(0.0), vec3<f32>(1.0)), 1.0);
    return t;
}
"#;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Vertex {
    position: [f32; 3],
    normal: [f32; 3],
    colour: [f32; 3],
    uv: [f32; 2],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Uniforms {
    view_proj: [[f32; 4]; 4],
    view: [[f32; 4]; 4],
    light: [f32; 4],
    width: u32,
    pad: [u32; 3],
}

/// What the reference shows at each pixel.
pub struct ReferenceImage {
    pub width: u32,
    pub height: u32,
    /// Lit by the headlight Blinn-Phong, or by the light `render_lit` was given.
    pub rgba: Vec<u8>,
    /// The unlit surface colour.
    pub albedo: Vec<u8>,
    /// View-space unit normal (facing the eye) and linear depth; `None` on background.
    pub surface: Vec<Option<([f32; 3], f32)>>,
}

/// A mesh uploaded once, drawn from any camera.
pub struct ReferenceRenderer {
    pipeline: wgpu::RenderPipeline,
    /// The same, drawing one peeled layer of front faces (`fs_peel`).
    peel: wgpu::RenderPipeline,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    index_count: u32,
    texture_view: wgpu::TextureView,
    sampler: wgpu::Sampler,
}

const COLOUR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const SURFACE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The near and far planes of the reference's projection for `camera`: the viewer's
/// (`clip_range`), with far / near kept within 1e5. The reference draws into a depth buffer
/// of f32 matrix depth, which beyond that ratio loses its far end (the viewer compares linear
/// depths, and its near plane may lie nearer).
pub fn reference_clip(
    ds: &strata_viewer::StreamDataset,
    camera: &strata_viewer::Camera,
    aspect: f32,
) -> (f32, f32) {
    let (near, far) = strata_viewer::lod::clip_range(ds, camera, aspect);
    (near.max(far * 1e-5), far)
}

impl ReferenceRenderer {
    /// `offset` is subtracted from every position: the dataset's anchor, so that the mesh and
    /// the points share coordinates.
    pub fn new(ctx: &GpuContext, mesh: &Mesh, offset: glam::DVec3) -> ReferenceRenderer {
        let device = &ctx.device;
        let normals = mesh.vertex_normals();
        let vertices: Vec<Vertex> = (0..mesh.positions.len())
            .map(|i| Vertex {
                position: (mesh.positions[i].as_dvec3() - offset).as_vec3().to_array(),
                normal: normals[i].to_array(),
                colour: mesh.colours[i].to_array(),
                uv: mesh.uvs[i].to_array(),
            })
            .collect();
        let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("reference mesh"),
            source: wgpu::ShaderSource::Wgsl(format!("{LIGHTING_WGSL}\n{SHADER}").into()),
        });
        let pipeline_with = |fragment: &str| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("reference mesh"),
            layout: None,
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs"),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<Vertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x3, 3 => Float32x2],
                })],
            },
            primitive: wgpu::PrimitiveState {
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some(fragment),
                compilation_options: Default::default(),
                targets: &[
                    Some(COLOUR_FORMAT.into()),
                    Some(SURFACE_FORMAT.into()),
                    Some(COLOUR_FORMAT.into()),
                ],
            }),
            multiview_mask: None,
            cache: None,
        })
        };
        let pipeline = pipeline_with("fs");
        let peel = pipeline_with("fs_peel");
        let tex = &mesh.texture;
        let texture = device.create_texture_with_data(
            &ctx.queue,
            &wgpu::TextureDescriptor {
                label: Some("albedo"),
                size: wgpu::Extent3d {
                    width: tex.width,
                    height: tex.height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba8Unorm,
                usage: wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            },
            wgpu::util::TextureDataOrder::LayerMajor,
            &tex.rgba,
        );
        ReferenceRenderer {
            pipeline,
            peel,
            vertices: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("reference vertices"),
                contents: bytemuck::cast_slice(&vertices),
                usage: wgpu::BufferUsages::VERTEX,
            }),
            indices: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("reference indices"),
                contents: bytemuck::cast_slice(&indices),
                usage: wgpu::BufferUsages::INDEX,
            }),
            index_count: indices.len() as u32,
            texture_view: texture.create_view(&Default::default()),
            sampler: device.create_sampler(&wgpu::SamplerDescriptor {
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                address_mode_u: wgpu::AddressMode::Repeat,
                address_mode_v: wgpu::AddressMode::Repeat,
                ..Default::default()
            }),
        }
    }

    pub fn render(
        &self,
        ctx: &GpuContext,
        view: Mat4,
        projection: Mat4,
        width: u32,
        height: u32,
        background: [u8; 3],
    ) -> anyhow::Result<ReferenceImage> {
        self.draw(ctx, view, projection, width, height, background, None, None)
    }

    /// As `render`, lit by the shared Blinn-Phong from world direction `light` (towards the
    /// light), unshadowed.
    #[allow(clippy::too_many_arguments)]
    pub fn render_lit(
        &self,
        ctx: &GpuContext,
        view: Mat4,
        projection: Mat4,
        width: u32,
        height: u32,
        background: [u8; 3],
        light: glam::Vec3,
    ) -> anyhow::Result<ReferenceImage> {
        let towards = view.transform_vector3(light.normalize());
        let light = Some(towards);
        self.draw(
            ctx, view, projection, width, height, background, None, light,
        )
    }

    /// The mesh as `layers` depth-peeled layers of front faces, each lit by the headlight and
    /// blended front to back with `opacity` over the background: the reference of a pipeline
    /// that peels and blends the points' layers the same way.
    #[allow(clippy::too_many_arguments)]
    pub fn render_peeled(
        &self,
        ctx: &GpuContext,
        view: Mat4,
        projection: Mat4,
        width: u32,
        height: u32,
        background: [u8; 3],
        layers: u32,
        opacity: f32,
    ) -> anyhow::Result<Vec<u8>> {
        let pixels = (width * height) as usize;
        let mut before = vec![0f32; pixels];
        let mut sum = vec![[0f32; 4]; pixels];
        for _ in 0..layers {
            let layer = self.draw(
                ctx,
                view,
                projection,
                width,
                height,
                background,
                Some(before.as_slice()),
                None,
            )?;
            for (i, s) in layer.surface.iter().enumerate() {
                match s {
                    Some((_, depth)) => {
                        let a = opacity * (1.0 - sum[i][3]);
                        for (c, total) in sum[i][..3].iter_mut().enumerate() {
                            *total += a * layer.rgba[4 * i + c] as f32;
                        }
                        sum[i][3] += a;
                        before[i] = *depth;
                    }
                    // Nothing left behind this pixel.
                    None => before[i] = f32::INFINITY,
                }
            }
        }
        Ok(sum
            .iter()
            .flat_map(|s| {
                let mut px = [255u8; 4];
                for c in 0..3 {
                    px[c] = (s[c] + (1.0 - s[3]) * background[c] as f32)
                        .round()
                        .clamp(0.0, 255.0) as u8;
                }
                px
            })
            .collect())
    }

    /// One draw of the mesh; with `before` (linear depth per pixel) a peeled layer; with
    /// `light` (view space, towards it) lit from there instead of by the headlight.
    #[allow(clippy::too_many_arguments)]
    fn draw(
        &self,
        ctx: &GpuContext,
        view: Mat4,
        projection: Mat4,
        width: u32,
        height: u32,
        background: [u8; 3],
        before: Option<&[f32]>,
        light: Option<glam::Vec3>,
    ) -> anyhow::Result<ReferenceImage> {
        let device = &ctx.device;
        let target = |label: &str, format: wgpu::TextureFormat| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            })
        };
        let colour = target("reference colour", COLOUR_FORMAT);
        let albedo = target("reference albedo", COLOUR_FORMAT);
        let surface = target("reference surface", SURFACE_FORMAT);
        let depth = target("reference depth", DEPTH_FORMAT);
        let uniforms = Uniforms {
            view_proj: (projection * view).to_cols_array_2d(),
            view: view.to_cols_array_2d(),
            light: light.map_or([0.0; 4], |l| [l.x, l.y, l.z, 1.0]),
            width,
            pad: [0; 3],
        };
        let pipeline = if before.is_some() {
            &self.peel
        } else {
            &self.pipeline
        };
        let previous = before.map(|b| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("reference layer before"),
                contents: bytemuck::cast_slice(b),
                usage: wgpu::BufferUsages::STORAGE,
            })
        });
        let ubuf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("reference uniforms"),
            contents: bytemuck::bytes_of(&uniforms),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let mut entries = vec![
            wgpu::BindGroupEntry {
                binding: 0,
                resource: ubuf.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(&self.texture_view),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::Sampler(&self.sampler),
            },
        ];
        if let Some(p) = &previous {
            entries.push(wgpu::BindGroupEntry {
                binding: 3,
                resource: p.as_entire_binding(),
            });
        }
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("reference"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let [r, g, b] = background.map(|c| c as f64 / 255.0);
            let colour_view = colour.create_view(&Default::default());
            let surface_view = surface.create_view(&Default::default());
            let albedo_view = albedo.create_view(&Default::default());
            let depth_view = depth.create_view(&Default::default());
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("reference"),
                color_attachments: &[
                    Some(wgpu::RenderPassColorAttachment {
                        view: &colour_view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a: 1.0 }),
                            store: wgpu::StoreOp::Store,
                        },
                    }),
                    Some(wgpu::RenderPassColorAttachment {
                        view: &surface_view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color {
                                r: 0.0,
                                g: 0.0,
                                b: 0.0,
                                a: -1.0,
                            }),
                            store: wgpu::StoreOp::Store,
                        },
                    }),
                    Some(wgpu::RenderPassColorAttachment {
                        view: &albedo_view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a: 1.0 }),
                            store: wgpu::StoreOp::Store,
                        },
                    }),
                ],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.set_vertex_buffer(0, self.vertices.slice(..));
            pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..self.index_count, 0, 0..1);
        }
        ctx.queue.submit([encoder.finish()]);
        let rgba = read_texture(ctx, &colour, 4)?;
        let albedo = read_texture(ctx, &albedo, 4)?;
        let raw = read_texture(ctx, &surface, 16)?;
        let surface = raw
            .chunks_exact(16)
            .map(|b| {
                let f = |k: usize| {
                    f32::from_le_bytes([b[4 * k], b[4 * k + 1], b[4 * k + 2], b[4 * k + 3]])
                };
                let d = f(3);
                (d > 0.0).then(|| ([f(0), f(1), f(2)], d))
            })
            .collect();
        Ok(ReferenceImage {
            width,
            height,
            rgba,
            albedo,
            surface,
        })
    }
}

/// Eye-dome lighting (`edl.wgsl`, the viewer's own constants) applied to `rgba` by the
/// reference's depth: a pipeline that lights with EDL is scored against the mesh lit the same
/// way.
pub fn eye_dome(image: &ReferenceImage, rgba: &[u8], strength: f32, radius: f32) -> Vec<u8> {
    const DIRECTIONS: [[f32; 2]; 8] = [
        [1.0, 0.0],
        [
            std::f32::consts::FRAC_1_SQRT_2,
            std::f32::consts::FRAC_1_SQRT_2,
        ],
        [0.0, 1.0],
        [
            -std::f32::consts::FRAC_1_SQRT_2,
            std::f32::consts::FRAC_1_SQRT_2,
        ],
        [-1.0, 0.0],
        [
            -std::f32::consts::FRAC_1_SQRT_2,
            -std::f32::consts::FRAC_1_SQRT_2,
        ],
        [0.0, -1.0],
        [
            std::f32::consts::FRAC_1_SQRT_2,
            -std::f32::consts::FRAC_1_SQRT_2,
        ],
    ];
    let (w, h) = (image.width as i64, image.height as i64);
    let log_depth = |x: i64, y: i64| -> Option<f32> {
        if x < 0 || y < 0 || x >= w || y >= h {
            return None;
        }
        image.surface[(y * w + x) as usize].map(|(_, d)| d.log2())
    };
    let mut out = rgba.to_vec();
    for y in 0..h {
        for x in 0..w {
            let Some(ld) = log_depth(x, y) else { continue };
            let response: f32 = DIRECTIONS
                .iter()
                .filter_map(|d| {
                    // WGSL's round() takes halves to even.
                    let (dx, dy) = (
                        (d[0] * radius).round_ties_even(),
                        (d[1] * radius).round_ties_even(),
                    );
                    log_depth(x + dx as i64, y + dy as i64)
                })
                .map(|nd| (ld - nd).max(0.0))
                .sum();
            let factor = (-response / 8.0 * 300.0 * strength).exp();
            let i = 4 * (y * w + x) as usize;
            for c in &mut out[i..i + 3] {
                *c = (*c as f32 * factor).round().clamp(0.0, 255.0) as u8;
            }
        }
    }
    out
}

/// The reference image for a pipeline that lights with `lighting`; `edl` is its eye-dome
/// strength and radius where it uses eye-dome lighting.
pub fn lit_as(image: &ReferenceImage, lighting: Lighting, edl: (f32, f32)) -> Vec<u8> {
    match lighting {
        Lighting::None => image.albedo.clone(),
        Lighting::Headlight => image.rgba.clone(),
        Lighting::EyeDome => eye_dome(image, &image.albedo, edl.0, edl.1),
    }
}

#[cfg(test)]
#[path = "reference_layout.rs"]
mod layout;
