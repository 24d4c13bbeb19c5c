//! A browser's WebGPU device gives the renderer WebGPU's default limits unless it asks for and
//! gets more: 8 storage buffers a shader stage, 32 colour-attachment bytes a sample, 128 MiB a
//! storage binding, no push constants. On a device made with exactly those limits (on the
//! tests' adapter), every technique renders the thesis scene with smoke where the smoke is, or
//! refuses in one line that names the limit it lacks.

use smokeshadow::Wait;
mod common;

use smokeshadow::gpu::{Gpu, OPTIONAL_FEATURES};
use smokeshadow::render::{RenderOptions, TechniqueConfig, render_offscreen};
use smokeshadow::scene::Scene;
use smokeshadow::shadow::{REGISTRY, TechniqueParams};

/// A device on the tests' adapter (the CPU's, or `SMOKESHADOW_TEST_ADAPTER`'s) with WebGPU's
/// default limits and the optional features it has, as a browser would give it.
fn webgpu_default_device() -> Gpu {
    let preference = common::adapter_preference();
    let instance = smokeshadow::gpu::instance();
    let adapter = pollster::block_on(smokeshadow::gpu::ranked_adapters(&instance))
        .into_iter()
        .find(|a| smokeshadow::gpu::matches(&preference, &a.get_info()))
        .unwrap_or_else(|| panic!("GPU tests need an adapter ({preference}); install lavapipe"));
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("webgpu-default-limits"),
        required_features: adapter.features() & OPTIONAL_FEATURES,
        required_limits: wgpu::Limits::default(),
        ..Default::default()
    }))
    .expect("a device with WebGPU's default limits");
    Gpu::from_device(device, queue, adapter.get_info())
}

#[test]
fn under_webgpus_default_limits_every_technique_renders_or_names_the_limit() {
    let gpu = webgpu_default_device();
    // The device holds WebGPU's limits, not the adapter's (lavapipe allows more of each).
    let defaults = wgpu::Limits::default();
    assert_eq!(gpu.limits.max_storage_buffers_per_shader_stage, 8);
    assert_eq!(
        gpu.limits.max_color_attachment_bytes_per_sample,
        defaults.max_color_attachment_bytes_per_sample
    );
    let mut scene = Scene::thesis_plume();
    (scene.output.width_px, scene.output.height_px) = (256, 192);
    let particles = smokeshadow::particles::scene_particles(&scene).unwrap();
    let mut rendered = Vec::new();
    for entry in REGISTRY
        .iter()
        .filter(|e| e.refusal(false, particles.len()).is_none())
    {
        let config = TechniqueConfig {
            name: entry.name.to_owned(),
            params: TechniqueParams::new(24, 256),
        };
        match render_offscreen(&gpu, &scene, &particles, &config, &RenderOptions::default()).wait()
        {
            Ok(frame) => {
                // The smoke's opacity is in the HDR frame's alpha: the plume is there.
                let opaque = frame.hdr.pixels.iter().filter(|p| p[3] > 0.5).count();
                assert!(opaque > 100, "{}: {opaque} pixels of smoke", entry.name);
                rendered.push(entry.name);
            }
            Err(err) => {
                let message = format!("{err:#}");
                assert!(
                    !message.contains('\n') && message.contains("limit `max_"),
                    "{}: not one line naming the limit: {message}",
                    entry.name
                );
            }
        }
    }
    // The reference must run wherever the comparison does, and so must the thesis' techniques.
    for name in ["exact", "none", "osm", "dom", "fom", "has"] {
        assert!(rendered.contains(&name), "{name} under WebGPU's limits");
    }
}
