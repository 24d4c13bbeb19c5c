//! The numbers panel: A's GPU pass times, CPU sort and UI frame time, shadow-map memory (A's
//! ledger, and B's total), and the measured error of A against exact and of B against A.

use eframe::egui;

use crate::viewer::controller::Controller;

/// Left panel, bottom: GPU times, bytes and the live error.
pub fn show(controller: &mut Controller, ui: &mut egui::Ui) {
    ui.heading("Numbers");
    if let Some(shown) = &controller.worker_views[0].shown
        && controller.side_on_worker(0)
    {
        ui.label(format!(
            "A: exact at {} px, rendered on the worker; {} of lists",
            format_size(shown.key.size.0, shown.key.size.1),
            crate::report::bytes(shown.bytes)
        ));
        return;
    }
    let Some(view) = &controller.views[0] else {
        return;
    };
    let (w, h) = view.size();
    ui.label(format!(
        "A: {} at {} px{}",
        view.config().name,
        format_size(w, h),
        if controller.reduced {
            " (reduced while moving)"
        } else {
            ""
        }
    ));
    let hide = controller.hide_timings;
    let ms = |v: f64, digits: usize| {
        if hide {
            "—".to_owned()
        } else {
            format!("{v:.digits$} ms")
        }
    };
    egui::Grid::new("numbers").striped(true).show(ui, |ui| {
        for (name, t) in &controller.times.passes {
            let caption = if *name == "shadow" {
                "GPU shadow (last build)".to_owned()
            } else {
                format!("GPU {name}")
            };
            ui.label(caption);
            ui.label(ms(*t, 2));
            ui.end_row();
        }
        ui.label("GPU frame (A)");
        ui.label(ms(controller.times.frame_ms, 2));
        ui.end_row();
        if let Some(stats) = &view.stats {
            ui.label("CPU sort");
            ui.label(ms(stats.sort_ms, 3));
            ui.end_row();
        }
        ui.label("UI frame");
        ui.label(ms(controller.ui_frame_ms, 1));
        ui.end_row();
        let memory = view.renderer().technique().memory();
        ui.label("Shadow memory");
        // Resident bytes (over every light face, at their peak), as the sweep's byte budgets
        // count them; the build's scratch (a deep capture's lists, the volume's slabs) is part
        // of them, and said apart.
        let (resident, transient) = view.renderer().shadow_bytes();
        let shown = match transient {
            0 => crate::report::bytes(resident),
            transient => format!(
                "{} ({} transient)",
                crate::report::bytes(resident),
                crate::report::bytes(transient)
            ),
        };
        ui.label(shown).on_hover_text(
            memory
                .entries()
                .iter()
                .map(|e| {
                    let transient = if e.transient { " (transient)" } else { "" };
                    format!("{}: {} bytes{transient}", e.label, e.bytes)
                })
                .collect::<Vec<_>>()
                .join("\n"),
        );
        ui.end_row();
        if let Some(b) = &controller.views[1]
            && controller.state.mode.shows_b()
        {
            ui.label("B memory");
            ui.label(crate::report::bytes(b.renderer().shadow_bytes().0));
            ui.end_row();
        }
    });
    ui.add_space(4.0);
    match &controller.analysed {
        Some(a) => {
            let stale = a.key != controller.analysis_key();
            ui.label(format!(
                "A vs exact: FLIP {:.4}, RMSE {:.4}{}",
                a.a_vs_exact.flip_mean,
                a.a_vs_exact.rmse_srgb,
                if stale { " (updating)" } else { "" }
            ))
            .on_hover_text(format!("measured at full resolution in {:.2} s", a.seconds));
            if let Some(b) = &a.b {
                ui.label(format!(
                    "B vs A: FLIP {:.4}, RMSE {:.4}",
                    b.metrics.flip_mean, b.metrics.rmse_srgb
                ));
            }
        }
        None => {
            ui.label("A vs exact: measuring when the view settles");
        }
    }
    if ui.button("Measure now (E)").clicked() {
        controller.measure_now();
    }
}

fn format_size(w: u32, h: u32) -> String {
    format!("{w}x{h}")
}
