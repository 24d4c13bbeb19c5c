//! The scene panel: the scene file (load, save, the thesis scene, reset the camera) and the
//! scene's emitters, wind and spotlight as drag values. Edits go through
//! [`Controller::edit_scene`], which reverts one that does not validate and reports it.

use eframe::egui::{self, Color32};

use crate::viewer::controller::Controller;
use smokeshadow_core::scene::{LightKind, Scene};

/// Right panel, top: the scene file and the scene's settings.
pub fn show(controller: &mut Controller, ui: &mut egui::Ui) {
    ui.heading("Scene");
    ui.horizontal(|ui| {
        let label = ui.label("File");
        ui.text_edit_singleline(&mut controller.scene_path)
            .labelled_by(label.id);
    });
    ui.horizontal(|ui| {
        if ui.button("Load").clicked() {
            controller.load_scene();
        }
        if ui.button("Save").clicked() {
            controller.save_scene();
        }
        if ui.button("Thesis scene").clicked() {
            controller.set_scene(Scene::thesis_plume());
        }
        if ui.button("Reset camera").clicked() {
            controller.reset_camera();
        }
    });
    if let Some(err) = &controller.scene_error {
        ui.colored_label(Color32::RED, err);
    }
    // What is loaded: the particles on screen (from a file or the emitters) and the volume.
    ui.label(controller.scene_summary());
    controller.edit_scene(|s| {
        // One header per emitter; a scene of several names them by number.
        let several = s.emitters.len() > 1;
        for (i, e) in s.emitters.iter_mut().enumerate() {
            let title = match several {
                true => format!("Emitter {}", i + 1),
                false => "Emitter".to_owned(),
            };
            egui::CollapsingHeader::new(title)
                .id_salt(("emitter", i))
                .default_open(i == 0)
                .show(ui, |ui| {
                    egui::Grid::new(("emitter", i)).show(ui, |ui| {
                        drag(ui, "Particles", &mut e.count, 1.0, 1.0..=100_000.0);
                        drag(ui, "Seed", &mut e.seed, 1.0, 0.0..=1e9);
                        drag(
                            ui,
                            "Density τ (1/m)",
                            &mut e.density_per_m,
                            0.01,
                            0.0..=50.0,
                        );
                        drag(
                            ui,
                            "Radius at birth (m)",
                            &mut e.radius_birth_m,
                            0.005,
                            0.01..=5.0,
                        );
                        drag(ui, "Growth (m/s)", &mut e.growth_m_per_s, 0.002, 0.0..=2.0);
                        drag(ui, "Lifetime (s)", &mut e.lifetime_s, 0.05, 0.1..=60.0);
                        drag(
                            ui,
                            "Buoyancy (m/s²)",
                            &mut e.buoyancy_m_per_s2,
                            0.02,
                            0.0..=20.0,
                        );
                        drag(
                            ui,
                            "Turbulence (m/s²)",
                            &mut e.turbulence_m_per_s2,
                            0.02,
                            0.0..=20.0,
                        );
                    });
                });
        }
        if let Some(v) = &mut s.volume {
            egui::CollapsingHeader::new("Volume")
                .default_open(true)
                .show(ui, |ui| {
                    ui.label(v.summary());
                    egui::Grid::new("volume").show(ui, |ui| {
                        drag(
                            ui,
                            "Density scale (1/m)",
                            &mut v.density_scale_per_m,
                            0.001,
                            0.0..=1e4,
                        );
                        drag(ui, "Eye steps", &mut v.eye_steps, 1.0, 1.0..=1024.0);
                        drag(ui, "Build steps", &mut v.build_steps, 1.0, 1.0..=1024.0);
                        drag(ui, "Powder", &mut v.powder, 0.01, 0.0..=1.0);
                        if v.procedural == "cloud" {
                            drag(ui, "Coverage", &mut v.cloud.coverage, 0.01, 0.0..=1.0);
                        }
                    });
                });
        }
        let w = &mut s.wind;
        egui::CollapsingHeader::new("Wind").show(ui, |ui| {
            egui::Grid::new("wind").show(ui, |ui| {
                drag(
                    ui,
                    "Strength (m/s)",
                    &mut w.strength_m_per_s,
                    0.05,
                    0.0..=30.0,
                );
                drag(ui, "Direction x", &mut w.direction.x, 0.05, -1.0..=1.0);
                drag(ui, "Direction z", &mut w.direction.z, 0.05, -1.0..=1.0);
                drag(ui, "Starts at (s)", &mut w.start_s, 0.1, 0.0..=60.0);
                drag(ui, "Ramp (s)", &mut w.ramp_s, 0.05, 0.0..=10.0);
            });
        });
        let l = &mut s.light;
        // The drags reach 100 m, or four times the light's farthest coordinate (a sun over
        // kilometres of cloud).
        let reach = (4.0 * f64::from(l.position.abs().max(l.target.abs()).max_element())).max(100.0);
        let intensity_max = (f64::from(l.intensity) * 4.0).max(1e5);
        egui::CollapsingHeader::new("Light").show(ui, |ui| {
            ui.horizontal(|ui| {
                ui.radio_value(&mut l.kind, LightKind::Spot, "Spot");
                ui.radio_value(&mut l.kind, LightKind::Point, "Point (six cube faces)");
            });
            egui::Grid::new("light").show(ui, |ui| {
                let speed = reach / 2000.0;
                drag(ui, "Position x", &mut l.position.x, speed, -reach..=reach);
                drag(ui, "Position y", &mut l.position.y, speed, -reach..=reach);
                drag(ui, "Position z", &mut l.position.z, speed, -reach..=reach);
                if l.kind.is_spot() {
                    drag(ui, "Target x", &mut l.target.x, speed, -reach..=reach);
                    drag(ui, "Target y", &mut l.target.y, speed, -reach..=reach);
                    drag(ui, "Target z", &mut l.target.z, speed, -reach..=reach);
                    drag(ui, "Cone (deg)", &mut l.cone_angle_deg, 0.2, 1.0..=79.0);
                }
                drag(ui, "Intensity", &mut l.intensity, 1.0, 0.0..=intensity_max);
            });
            ui.label("In the view: drag the yellow ring to aim the light; shift-drag moves the light around its target.");
        });
    });
}

/// A labelled drag value in a grid row.
fn drag<N: egui::emath::Numeric>(
    ui: &mut egui::Ui,
    label: &str,
    value: &mut N,
    speed: f64,
    range: std::ops::RangeInclusive<f64>,
) {
    let l = ui.label(label);
    ui.add(
        egui::DragValue::new(value)
            .speed(speed)
            .range(N::from_f64(*range.start())..=N::from_f64(*range.end())),
    )
    .labelled_by(l.id);
    ui.end_row();
}
