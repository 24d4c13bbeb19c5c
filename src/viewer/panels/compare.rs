//! The comparison panel: the mode, configurations A and B (source, technique, budget), and the
//! settings they share: shadow-map resolution and splatting, the parameters of A's and B's
//! techniques (one group a technique, headed by its name; each a slider over its range, or
//! buttons for its choices), billboards, render size and exposure.

use eframe::egui::{self, Color32};

use crate::viewer::controller::{
    CompareMode, Controller, Side, Source, budget_meaning, clamp_channels, comparable_techniques,
};
use smokeshadow_core::scene::ShadowSettings;
use smokeshadow_core::shadow::{self, OccluderMode, ParamSpec, ParamValue, SplatMode};

/// Left panel, top: the comparison (mode, A, B) and the shared technique settings.
pub fn show(controller: &mut Controller, ui: &mut egui::Ui) {
    ui.heading("Compare");
    ui.horizontal_wrapped(|ui| {
        for (mode, label) in CompareMode::ALL {
            ui.radio_value(&mut controller.state.mode, mode, label);
        }
    });
    if controller.state.mode == CompareMode::Split {
        ui.add(egui::Slider::new(&mut controller.state.split, 0.0..=1.0).text("Divider"));
    }
    ui.separator();
    for (i, label) in ["A", "B"].iter().enumerate() {
        let side = if i == 0 {
            &mut controller.state.a
        } else {
            &mut controller.state.b
        };
        side_editor(ui, label, side);
        ui.separator();
    }
    if let Some(err) = &controller.technique_error {
        ui.colored_label(Color32::RED, err);
    }

    ui.heading("Shadow settings");
    let shadow = &mut controller.state.scene.shadow;
    ui.horizontal(|ui| {
        let label = ui.label("Shadow map");
        egui::ComboBox::from_id_salt("shadow_res")
            .selected_text(format!("{0}x{0}", shadow.resolution_px))
            .show_ui(ui, |ui| {
                for res in [128, 256, 512, 1024, 2048] {
                    ui.selectable_value(&mut shadow.resolution_px, res, format!("{res}x{res}"));
                }
            })
            .response
            .labelled_by(label.id);
    });
    ui.horizontal(|ui| {
        ui.label("Splat");
        ui.radio_value(
            &mut shadow.splat,
            SplatMode::Segment,
            SplatMode::Segment.label(),
        );
        ui.radio_value(
            &mut shadow.splat,
            SplatMode::Point,
            SplatMode::Point.label(),
        );
    });
    ui.horizontal(|ui| {
        ui.label("Occluders");
        ui.radio_value(
            &mut shadow.occluders,
            OccluderMode::Exact,
            "exact (as the reference)",
        );
        ui.radio_value(&mut shadow.occluders, OccluderMode::Map, "depth map (PCF)");
    });
    // The parameters of A's and B's techniques, one group a technique headed by its name and
    // sides (one group when A and B show the same technique).
    let groups = controller.shown_params();
    if groups.is_empty() {
        ui.label("(no technique parameters: A and B show exact)");
    }
    let shadow = &mut controller.state.scene.shadow;
    for group in groups {
        egui::CollapsingHeader::new(group.heading())
            .id_salt(("technique_params", group.technique))
            .default_open(true)
            .show(ui, |ui| {
                if group.params.is_empty() {
                    ui.label(format!("{} has no parameters", group.technique));
                }
                for spec in group.params {
                    param_editor(ui, shadow, spec);
                }
            });
    }
    ui.checkbox(&mut controller.state.spherical, "Spherical billboards");
    let res = &mut controller.state.particle_res;
    egui::ComboBox::from_label("Particle resolution")
        .selected_text(res.name())
        .show_ui(ui, |ui| {
            for r in smokeshadow_core::render::ParticleRes::ALL {
                ui.selectable_value(res, r, r.name());
            }
        });
    let sort = &mut controller.state.sort;
    egui::ComboBox::from_label("Particle sort")
        .selected_text(sort.name())
        .show_ui(ui, |ui| {
            for order in smokeshadow_core::render::SortOrder::ALL {
                ui.selectable_value(sort, order, order.name());
            }
        })
        .response
        .on_hover_text(
            "view: back to front by view depth; half-angle: one sort along the half-angle \
             that has draws in too (thesis ch. 5)",
        );
    ui.checkbox(&mut controller.state.fit_window, "Render at window size");
    ui.add(
        egui::Slider::new(&mut controller.state.scene.shading.exposure, 0.1..=8.0)
            .logarithmic(true)
            .text("Exposure"),
    );
}

/// One technique parameter's editor: a choice of buttons for one with named choices, a slider
/// over its range otherwise, and for one whose default is derived per frame, a checkbox that
/// fixes it. Unset and default are the same setting: the scene keeps only what differs from
/// the default, so it stays canonical.
fn param_editor(ui: &mut egui::Ui, shadow: &mut ShadowSettings, spec: &ParamSpec) {
    let range = spec.min..=spec.max;
    let text = format!("{} ({})", spec.key, spec.unit);
    let logarithmic = spec.max / spec.min.max(1e-6) > 100.0;
    let set = shadow
        .params
        .get(spec.key)
        .and_then(|v| spec.resolve(v).ok());
    match spec.default {
        Some(default) if !spec.choices.is_empty() => {
            let mut index = set.unwrap_or(default) as usize;
            ui.horizontal_wrapped(|ui| {
                ui.label(spec.key).on_hover_text(spec.doc);
                for (i, name) in spec.choices.iter().enumerate() {
                    ui.radio_value(&mut index, i, *name).on_hover_text(spec.doc);
                }
            });
            if index as f32 == default {
                shadow.params.remove(spec.key);
            } else {
                let name = spec.choices[index].to_owned();
                shadow
                    .params
                    .insert(spec.key.to_owned(), ParamValue::Choice(name));
            }
        }
        Some(default) => {
            let mut value = set.unwrap_or(default);
            ui.add(
                egui::Slider::new(&mut value, range)
                    .logarithmic(logarithmic)
                    .text(text),
            )
            .on_hover_text(spec.doc);
            if value == default {
                shadow.params.remove(spec.key);
            } else {
                shadow
                    .params
                    .insert(spec.key.to_owned(), ParamValue::Number(value));
            }
        }
        None => {
            let mut fixed = shadow.params.contains_key(spec.key);
            ui.checkbox(&mut fixed, format!("fixed {}", spec.key))
                .on_hover_text(spec.doc);
            if fixed {
                let mut value = set.unwrap_or(spec.min.max(1.0).min(spec.max));
                ui.add(
                    egui::Slider::new(&mut value, range)
                        .logarithmic(logarithmic)
                        .text(text),
                );
                shadow
                    .params
                    .insert(spec.key.to_owned(), ParamValue::Number(value));
            } else {
                shadow.params.remove(spec.key);
            }
        }
    }
}

/// A side's pickers: source, technique, budget.
fn side_editor(ui: &mut egui::Ui, label: &str, side: &mut Side) {
    ui.strong(format!("Configuration {label}"));
    ui.horizontal(|ui| {
        ui.radio_value(&mut side.source, Source::Technique, "technique");
        ui.radio_value(&mut side.source, Source::Baseline24, "24-ch baseline");
        ui.radio_value(&mut side.source, Source::Exact, shadow::reference().name);
    });
    if side.source == Source::Exact {
        return;
    }
    ui.horizontal(|ui| {
        let l = ui.label(format!("Technique {label}"));
        egui::ComboBox::from_id_salt(format!("technique_{label}"))
            .selected_text(side.technique.clone())
            .show_ui(ui, |ui| {
                for name in comparable_techniques() {
                    ui.selectable_value(&mut side.technique, name.to_owned(), name);
                }
            })
            .response
            .labelled_by(l.id);
    });
    clamp_channels(side);
    if side.source == Source::Technique {
        let entry = shadow::find(&side.technique).expect("registered");
        ui.add(
            egui::Slider::new(&mut side.channels, entry.min_channels..=entry.max_channels)
                .text(format!("Channels {label}")),
        );
        ui.label(budget_meaning(&side.technique, side.channels));
    }
}
