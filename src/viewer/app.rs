//! The eframe application: glues the [`Controller`] (state and logic, no egui) to egui. Each UI
//! frame it takes in the worker's replies and the keys, lays out the panels around the
//! viewport, lets the controller render what changed, keeps the egui textures in step
//! ([`Textures`]) and asks for the next repaint. Layout changes go in `ViewerApp::ui`; what a
//! control does goes in the controller, how it looks in its panel.

use std::ops::{Deref, DerefMut};
use std::sync::Arc;

use eframe::egui::{self, Color32};

use super::controller::{Controller, Repaint};
use super::panels;
use super::shortcuts;
use super::textures::Textures;
use super::viewport::{self, Drags};
use super::window_shot::WindowShot;
use smokeshadow_core::gpu::Gpu;
use smokeshadow_core::scene::Scene;

/// The viewer application: the controller and what egui needs to show it.
///
/// It dereferences to its [`Controller`], so callers (the tests among them) read and set the
/// state as `app.state`, `app.settled()`, whether or not a window is involved.
pub struct ViewerApp {
    pub controller: Controller,
    textures: Textures,
    window_shot: WindowShot,
    drags: Drags,
}

impl Deref for ViewerApp {
    type Target = Controller;

    fn deref(&self) -> &Controller {
        &self.controller
    }
}

impl DerefMut for ViewerApp {
    fn deref_mut(&mut self) -> &mut Controller {
        &mut self.controller
    }
}

impl ViewerApp {
    pub fn new(cc: &eframe::CreationContext<'_>, scene: Scene, path: Option<String>) -> Self {
        Self::with_span(cc, scene, path, None)
    }

    /// [`ViewerApp::new`], playing `span` (`view --animate`) from the start when given.
    pub fn with_span(
        cc: &eframe::CreationContext<'_>,
        scene: Scene,
        path: Option<String>,
        span: Option<smokeshadow_core::motion::Span>,
    ) -> Self {
        let render_state = cc.wgpu_render_state.clone();
        let gpu = render_state.as_ref().map(|rs| {
            Arc::new(Gpu::from_device(
                rs.device.clone(),
                rs.queue.clone(),
                rs.adapter.get_info(),
            ))
        });
        let mut controller = Controller::new(scene, path, gpu);
        if let Some(span) = span {
            controller.play_span(span);
        }
        Self {
            textures: Textures::new(render_state, &controller),
            controller,
            window_shot: WindowShot::default(),
            drags: Drags::default(),
        }
    }
}

impl eframe::App for ViewerApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        let dt = ctx.input(|i| i.stable_dt).min(0.1);
        let c = &mut self.controller;
        c.receive();
        self.textures.sync_worker_images(&ctx, c);
        self.window_shot.write(c);
        shortcuts::handle(c, &self.window_shot, &ctx);
        c.advance(dt);
        if c.gpu.is_none() {
            egui::CentralPanel::default().show(ui, |ui| {
                ui.colored_label(
                    Color32::RED,
                    "This window has no wgpu renderer: the viewer needs a Vulkan, Metal or DX12 adapter (on a machine without a GPU, Mesa's lavapipe: `apt-get install mesa-vulkan-drivers libvulkan1`).",
                );
            });
            return;
        }

        egui::Panel::left("compare")
            .resizable(false)
            .default_size(300.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| {
                    panels::compare::show(c, ui);
                    ui.separator();
                    panels::numbers::show(c, ui);
                });
            });
        egui::Panel::right("scene")
            .resizable(false)
            .default_size(320.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| {
                    panels::scene::show(c, ui);
                    ui.separator();
                    panels::inspector::show(c, &self.textures, ui);
                    ui.separator();
                    panels::probe::show(c, ui);
                });
            });
        egui::Panel::bottom("time").show(ui, |ui| panels::time_bar::show(c, &self.window_shot, ui));
        let mut viewport_px = (0, 0);
        let mut interacting = c.state.playing;
        egui::CentralPanel::default().show(ui, |ui| {
            let (px, dragging) = viewport::show(c, &self.textures, &mut self.drags, ui);
            viewport_px = px;
            interacting |= dragging;
        });
        interacting |= ctx.dragged_id().is_some();

        c.update(viewport_px, interacting);
        self.textures.sync_views(c);
        if c.state.show_help {
            panels::help::show(c, &ctx);
        }
        match c.repaint(interacting) {
            Repaint::Now => ctx.request_repaint(),
            Repaint::After(delay) => ctx.request_repaint_after(delay),
            Repaint::OnInput => {}
        }
    }
}
