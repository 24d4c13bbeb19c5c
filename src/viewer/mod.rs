//! `smokeshadow view`: the interactive viewer (egui + winit through eframe), drawing with the
//! same [`crate::render::Renderer`] the CLI, the tests and the sweep use. A graphics engineer
//! flips between techniques and budgets and sees, side by side, what each gets wrong and what it
//! costs.
//!
//! Without egui (tests drive these directly):
//! - [`controller`]: what the user set and what each control does; when to render and measure;
//! - [`view`]: the two configurations A and B rendered into textures;
//! - [`analysis`]: a worker thread for everything that reads back (errors against `exact`,
//!   difference and FLIP images, the transmittance probe, screenshots), so the UI never waits;
//! - [`camera`]: the orbit camera; [`map_view`]: the inspector's shadow-map pictures.
//!
//! With egui:
//! - [`app`]: the eframe application gluing the controller to the rest;
//! - [`panels`]: one file per panel; [`viewport`]: the pictures and the mouse;
//! - [`shortcuts`]: the one table of keys, which also feeds the help;
//! - [`textures`]: the controller's pictures as egui textures; [`window_shot`]: the window's
//!   screenshot, asked of egui.
//!
//! eframe creates the wgpu device with what the renderer needs ([`wgpu_setup`]: the adapter
//! the user asked for, its own limits, timestamp queries and 32-bit float blending/filtering).

pub mod analysis;
pub mod app;
pub mod camera;
pub mod controller;
pub mod map_view;
pub mod panels;
pub mod shortcuts;
pub mod textures;
pub mod view;
pub mod viewport;
pub mod window_shot;

use std::path::PathBuf;
use std::sync::Arc;

use eframe::egui_wgpu;

use smokeshadow_core::gpu::{self, AdapterPreference};

pub use app::ViewerApp;
pub use controller::{CompareMode, Controller, ParamGroup, Side, Source, ViewState};

/// How eframe (or a test harness) should create the wgpu device: the adapter matching
/// `preference` in the tool's usual order, the adapter's own limits, and the optional features
/// the techniques use.
pub fn wgpu_setup(preference: AdapterPreference) -> egui_wgpu::WgpuSetup {
    let mut create = egui_wgpu::WgpuSetupCreateNew::without_display_handle();
    create.instance_descriptor.backends = wgpu::Backends::PRIMARY;
    create.native_adapter_selector = Some(Arc::new(move |adapters, surface| {
        let mut usable: Vec<&wgpu::Adapter> = adapters
            .iter()
            .filter(|a| surface.is_none_or(|s| a.is_surface_supported(s)))
            .filter(|a| gpu::matches(&preference, &a.get_info()))
            .collect();
        usable.sort_by_key(|a| gpu::rank(&a.get_info()));
        usable.first().map(|a| (*a).clone()).ok_or_else(|| {
            format!(
                "no GPU adapter matching {preference} can draw to this window: install a Vulkan driver (on a machine without a GPU, Mesa's lavapipe: `apt-get install mesa-vulkan-drivers libvulkan1`)"
            )
        })
    }));
    create.device_descriptor = Arc::new(gpu::device_descriptor);
    egui_wgpu::WgpuSetup::CreateNew(create)
}

/// Window options for the viewer.
pub fn native_options(preference: AdapterPreference) -> eframe::NativeOptions {
    let mut options = eframe::NativeOptions {
        viewport: eframe::egui::ViewportBuilder::default()
            .with_inner_size([1500.0, 940.0])
            .with_title("smokeshadow"),
        renderer: eframe::Renderer::Wgpu,
        ..Default::default()
    };
    options.wgpu_options.wgpu_setup = wgpu_setup(preference);
    options
}

/// Opens the viewer on `scene` (the embedded thesis scene when `None`), rescaled to `particles`
/// when given ([`crate::scene::Scene::with_particles`]), and returns when the window closes. Problems found
/// before the window exists (a bad scene file, no adapter) are returned as one-line errors.
pub fn run(
    scene_path: Option<PathBuf>,
    particles: Option<u32>,
    span: Option<(String, Option<f32>)>,
    preference: AdapterPreference,
) -> anyhow::Result<()> {
    let scene = crate::particles::open_scene(scene_path.as_deref())?;
    let scene = match particles {
        Some(n) => scene.with_particles(n)?,
        None => scene,
    };
    // The span at the sweep's default rate: a file sequence's own, else 30 fps.
    let span = span
        .map(|(range, fps)| {
            let fps = fps.unwrap_or_else(|| smokeshadow_core::motion::default_fps(&scene));
            smokeshadow_core::motion::Span::parse(&range, fps)
        })
        .transpose()
        .map_err(anyhow::Error::msg)?;
    let adapters = pollster::block_on(gpu::ranked_adapters(&gpu::instance()));
    if !adapters
        .iter()
        .any(|a| gpu::matches(&preference, &a.get_info()))
    {
        return Err(gpu::GpuError::NoAdapter {
            detail: match &preference {
                AdapterPreference::Auto => String::new(),
                other => format!(" matching {other}"),
            },
        }
        .into());
    }
    let path = scene_path.map(|p| p.display().to_string());
    eframe::run_native(
        "smokeshadow",
        native_options(preference),
        Box::new(move |cc| Ok(Box::new(ViewerApp::with_span(cc, scene, path, span)))),
    )
    .map_err(|err| anyhow::anyhow!("cannot open the viewer window: {err}"))
}
