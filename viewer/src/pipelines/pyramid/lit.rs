//! The pyramid's share of the point shadows (`shadows`, beyond paper 003): each pixel's
//! nearest point gives its lit share to the colour plane's alpha before the pyramid is built,
//! so that the pull-push fills holes with it as with colour and the shading scales the
//! diffuse and specular light by it.

use crate::ViewerError;
use crate::gpu::timing::Timer;
use crate::pipelines::PipelineFrame;
use crate::pipelines::filters::bind;
use crate::pipelines::projection::{ArenaGroup, GROUP_SIZE, pixel_groups};
use crate::pipelines::shader::ShaderSource;
use crate::pipelines::shadows::LIT_STREAM;

const LIT_WGSL: &str = include_str!("pyramid_lit.wgsl");

pub fn shaders() -> Vec<ShaderSource> {
    vec![ShaderSource::new("pyramid lit", &[LIT_WGSL])]
}

pub struct LitPass {
    pipe: wgpu::ComputePipeline,
    scale: wgpu::Buffer,
}

impl LitPass {
    pub fn new(device: &wgpu::Device) -> LitPass {
        LitPass {
            pipe: shaders()[0].compute(device, None),
            scale: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("pyramid lit scale"),
                size: 16,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        }
    }

    /// Writes the drawn points' lit shares (`lit_scale`: 1 / the samples summed) into the
    /// alpha of `frame.screen.colours`.
    pub fn encode(
        &self,
        frame: &PipelineFrame,
        encoder: &mut wgpu::CommandEncoder,
        lit_scale: f32,
        timer: &mut Timer,
    ) -> Result<(), ViewerError> {
        let device = &frame.ctx.device;
        let screen = frame.screen;
        frame.ctx.queue.write_buffer(
            &self.scale,
            0,
            bytemuck::cast_slice(&[lit_scale, 0.0, 0.0, 0.0]),
        );
        let groups = frame
            .arenas
            .iter()
            .map(|d| {
                let (_, [lit]) = frame.cache.arena_streams(d.arena, [LIT_STREAM])?;
                Ok((ArenaGroup::new(device, d, GROUP_SIZE), lit))
            })
            .collect::<Result<Vec<_>, ViewerError>>()?;
        let planes = bind(
            device,
            &self.pipe,
            0,
            &[
                (0, screen.uniforms.as_entire_binding()),
                (1, self.scale.as_entire_binding()),
                (2, screen.depths.as_entire_binding()),
                (3, screen.indices.as_entire_binding()),
                (4, screen.colours.as_entire_binding()),
            ],
        );
        let (gx, gy) = pixel_groups(screen.width, screen.height);
        let timestamp_writes = timer.pass(encoder, "pyramid lit");
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("pyramid lit"),
            timestamp_writes,
        });
        pass.set_pipeline(&self.pipe);
        pass.set_bind_group(0, &planes, &[]);
        for (g, lit) in &groups {
            if g.groups == 0 {
                continue;
            }
            let arena = bind(
                device,
                &self.pipe,
                1,
                &[
                    (0, g.ranges.as_entire_binding()),
                    (1, lit.as_entire_binding()),
                ],
            );
            pass.set_bind_group(1, &arena, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        Ok(())
    }
}
