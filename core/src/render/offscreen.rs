//! A frame drawn offscreen at the scene's size and read back: the path the CLI's `render` and
//! the GPU tests share.

use super::{FrameStats, OUTPUT_FORMAT, RenderOptions, Renderer, TechniqueConfig};
use crate::gpu::{Gpu, PassTimes};
use crate::scene::Scene;
use crate::sim::Particle;

/// An offscreen output texture the CLI and tests render into and read back.
pub struct OffscreenTarget {
    pub texture: wgpu::Texture,
    pub view: wgpu::TextureView,
}

impl OffscreenTarget {
    pub fn new(gpu: &Gpu, width: u32, height: u32) -> Self {
        let texture = gpu
            .device
            .create_texture(&crate::gpu::texture_2d_descriptor(
                "output",
                (width, height),
                OUTPUT_FORMAT,
                wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::COPY_SRC
                    | wgpu::TextureUsages::TEXTURE_BINDING,
            ));
        let view = texture.create_view(&Default::default());
        Self { texture, view }
    }

    /// The tone-mapped frame it holds, read back as 8-bit sRGB (alpha dropped). Awaits the
    /// GPU.
    pub async fn read_rgb(&self, gpu: &Gpu) -> Result<image::RgbImage, crate::gpu::GpuError> {
        let rgba = crate::gpu::read_texture_rgba8(gpu, &self.texture).await?;
        Ok(image::DynamicImage::ImageRgba8(rgba).into_rgb8())
    }
}

/// The result of [`render_offscreen`].
pub struct OffscreenFrame {
    /// The tone-mapped sRGB frame.
    pub image: image::RgbaImage,
    /// The HDR frame: premultiplied linear radiance, alpha = smoke opacity.
    pub hdr: crate::gpu::Rgba16fImage,
    pub stats: FrameStats,
    pub times: PassTimes,
}

/// Renders one frame offscreen at the scene's output size and reads it back: the path the CLI's
/// `render` and the GPU tests share.
pub async fn render_offscreen(
    gpu: &Gpu,
    scene: &Scene,
    particles: &[Particle],
    technique: &TechniqueConfig,
    options: &RenderOptions,
) -> anyhow::Result<OffscreenFrame> {
    let (w, h) = (scene.output.width_px, scene.output.height_px);
    let mut renderer = Renderer::new(gpu, w, h, OUTPUT_FORMAT, technique).await?;
    let target = OffscreenTarget::new(gpu, w, h);
    let stats = renderer
        .render(gpu, scene, particles, options, &target.view)
        .await?;
    let times = renderer.gpu_times(gpu).await?;
    Ok(OffscreenFrame {
        image: crate::gpu::read_texture_rgba8(gpu, &target.texture).await?,
        hdr: crate::gpu::read_texture_rgba16f(gpu, renderer.hdr_texture()).await?,
        stats,
        times,
    })
}
