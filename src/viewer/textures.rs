//! The egui side of the viewer's pictures: the controller's GPU outputs (views A and B, the
//! inspector) registered as native egui textures, and the images the analysis worker sent
//! (sides it rendered, the difference and FLIP pictures) uploaded as egui textures. Refreshed
//! from the [`Controller`] once per frame, so the controller never holds an egui type; a new
//! picture adds its cache slot here and its lookup for the panel or viewport that shows it.

use eframe::egui;
use eframe::egui_wgpu;

use super::controller::{CompareMode, Controller};

/// egui's handles for what the controller shows.
#[derive(Default)]
pub struct Textures {
    render_state: Option<egui_wgpu::RenderState>,
    /// Views A and B: their registration and the output generation it is of.
    views: [Option<(egui::TextureId, u64)>; 2],
    /// Sides rendered by the worker: the request the image answered and its upload.
    worker: [Option<(u64, egui::TextureHandle)>; 2],
    /// The analysis' pictures: the request they answered, |A − B| × 4 and the FLIP heat map.
    comparison: Option<(u64, Option<(egui::TextureHandle, egui::TextureHandle)>)>,
    /// The temporal compare's pictures: the request they answered, A's change, `exact`'s and
    /// their difference.
    motion: Option<(u64, Option<[egui::TextureHandle; 3]>)>,
    /// The inspector's image.
    pub inspector: Option<egui::TextureId>,
}

impl Textures {
    /// Registers the controller's inspector image with `render_state`'s egui renderer.
    pub fn new(render_state: Option<egui_wgpu::RenderState>, controller: &Controller) -> Self {
        let inspector = render_state
            .as_ref()
            .zip(controller.inspector.as_ref())
            .map(|(rs, inspector)| {
                rs.renderer.write().register_native_texture(
                    &rs.device,
                    &inspector.display_view,
                    wgpu::FilterMode::Nearest,
                )
            });
        Self {
            render_state,
            inspector,
            ..Default::default()
        }
    }

    /// Uploads the worker's images that arrived since the last call (after
    /// [`Controller::receive`]).
    pub fn sync_worker_images(&mut self, ctx: &egui::Context, controller: &Controller) {
        let load = |name: String, image: &image::RgbImage| {
            let size = [image.width() as usize, image.height() as usize];
            ctx.load_texture(
                name,
                egui::ColorImage::from_rgb(size, image.as_raw()),
                egui::TextureOptions::LINEAR,
            )
        };
        for (i, (view, cached)) in controller
            .worker_views
            .iter()
            .zip(&mut self.worker)
            .enumerate()
        {
            let shown = view.shown.as_ref();
            if shown.map(|s| s.id) != cached.as_ref().map(|(id, _)| *id) {
                *cached = shown.map(|s| (s.id, load(format!("viewer.side{i}"), &s.image)));
            }
        }
        let analysed = controller.analysed.as_ref();
        if analysed.map(|a| a.id) != self.comparison.as_ref().map(|(id, _)| *id) {
            self.comparison = analysed.map(|a| {
                let pictures = a.b.as_ref().map(|b| {
                    (
                        load("viewer.difference".to_owned(), &b.difference_x4),
                        load("viewer.flip".to_owned(), &b.flip_heat),
                    )
                });
                (a.id, pictures)
            });
        }
        if analysed.map(|a| a.id) != self.motion.as_ref().map(|(id, _)| *id) {
            self.motion = analysed.map(|a| {
                let pictures = a.motion.as_ref().map(|(p, _)| {
                    [
                        load("viewer.change_a".to_owned(), &p.technique),
                        load("viewer.change_exact".to_owned(), &p.exact),
                        load("viewer.change_difference".to_owned(), &p.difference),
                    ]
                });
                (a.id, pictures)
            });
        }
    }

    /// The temporal compare's three pictures (A's change, `exact`'s, their difference), once
    /// they arrived.
    pub fn motion(&self) -> Option<[egui::TextureId; 3]> {
        let pictures = self.motion.as_ref()?.1.as_ref()?;
        Some(pictures.each_ref().map(egui::TextureHandle::id))
    }

    /// Registers views A and B with egui, or re-registers them after a resize (after
    /// [`Controller::update`] rendered them). The controller creates each view once.
    pub fn sync_views(&mut self, controller: &Controller) {
        let Some(rs) = &self.render_state else {
            return;
        };
        for (view, cached) in controller.views.iter().zip(&mut self.views) {
            let Some(view) = view else {
                continue;
            };
            let generation = view.output_generation();
            match cached {
                None => {
                    let id = rs.renderer.write().register_native_texture(
                        &rs.device,
                        view.display_view(),
                        wgpu::FilterMode::Linear,
                    );
                    *cached = Some((id, generation));
                }
                Some((id, shown)) if *shown != generation => {
                    rs.renderer.write().update_egui_texture_from_wgpu_texture(
                        &rs.device,
                        view.display_view(),
                        wgpu::FilterMode::Linear,
                        *id,
                    );
                    *shown = generation;
                }
                Some(_) => {}
            }
        }
    }

    /// The texture side `i` shows now.
    pub fn side(&self, controller: &Controller, i: usize) -> Option<egui::TextureId> {
        if controller.side_on_worker(i) {
            self.worker[i].as_ref().map(|(_, t)| t.id())
        } else {
            self.views[i].map(|(id, _)| id)
        }
    }

    /// The analysis' picture for `mode` (difference or FLIP map), once it arrived.
    pub fn comparison(&self, mode: CompareMode) -> Option<egui::TextureId> {
        let (difference, flip) = self.comparison.as_ref()?.1.as_ref()?;
        Some(if mode == CompareMode::Difference {
            difference.id()
        } else {
            flip.id()
        })
    }
}
