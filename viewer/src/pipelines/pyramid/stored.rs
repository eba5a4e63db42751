//! The pyramid's stored normals (`stored_normals`, beyond paper 003): where the dataset has
//! normals, each pixel's nearest point gives its normal to level 0 of the normal pyramid before
//! the hidden-point removal, which keeps it where the point is visible; the pull-push carries it
//! into the holes like colour, and the shading takes it in place of the normals the paper
//! estimates from the filled depth, which round off thin and sharp shapes and tilt at depth
//! edges.

use super::passes::{COMMON_WGSL, PyramidTargets};
use crate::ViewerError;
use crate::gpu::timing::Timer;
use crate::pipelines::filters::bind;
use super::lit::per_arena_pass;
use crate::pipelines::projection::{ArenaGroup, GROUP_SIZE, OCT16_WGSL};
use crate::pipelines::shader::ShaderSource;
use crate::pipelines::{PipelineFrame, PointStream};

const STORED_WGSL: &str = include_str!("pyramid_stored.wgsl");

pub fn shaders() -> Vec<ShaderSource> {
    vec![ShaderSource::new(
        "stored normals",
        &[COMMON_WGSL, OCT16_WGSL, STORED_WGSL],
    )]
}

pub struct StoredNormals {
    pipe: wgpu::ComputePipeline,
}

impl StoredNormals {
    pub fn new(device: &wgpu::Device) -> StoredNormals {
        StoredNormals {
            pipe: shaders()[0].compute(device, None),
        }
    }

    /// Clears level 0 of `targets`' normal pyramid and writes the drawn points' normals into
    /// it. The pyramid's uniforms must hold this frame's view before the commands run.
    pub fn encode(
        &self,
        frame: &PipelineFrame,
        targets: &PyramidTargets,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut Timer,
    ) -> Result<(), ViewerError> {
        let device = &frame.ctx.device;
        let screen = frame.screen;
        let pixels = screen.width as u64 * screen.height as u64;
        encoder.clear_buffer(&targets.normals, 0, Some(pixels * 4));
        let groups = frame
            .arenas
            .iter()
            .map(|d| {
                let (_, [normals]) = frame
                    .cache
                    .arena_streams(d.arena, [PointStream::Normals])?;
                Ok((ArenaGroup::new(device, d, GROUP_SIZE), normals))
            })
            .collect::<Result<Vec<_>, ViewerError>>()?;
        let uniforms = bind(
            device,
            &self.pipe,
            0,
            &[
                (0, screen.uniforms.as_entire_binding()),
                (1, targets.params.as_entire_binding()),
            ],
        );
        let planes = bind(
            device,
            &self.pipe,
            1,
            &[
                (0, screen.depths.as_entire_binding()),
                (5, targets.normals.as_entire_binding()),
            ],
        );
        per_arena_pass(
            encoder,
            timer,
            ("stored normals", &self.pipe),
            (screen.width, screen.height),
            &[&uniforms, &planes],
            &groups,
            |g, normals| {
                bind(
                    device,
                    &self.pipe,
                    2,
                    &[
                        (0, g.ranges.as_entire_binding()),
                        (1, normals.as_entire_binding()),
                        (2, screen.indices.as_entire_binding()),
                    ],
                )
            },
        );
        Ok(())
    }
}
