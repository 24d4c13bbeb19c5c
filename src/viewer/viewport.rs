//! The viewport: the pictures of the current comparison mode (A alone, split, side by side,
//! flip, the worker's difference and FLIP maps), the corner caption, the spotlight's handle, and
//! what the mouse does there (orbit, pan, zoom, aim or move the light, drag the divider, probe).
//! The geometry (where the image sits, what a pointer position means in it) is worked out here;
//! what a gesture changes is the [`Controller`]'s. A new mode draws its case in [`show`].

use eframe::egui::{self, Color32, PointerButton, Rect, Vec2, pos2};
use glam::Vec3;

use super::controller::{CompareMode, Controller};
use super::shortcuts::{self, Action};
use super::textures::Textures;

/// Which drag is under way (decided when it starts).
#[derive(Default)]
pub struct Drags {
    /// The current drag started on the split view's divider.
    divider: bool,
    /// The current drag started on the spotlight's target handle.
    light_target: bool,
}

/// Draws the viewport and handles its mouse input. Returns the image's size in physical pixels
/// and whether the user is dragging in it.
pub fn show(
    controller: &mut Controller,
    textures: &Textures,
    drags: &mut Drags,
    ui: &mut egui::Ui,
) -> ((u32, u32), bool) {
    let state = &controller.state;
    let available = ui.available_size();
    let (full_w, full_h) = (
        state.scene.output.width_px as f32,
        state.scene.output.height_px as f32,
    );
    let aspect = if state.fit_window {
        available.x / available.y.max(1.0)
    } else {
        full_w / full_h
    };
    // Pictures across: A and B side by side, the temporal compare's three.
    let across = match state.mode {
        CompareMode::SideBySide => 2.0,
        CompareMode::Motion => 3.0,
        _ => 1.0,
    };
    let slot = Vec2::new(available.x / across, available.y);
    let size = if slot.x / slot.y.max(1.0) > aspect {
        Vec2::new(slot.y * aspect, slot.y)
    } else {
        Vec2::new(slot.x, slot.x / aspect)
    };
    let total = Vec2::new(size.x * across, size.y);
    // Centred in the space the viewport is given: the image keeps its aspect, so it fills
    // that space's width or its height, and the rest is shared evenly around it.
    let space = Rect::from_min_size(ui.cursor().min, available);
    let response = ui.allocate_rect(
        Rect::from_center_size(space.center(), total),
        egui::Sense::click_and_drag(),
    );
    let rect = response.rect;
    let image_rect = Rect::from_min_size(rect.min, size);
    let ppp = ui.ctx().pixels_per_point();
    let px = ((size.x * ppp) as u32, (size.y * ppp) as u32);

    let whole = Rect::from_min_max(pos2(0.0, 0.0), pos2(1.0, 1.0));
    let painter = ui.painter_at(rect);
    let id = |i: usize| textures.side(controller, i);
    match state.mode {
        CompareMode::Single => {
            if let Some(a) = id(0) {
                painter.image(a, image_rect, whole, Color32::WHITE);
            }
        }
        CompareMode::Split => {
            let x = image_rect.left() + image_rect.width() * state.split;
            if let Some(a) = id(0) {
                painter.image(
                    a,
                    Rect::from_min_max(image_rect.min, pos2(x, image_rect.max.y)),
                    Rect::from_min_max(pos2(0.0, 0.0), pos2(state.split, 1.0)),
                    Color32::WHITE,
                );
            }
            if let Some(b) = id(1) {
                painter.image(
                    b,
                    Rect::from_min_max(pos2(x, image_rect.min.y), image_rect.max),
                    Rect::from_min_max(pos2(state.split, 0.0), pos2(1.0, 1.0)),
                    Color32::WHITE,
                );
            }
            painter.line_segment(
                [pos2(x, image_rect.top()), pos2(x, image_rect.bottom())],
                egui::Stroke::new(2.0, Color32::WHITE),
            );
        }
        CompareMode::SideBySide => {
            if let Some(a) = id(0) {
                painter.image(a, image_rect, whole, Color32::WHITE);
            }
            if let Some(b) = id(1) {
                painter.image(
                    b,
                    image_rect.translate(Vec2::new(size.x, 0.0)),
                    whole,
                    Color32::WHITE,
                );
            }
        }
        CompareMode::Flip => {
            let show_b = shortcuts::held(ui.ctx(), Action::ShowB);
            if let Some(t) = id(usize::from(show_b)) {
                painter.image(t, image_rect, whole, Color32::WHITE);
            }
            if show_b {
                ui.ctx().request_repaint();
            }
        }
        CompareMode::Motion => match textures.motion() {
            Some(pictures) => {
                for (i, texture) in pictures.into_iter().enumerate() {
                    let at = image_rect.translate(Vec2::new(size.x * i as f32, 0.0));
                    painter.image(texture, at, whole, Color32::WHITE);
                    let label = ["A's change", "exact's change", "A's - exact's"][i];
                    painter.text(
                        at.left_bottom() + Vec2::new(8.0, -8.0),
                        egui::Align2::LEFT_BOTTOM,
                        label,
                        egui::FontId::proportional(14.0),
                        Color32::WHITE,
                    );
                }
            }
            None => {
                if let Some(a) = id(0) {
                    painter.image(a, image_rect, whole, Color32::from_gray(90));
                }
            }
        },
        CompareMode::Difference | CompareMode::FlipMap => match textures.comparison(state.mode) {
            Some(texture) => {
                painter.image(texture, image_rect, whole, Color32::WHITE);
            }
            None => {
                if let Some(a) = id(0) {
                    painter.image(a, image_rect, whole, Color32::from_gray(90));
                }
            }
        },
    }
    painter.text(
        rect.left_top() + Vec2::new(8.0, 8.0),
        egui::Align2::LEFT_TOP,
        caption(controller),
        egui::FontId::proportional(15.0),
        Color32::WHITE,
    );

    // The spotlight's handle: where its axis meets the scene, and the axis towards the light.
    let scene = controller.frame_scene();
    // (The camera's aspect is the image's, whatever size it renders at.)
    let (w, h) = (
        (image_rect.width().round() as u32).max(1),
        (image_rect.height().round() as u32).max(1),
    );
    let camera = smokeshadow_core::render::CameraMatrices::new(&scene, w, h);
    let to_screen = |p: Vec3| {
        camera.project_to_pixel(p, w, h).map(|px| {
            image_rect.min
                + Vec2::new(px.x, px.y) / Vec2::new(w as f32, h as f32) * image_rect.size()
        })
    };
    let handle = to_screen(scene.light.target);
    if let Some(h) = handle.filter(|h| image_rect.contains(*h)) {
        let yellow = Color32::from_rgb(255, 210, 60);
        let toward =
            scene.light.target + (scene.light.position - scene.light.target).normalize() * 1.5;
        if let Some(t) = to_screen(toward) {
            painter.line_segment([h, t], egui::Stroke::new(1.5, yellow));
        }
        painter.circle_stroke(h, 7.0, egui::Stroke::new(2.0, yellow));
    }

    // Interaction: orbit, pan, zoom, light, divider, probe.
    let uv_of = |p: egui::Pos2| {
        let uv = (p - image_rect.min) / image_rect.size();
        glam::Vec2::new(uv.x, uv.y)
    };
    let mut dragging = false;
    let shift = ui.input(|i| i.modifiers.shift);
    if response.drag_started()
        && let Some(p) = response.interact_pointer_pos()
    {
        let state = &controller.state;
        let x = image_rect.left() + image_rect.width() * state.split;
        drags.divider = state.mode == CompareMode::Split && (p.x - x).abs() < 10.0;
        drags.light_target = !drags.divider && handle.is_some_and(|h| h.distance(p) < 12.0);
    }
    if response.dragged_by(PointerButton::Primary) {
        let d = response.drag_delta();
        if drags.divider {
            let split = &mut controller.state.split;
            *split = (*split + d.x / image_rect.width()).clamp(0.0, 1.0);
        } else if drags.light_target
            && let Some(p) = response.interact_pointer_pos()
        {
            controller.aim_light(&camera, uv_of(p));
        } else if shift {
            controller.orbit_light(d.x, d.y);
        } else {
            controller.state.orbit.orbit(d.x, d.y);
        }
        dragging = true;
    }
    if response.dragged_by(PointerButton::Secondary) || response.dragged_by(PointerButton::Middle) {
        let d = response.drag_delta();
        let fov_y_deg = controller.state.scene.camera.fov_y_deg;
        controller
            .state
            .orbit
            .pan(d.x, d.y, image_rect.height(), fov_y_deg);
        dragging = true;
    }
    if response.drag_stopped() {
        drags.divider = false;
        drags.light_target = false;
    }
    if response.hovered() {
        let scroll = ui.input(|i| i.smooth_scroll_delta.y);
        if scroll != 0.0 {
            controller.state.orbit.zoom(scroll / 50.0);
            dragging = true;
        }
        if let Some(p) = response.hover_pos()
            && image_rect.contains(p)
        {
            response
                .clone()
                .on_hover_text_at_pointer(pixel_readout(controller, uv_of(p)));
        }
    }
    if response.clicked()
        && let Some(p) = response.interact_pointer_pos()
    {
        // The same point in the first picture, whichever picture was clicked.
        let column = ((p.x - image_rect.left()) / size.x)
            .floor()
            .clamp(0.0, across - 1.0);
        let local = p - Vec2::new(size.x * column, 0.0);
        if image_rect.contains(local) {
            controller.request_probe(uv_of(local));
        }
    }
    (px, dragging)
}

/// The caption in the top left corner: what each side shows, or what the analysis measured.
fn caption(controller: &Controller) -> String {
    let state = &controller.state;
    // With the size it renders at (not for a side the worker renders: its size is the frame's).
    let label = |view: usize, side: &super::controller::Side| match &controller.views[view] {
        Some(v) if !controller.side_on_worker(view) => {
            format!("{} · {}x{} px", side.label(), v.size().0, v.size().1)
        }
        _ => side.label(),
    };
    match state.mode {
        CompareMode::Single | CompareMode::Flip => format!("A: {}", label(0, &state.a)),
        CompareMode::Difference | CompareMode::FlipMap => {
            let what = if state.mode == CompareMode::Difference {
                "|A - B| x 4"
            } else {
                "FLIP of B vs A"
            };
            let key = controller.analysis_key();
            match controller
                .analysed
                .as_ref()
                .and_then(|a| a.b.as_ref().map(|b| (&a.key, &b.metrics)))
            {
                Some((measured, m)) => format!(
                    "{what}: A {} / B {}, FLIP mean {:.4}{}",
                    state.a.label(),
                    state.b.label(),
                    m.flip_mean,
                    if *measured != key { " (updating)" } else { "" }
                ),
                None => format!("{what}: computing ..."),
            }
        }
        CompareMode::Motion => {
            let key = controller.analysis_key();
            match controller.analysed.as_ref().and_then(|a| {
                let (p, before) = a.motion.as_ref()?;
                Some((&a.key, p, before))
            }) {
                Some((measured, p, before)) => format!(
                    "A {}: change from t = {before:.3} s to {:.3} s, x{} (orange brighter, blue darker)\ntemporal error {:.2e} (p99.9 {:.2e}), {} pops; exact changes {:.2e}{}",
                    state.a.label(),
                    state.time_s,
                    smokeshadow_core::motion::CHANGE_GAIN,
                    p.temporal_error,
                    p.temporal_p999,
                    p.pops,
                    p.exact_change,
                    if *measured != key { " (updating)" } else { "" }
                ),
                None => "A's change vs exact's: computing ... (after the view settles, paused)"
                    .to_owned(),
            }
        }
        _ => format!("A: {}    B: {}", label(0, &state.a), label(1, &state.b)),
    }
}

/// The pixel values under the cursor, from the worker's full-size image of A (once the
/// view has settled and been measured).
fn pixel_readout(controller: &Controller, uv: glam::Vec2) -> String {
    let key = controller.analysis_key();
    let values = match controller.analysed.as_ref().filter(|a| a.key == key) {
        Some(a) => {
            let (w, h) = a.image_a.dimensions();
            let x = ((uv.x * w as f32) as u32).min(w - 1);
            let y = ((uv.y * h as f32) as u32).min(h - 1);
            let [r, g, b] = a.image_a.get_pixel(x, y).0;
            format!("A pixel ({x}, {y}): sRGB {r} {g} {b}")
        }
        None => "A pixel: measuring when the view settles".to_owned(),
    };
    format!("{values}\nclick to probe T along the light ray here")
}
