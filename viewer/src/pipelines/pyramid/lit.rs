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
        per_arena_pass(
            encoder,
            timer,
            ("pyramid lit", &self.pipe),
            (screen.width, screen.height),
            &[&planes],
            &groups,
            |g, lit| {
                bind(
                    device,
                    &self.pipe,
                    1,
                    &[
                        (0, g.ranges.as_entire_binding()),
                        (1, lit.as_entire_binding()),
                    ],
                )
            },
        );
        Ok(())
    }
}

/// Runs `pipe` (named `name` in the pass times) over a `size` screen once per drawn arena:
/// the bind groups `fixed` from group 0 on, then each arena's, made by `bind_arena`, after
/// them. The pyramid's passes that take each pixel's point from its arena use it.
pub(super) fn per_arena_pass<T>(
    encoder: &mut wgpu::CommandEncoder,
    timer: &mut Timer,
    (name, pipe): (&str, &wgpu::ComputePipeline),
    (width, height): (u32, u32),
    fixed: &[&wgpu::BindGroup],
    arenas: &[(ArenaGroup, T)],
    bind_arena: impl Fn(&ArenaGroup, &T) -> wgpu::BindGroup,
) {
    let (gx, gy) = pixel_groups(width, height);
    let timestamp_writes = timer.pass(encoder, name);
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(name),
        timestamp_writes,
    });
    pass.set_pipeline(pipe);
    for (k, group) in fixed.iter().enumerate() {
        pass.set_bind_group(k as u32, *group, &[]);
    }
    for (g, extra) in arenas {
        if g.groups == 0 {
            continue;
        }
        pass.set_bind_group(fixed.len() as u32, &bind_arena(g, extra), &[]);
        pass.dispatch_workgroups(gx, gy, 1);
    }
}
