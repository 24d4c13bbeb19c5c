//! The transmittance probe: the curves the worker measured along the light ray through the
//! point last clicked in the viewport (A's technique, the others at its budget, and exact).

use eframe::egui;

use crate::viewer::controller::Controller;
use smokeshadow_core::shadow;

/// Right panel, bottom: the probe's plot.
pub fn show(controller: &mut Controller, ui: &mut egui::Ui) {
    egui::CollapsingHeader::new("Transmittance probe").default_open(true).show(ui, |ui| {
        ui.label("Click the view: T along the light ray through that point, for A's technique, the others at its budget, and exact.");
        let Some(probe) = &controller.probe else {
            return;
        };
        ui.label(format!(
            "point ({:.2}, {:.2}, {:.2}), {:.2} m from the light",
            probe.point.x, probe.point.y, probe.point.z, probe.point_distance_m
        ));
        let exact_colour = ui.visuals().strong_text_color();
        egui_plot::Plot::new("probe")
            .legend(egui_plot::Legend::default().follow_insertion_order(true))
            .height(220.0)
            .x_axis_label("distance from the light (m)")
            .y_axis_label("T")
            .include_y(0.0)
            .include_y(1.0)
            .show(ui, |plot| {
                for s in &probe.series {
                    let mut line = egui_plot::Line::new(s.label.clone(), s.points.clone());
                    if s.label == shadow::reference().name {
                        line = line.color(exact_colour).width(2.5);
                    }
                    plot.line(line);
                }
                plot.vline(egui_plot::VLine::new("probed point", f64::from(probe.point_distance_m)));
            });
    });
}
