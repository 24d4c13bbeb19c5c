//! The inspector: A's shadow maps, one channel at a time (picked from the technique's debug
//! maps, drawn by the controller into an image at a chosen scale).

use eframe::egui::{self, Vec2};

use crate::viewer::controller::{Controller, INSPECTOR_PX, inspect_channels};
use crate::viewer::textures::Textures;

/// Right panel, middle: the channel picker, its scale and the image.
pub fn show(controller: &mut Controller, textures: &Textures, ui: &mut egui::Ui) {
    egui::CollapsingHeader::new("Inspector: A's shadow maps")
        .default_open(true)
        .show(ui, |ui| {
            let Some(view) = &controller.views[0] else {
                return;
            };
            let channels = inspect_channels(view);
            if channels.is_empty() {
                ui.label(format!(
                    "{} keeps no maps to show (exact evaluates T in closed form through light-space tile lists).",
                    view.config().name
                ));
                return;
            }
            let state = &mut controller.state;
            state.inspect_channel = state.inspect_channel.min(channels.len() - 1);
            ui.horizontal(|ui| {
                let label = ui.label("Channel");
                egui::ComboBox::from_id_salt("inspect_channel")
                    .selected_text(channels[state.inspect_channel].2.clone())
                    .width(220.0)
                    .show_ui(ui, |ui| {
                        for (i, (_, _, name, _)) in channels.iter().enumerate() {
                            ui.selectable_value(&mut state.inspect_channel, i, name);
                        }
                    })
                    .response
                    .labelled_by(label.id);
            });
            ui.add(
                egui::Slider::new(&mut state.inspect_scale, 0.01..=100.0)
                    .logarithmic(true)
                    .text("Scale"),
            );
            if let Some(texture) = textures.inspector {
                ui.image((texture, Vec2::splat(INSPECTOR_PX as f32)));
            }
        });
}
