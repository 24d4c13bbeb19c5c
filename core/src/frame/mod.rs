//! The frame's building blocks, shared by the renderer and the techniques that draw particles
//! themselves (`has`): the Rust mirrors of the WGSL structs (`gpu_data`), the camera's matrices,
//! the target formats, the opaque geometry, and the particle passes (lighting compute, billboard
//! pipelines, blend states). Nothing here knows a shadow technique: dependencies run scene ->
//! sim -> gpu -> frame -> shadow -> render -> the applications.

pub mod camera;
pub mod fullscreen;
pub mod geometry;
pub mod gpu_data;
pub mod occluders;
pub mod particles;

pub use camera::CameraMatrices;
pub use particles::{OVER, ParticleLayouts, ParticlePipelines, UNDER};

/// Format of the HDR frame (premultiplied radiance; alpha = smoke opacity).
pub const HDR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
/// Format of the opaque depth.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Format of the tone-mapped output the CLI writes to PNG.
pub const OUTPUT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
