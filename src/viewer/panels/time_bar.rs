//! The time bar: play / pause and the simulation time, the wind gust's start, the screenshot
//! buttons, the help button and the status line.

use eframe::egui;

use crate::viewer::controller::Controller;
use crate::viewer::window_shot::WindowShot;

/// Bottom bar: time, play, screenshots, status.
pub fn show(controller: &mut Controller, window_shot: &WindowShot, ui: &mut egui::Ui) {
    ui.horizontal(|ui| {
        let label = if controller.state.playing {
            "Pause"
        } else {
            "Play"
        };
        if ui.button(label).clicked() {
            controller.toggle_play();
        }
        let (start, end) = controller.time_range();
        ui.add(egui::Slider::new(&mut controller.state.time_s, start..=end).text("Time (s)"));
        if let Some(span) = &controller.state.span {
            ui.label(format!("span: {}", span.describe()));
        }
        let wind = &controller.state.scene.wind;
        if wind.strength_m_per_s > 0.0 {
            ui.label(format!("wind gust at {:.1} s", wind.start_s));
        }
        if ui.button("Save view PNG (S)").clicked() {
            controller.save_viewport();
        }
        if ui.button("Save window PNG (Ctrl+S)").clicked() {
            let ctx = ui.ctx().clone();
            window_shot.save(&ctx, controller);
        }
        if ui.button("Help (H)").clicked() {
            controller.toggle_help();
        }
        ui.label(&controller.status);
    });
}
