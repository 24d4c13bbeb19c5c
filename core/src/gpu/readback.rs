//! Copying buffers and textures back to the CPU (texture rows padded to 256 bytes on the GPU
//! side). Every read-back is awaited: the copy is submitted, the staging buffer's mapping asked
//! for, and its callback answers a one-shot. On the host the device is polled until the work is
//! done first, so the answer is there when awaited; on the web the browser maps the buffer
//! between tasks and the await yields to it.

use super::{Gpu, GpuError};

/// Copies a 2D texture of `bytes_per_texel` into tightly packed rows.
async fn read_texture(
    gpu: &Gpu,
    texture: &wgpu::Texture,
    bytes_per_texel: u32,
) -> Result<Vec<u8>, GpuError> {
    let (width, height) = (texture.width(), texture.height());
    let unpadded = width * bytes_per_texel;
    let padded =
        unpadded.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback.buffer"),
        size: u64::from(padded) * u64::from(height),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("readback.encoder"),
        });
    encoder.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(height),
            },
        },
        wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
    );
    gpu.queue.submit([encoder.finish()]);
    map_and_copy(gpu, &buffer, |view| {
        let mut out = Vec::with_capacity((unpadded * height) as usize);
        for row in view.chunks_exact(padded as usize) {
            out.extend_from_slice(&row[..unpadded as usize]);
        }
        out
    })
    .await
}

/// Copies `size` bytes of `buffer` from `offset` (both multiples of 4) back to the CPU. The
/// buffer needs `COPY_SRC`.
pub async fn read_buffer(
    gpu: &Gpu,
    buffer: &wgpu::Buffer,
    offset: u64,
    size: u64,
) -> Result<Vec<u8>, GpuError> {
    let staging = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback.staging"),
        size,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("readback.encoder"),
        });
    encoder.copy_buffer_to_buffer(buffer, offset, &staging, 0, size);
    gpu.queue.submit([encoder.finish()]);
    map_and_copy(gpu, &staging, |bytes| bytes.to_vec()).await
}

/// Maps all of `buffer` (after the work already submitted), hands its bytes to `f` and unmaps
/// it.
pub(super) async fn map_and_copy<T>(
    gpu: &Gpu,
    buffer: &wgpu::Buffer,
    f: impl FnOnce(&[u8]) -> T,
) -> Result<T, GpuError> {
    let slice = buffer.slice(..);
    let (tx, rx) = futures_channel::oneshot::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    gpu.wait_idle()?;
    rx.await
        .map_err(|e| GpuError::Readback(e.to_string()))?
        .map_err(|e| GpuError::Readback(e.to_string()))?;
    let view = slice
        .get_mapped_range()
        .map_err(|e| GpuError::Readback(e.to_string()))?;
    let out = f(&view);
    drop(view);
    buffer.unmap();
    Ok(out)
}

/// Reads an 8-bit RGBA texture (e.g. the tone-mapped sRGB frame).
pub async fn read_texture_rgba8(
    gpu: &Gpu,
    texture: &wgpu::Texture,
) -> Result<image::RgbaImage, GpuError> {
    let bytes = read_texture(gpu, texture, 4).await?;
    image::RgbaImage::from_raw(texture.width(), texture.height(), bytes)
        .ok_or_else(|| GpuError::Readback("size mismatch".into()))
}

/// A linear HDR image read back from an RGBA16F texture, as f32.
#[derive(Clone, Debug)]
pub struct Rgba16fImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 4]>,
}

impl Rgba16fImage {
    pub fn get(&self, x: u32, y: u32) -> [f32; 4] {
        self.pixels[(y * self.width + x) as usize]
    }
}

/// Reads an RGBA16F texture (the HDR frame: premultiplied radiance and smoke opacity in alpha).
pub async fn read_texture_rgba16f(
    gpu: &Gpu,
    texture: &wgpu::Texture,
) -> Result<Rgba16fImage, GpuError> {
    let bytes = read_texture(gpu, texture, 8).await?;
    let pixels = bytes
        .chunks_exact(8)
        .map(|t| std::array::from_fn(|i| half_to_f32(u16::from_le_bytes([t[2 * i], t[2 * i + 1]]))))
        .collect();
    Ok(Rgba16fImage {
        width: texture.width(),
        height: texture.height(),
        pixels,
    })
}

/// Reads a single-channel R16F texture (a start-depth map, say) as f32, row by row.
pub async fn read_texture_r16f(gpu: &Gpu, texture: &wgpu::Texture) -> Result<Vec<f32>, GpuError> {
    let bytes = read_texture(gpu, texture, 2).await?;
    Ok(bytes
        .chunks_exact(2)
        .map(|t| half_to_f32(u16::from_le_bytes([t[0], t[1]])))
        .collect())
}

/// IEEE 754 binary16 to f32.
fn half_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = i32::from((h >> 10) & 0x1f);
    let mant = f32::from(h & 0x3ff);
    sign * match exp {
        0 => mant * 2f32.powi(-24),
        31 if mant == 0.0 => f32::INFINITY,
        31 => f32::NAN,
        _ => (1.0 + mant / 1024.0) * 2f32.powi(exp - 15),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn half_floats_decode() {
        use super::half_to_f32;
        assert_eq!(half_to_f32(0x3c00), 1.0);
        assert_eq!(half_to_f32(0xc000), -2.0);
        assert_eq!(half_to_f32(0x0000), 0.0);
        assert_eq!(half_to_f32(0x3555), 0.333_251_95);
        assert_eq!(half_to_f32(0x0001), 2f32.powi(-24));
    }
}
