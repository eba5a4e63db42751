//! For tests that run a module on the GPU: one compute pass of given dispatches, submitted.

/// Encodes one compute pass that runs each (pipeline, bind group 0, workgroups x and y) in
/// order, and submits it.
pub fn run_passes(
    ctx: &crate::gpu::GpuContext,
    passes: &[(&wgpu::ComputePipeline, &wgpu::BindGroup, (u32, u32))],
) {
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        for (pipe, group, (x, y)) in passes {
            pass.set_pipeline(pipe);
            pass.set_bind_group(0, *group, &[]);
            pass.dispatch_workgroups(*x, *y, 1);
        }
    }
    ctx.queue.submit([encoder.finish()]);
}
