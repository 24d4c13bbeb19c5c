//! The help window: every row of the shortcut table, then what the mouse does, so the help
//! lists exactly the keys [`crate::viewer::shortcuts::handle`] answers.

use eframe::egui;

use crate::viewer::controller::Controller;
use crate::viewer::shortcuts::{MOUSE, SHORTCUTS};

/// The "Keyboard and mouse" window; closing it hides the help.
pub fn show(controller: &mut Controller, ctx: &egui::Context) {
    let mut open = true;
    egui::Window::new("Keyboard and mouse")
        .open(&mut open)
        .collapsible(false)
        .show(ctx, |ui| {
            egui::Grid::new("help").striped(true).show(ui, |ui| {
                let keys = SHORTCUTS.iter().map(|s| (s.keys, s.description));
                for (keys, what) in keys.chain(MOUSE.iter().copied()) {
                    ui.monospace(keys);
                    ui.label(what);
                    ui.end_row();
                }
            });
        });
    if !open {
        controller.state.show_help = false;
    }
}
