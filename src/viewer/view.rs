//! One configuration of the viewer (A or B) rendered by the shared [`Renderer`] into a texture
//! that the UI shows. The texture is `Rgba8UnormSrgb`, as for the CLI, and egui samples it
//! through an `Rgba8Unorm` view: egui expects already-encoded values, so the sRGB bytes pass
//! through. The view knows nothing of egui: [`super::textures`] registers `display_view` with
//! egui's renderer, and again whenever `output_generation` says the texture was replaced.

use crate::Wait;
use smokeshadow_core::gpu::{Gpu, PassTimes};
use smokeshadow_core::render::{
    FrameStats, OUTPUT_FORMAT, RenderOptions, Renderer, TechniqueConfig,
};
use smokeshadow_core::scene::Scene;
use smokeshadow_core::shadow::ShadowError;
use smokeshadow_core::sim::Particle;

/// What a view last rendered, to skip frames when nothing changed.
#[derive(Clone, Debug, PartialEq)]
struct Rendered {
    revision: u64,
    config: TechniqueConfig,
    size: (u32, u32),
}

/// The output texture and the two views of it.
struct Output {
    texture: wgpu::Texture,
    render_view: wgpu::TextureView,
    display_view: wgpu::TextureView,
}

impl Output {
    fn new(device: &wgpu::Device, size: (u32, u32)) -> Self {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("viewer.output"),
            size: wgpu::Extent3d {
                width: size.0,
                height: size.1,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: OUTPUT_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[wgpu::TextureFormat::Rgba8Unorm],
        });
        let render_view = texture.create_view(&Default::default());
        let display_view = texture.create_view(&wgpu::TextureViewDescriptor {
            format: Some(wgpu::TextureFormat::Rgba8Unorm),
            ..Default::default()
        });
        Self {
            texture,
            render_view,
            display_view,
        }
    }
}

/// A renderer, its output texture, and what it shows.
pub struct View {
    renderer: Renderer,
    config: TechniqueConfig,
    output: Output,
    size: (u32, u32),
    /// Bumped whenever `output` is replaced (on a resize), so the UI registers the new one.
    output_generation: u64,
    rendered: Option<Rendered>,
    /// The last frame's CPU-side numbers.
    pub stats: Option<FrameStats>,
}

impl View {
    pub fn new(gpu: &Gpu, config: &TechniqueConfig, size: (u32, u32)) -> Result<Self, ShadowError> {
        let renderer = Renderer::new(gpu, size.0, size.1, OUTPUT_FORMAT, config).wait()?;
        let output = Output::new(&gpu.device, size);
        Ok(Self {
            renderer,
            config: config.clone(),
            output,
            size,
            output_generation: 0,
            rendered: None,
            stats: None,
        })
    }

    /// Switches technique or parameters (pipelines are rebuilt only when they change); on an
    /// error the view keeps what it had.
    pub fn set_config(&mut self, gpu: &Gpu, config: &TechniqueConfig) -> Result<(), ShadowError> {
        if *config != self.config {
            self.renderer.set_technique(gpu, config).wait()?;
            self.config = config.clone();
        }
        Ok(())
    }

    /// Renders `scene` at `size` unless this exact frame is already shown. Returns whether it
    /// rendered.
    pub fn render(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        options: &RenderOptions,
        revision: u64,
        size: (u32, u32),
    ) -> Result<bool, ShadowError> {
        let wanted = Rendered {
            revision,
            config: self.config.clone(),
            size,
        };
        if self.rendered.as_ref() == Some(&wanted) {
            return Ok(false);
        }
        if size != self.size {
            self.renderer
                .resize(gpu, size.0, size.1)
                .wait()
                .map_err(|e| ShadowError::Gpu(e.to_string()))?;
            self.output = Output::new(&gpu.device, size);
            self.output_generation += 1;
            self.size = size;
        }
        let stats = self
            .renderer
            .render(gpu, scene, particles, options, &self.output.render_view)
            .wait()?;
        self.stats = Some(stats);
        self.rendered = Some(wanted);
        Ok(true)
    }

    /// Pass times of a finished frame, when one has arrived (never waits).
    pub fn poll_times(&mut self, gpu: &Gpu) -> Option<PassTimes> {
        self.renderer.poll_gpu_times(gpu)
    }

    /// The app revision the shown image was rendered for.
    pub fn rendered_revision(&self) -> Option<u64> {
        self.rendered.as_ref().map(|r| r.revision)
    }

    pub fn renderer(&self) -> &Renderer {
        &self.renderer
    }

    pub fn config(&self) -> &TechniqueConfig {
        &self.config
    }

    /// The `Rgba8Unorm` view of the output for the UI to sample.
    pub fn display_view(&self) -> &wgpu::TextureView {
        &self.output.display_view
    }

    /// Which output texture `display_view` is of: it changes when the view is resized.
    pub fn output_generation(&self) -> u64 {
        self.output_generation
    }

    /// The size the view last rendered at.
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    /// Reads the shown image back, waiting for the GPU (tests and explicit saves only).
    pub fn read_image(&self, gpu: &Gpu) -> anyhow::Result<image::RgbaImage> {
        Ok(smokeshadow_core::gpu::read_texture_rgba8(gpu, &self.output.texture).wait()?)
    }
}
