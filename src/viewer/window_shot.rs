//! The window's screenshot (Ctrl+S, the time bar's button): asked of egui, handed to the
//! controller to write once egui delivers it a frame later.

use std::sync::{Arc, Mutex};

use eframe::egui;

use super::controller::Controller;

/// The window screenshot asked of egui, until it arrives.
#[derive(Default)]
pub struct WindowShot(Arc<Mutex<Option<Arc<egui::ColorImage>>>>);

impl WindowShot {
    /// Asks egui for the window's pixels; the controller writes them once they arrive.
    pub fn save(&self, ctx: &egui::Context, controller: &mut Controller) {
        let slot = self.0.clone();
        let repaint = ctx.clone();
        ctx.request_screenshot(move |image| {
            *slot.lock().expect("screenshot slot") = Some(image);
            repaint.request_repaint();
        });
        controller.status = "saving the window ...".to_owned();
    }

    /// Hands an arrived screenshot to the controller to write.
    pub(super) fn write(&self, controller: &mut Controller) {
        let shot = self.0.lock().expect("screenshot slot").take();
        if let Some(image) = shot {
            controller.save_window_image(image::RgbaImage::from_raw(
                image.size[0] as u32,
                image.size[1] as u32,
                image.pixels.iter().flat_map(|c| c.to_array()).collect(),
            ));
        }
    }
}
