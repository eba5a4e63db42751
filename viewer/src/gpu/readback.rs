//! Copying GPU buffers and textures back to the CPU, blocking (headless rendering, tests and
//! the quality harness; never the window's frame loop).

use crate::ViewerError;
use crate::gpu::GpuContext;

/// The first `size` bytes of `source`.
pub fn read_buffer(
    ctx: &GpuContext,
    source: &wgpu::Buffer,
    size: u64,
) -> Result<Vec<u8>, ViewerError> {
    let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("readback"),
        });
    encoder.copy_buffer_to_buffer(source, 0, &buffer, 0, size);
    ctx.queue.submit([encoder.finish()]);
    map_read(ctx, &buffer)
}

/// A 2D texture of `texel` bytes per pixel, as tightly packed rows.
pub fn read_texture(
    ctx: &GpuContext,
    texture: &wgpu::Texture,
    texel: u32,
) -> Result<Vec<u8>, ViewerError> {
    let (w, h) = (texture.width(), texture.height());
    let row = w * texel;
    let padded =
        row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("image readback"),
        size: padded as u64 * h as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("image readback"),
        });
    encoder.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(h),
            },
        },
        wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        },
    );
    ctx.queue.submit([encoder.finish()]);
    let data = map_read(ctx, &buffer)?;
    let mut out = Vec::with_capacity((row * h) as usize);
    for y in 0..h as usize {
        out.extend_from_slice(&data[y * padded as usize..y * padded as usize + row as usize]);
    }
    Ok(out)
}

fn map_read(ctx: &GpuContext, buffer: &wgpu::Buffer) -> Result<Vec<u8>, ViewerError> {
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.slice(..).map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    ctx.wait()?;
    // The wait above returned, so the map has finished unless the device was lost meanwhile.
    rx.recv_timeout(super::context::GPU_WAIT_LIMIT)
        .map_err(|_| ViewerError::Gpu("the GPU never delivered a readback".into()))?
        .map_err(|e| ViewerError::Gpu(format!("readback failed: {e}")))?;
    let data = buffer
        .slice(..)
        .get_mapped_range()
        .map_err(|e| ViewerError::Gpu(format!("readback failed: {e}")))?
        .to_vec();
    buffer.unmap();
    Ok(data)
}
