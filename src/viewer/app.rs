//! The viewer application: what the user set ([`ViewState`]), the panels that set it, the
//! viewport that shows configurations A and B in the comparison modes, and the bookkeeping that
//! decides when to render (only when something changed, at half resolution while the user drags,
//! full resolution when idle) and when to ask the analysis worker for numbers.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use eframe::egui::{self, Color32, Key, PointerButton, Rect, Vec2, pos2};
use eframe::egui_wgpu;
use glam::Vec3;

use super::analysis::{Analysis, Frame, ProbeSeries, Reply, Request};
use super::camera::Orbit;
use super::map_view::{MAP_VIEW_FORMAT, MapView};
use super::view::View;
use crate::diff::Metrics;
use crate::gpu::Gpu;
use crate::render::{RenderOptions, TechniqueConfig};
use crate::scene::Scene;
use crate::shadow::{self, MapKind, SplatMode};
use crate::sim::{Particle, Simulation};

/// How A and B are shown.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompareMode {
    /// A alone.
    Single,
    /// A left of a draggable divider, B right of it.
    Split,
    /// A and B next to each other.
    SideBySide,
    /// A, and B while the B key is held.
    Flip,
    /// |A − B| × 4.
    Difference,
    /// The FLIP error map of B against A.
    FlipMap,
}

impl CompareMode {
    /// Every mode with its label and keyboard shortcut.
    pub const ALL: [(CompareMode, &'static str, Key); 6] = [
        (CompareMode::Single, "Single", Key::Num1),
        (CompareMode::Split, "Split", Key::Num2),
        (CompareMode::SideBySide, "Side by side", Key::Num3),
        (CompareMode::Flip, "Flip (hold B)", Key::Num4),
        (CompareMode::Difference, "Difference x4", Key::Num5),
        (CompareMode::FlipMap, "FLIP map", Key::Num6),
    ];

    /// Whether B is rendered in this mode.
    pub fn shows_b(self) -> bool {
        !matches!(self, CompareMode::Single)
    }

    /// Whether the picture comes from the analysis worker (A and B read back and compared).
    pub fn analysed(self) -> bool {
        matches!(self, CompareMode::Difference | CompareMode::FlipMap)
    }
}

/// What a side (A or B) shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// The side's technique at the side's budget.
    Technique,
    /// The side's technique at 24 channels: the thesis' baseline.
    Baseline24,
    /// The `exact` reference.
    Exact,
}

/// One side of the comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct Side {
    pub source: Source,
    pub technique: String,
    pub channels: u32,
}

/// Everything the user set. The scene (camera, light, emitter, wind, shadow-map settings,
/// exposure) is the one saved to and loaded from TOML.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewState {
    pub scene: Scene,
    pub orbit: Orbit,
    pub time_s: f32,
    pub playing: bool,
    pub a: Side,
    pub b: Side,
    pub mode: CompareMode,
    /// Divider position in split view, 0..1 across the image.
    pub split: f32,
    pub spherical: bool,
    /// Render at the viewport's size instead of the scene's output size.
    pub fit_window: bool,
    /// Inspector: the selected map channel (index into the flattened list) and its scale.
    pub inspect_channel: usize,
    pub inspect_scale: f32,
    pub show_help: bool,
}

/// What a measurement is of: the frame's revision and the configurations compared.
#[derive(Clone, Debug, PartialEq)]
struct AnalysisKey {
    revision: u64,
    a: TechniqueConfig,
    b: Option<TechniqueConfig>,
}

/// What the worker last measured, and of what.
struct Analysed {
    key: AnalysisKey,
    /// A as the worker rendered it (full size), for the cursor's pixel values.
    image_a: image::RgbImage,
    a_vs_exact: Metrics,
    seconds: f64,
    b: Option<(Metrics, egui::TextureHandle, egui::TextureHandle)>,
}

/// The last probe's curves.
struct Probed {
    point: Vec3,
    point_distance_m: f32,
    series: Vec<ProbeSeries>,
}

/// What a side rendered by the worker shows.
#[derive(Clone, Debug, PartialEq)]
struct WorkerKey {
    revision: u64,
    size: (u32, u32),
    config: TechniqueConfig,
}

/// A side shown through the analysis worker: `exact`, whose build reads its list sizes back
/// from the GPU, which the UI thread never waits for.
#[derive(Default)]
struct WorkerView {
    shown: Option<(WorkerKey, egui::TextureHandle, u64)>,
    pending: Option<(u64, WorkerKey)>,
}

/// GPU pass times, smoothed over the frames that ran them (the shadow build is skipped while
/// only the camera moves, so its figure is that of the last build), and the frame total.
#[derive(Default)]
struct Smoothed {
    passes: Vec<(&'static str, f64)>,
    frame_ms: f64,
}

impl Smoothed {
    fn add(&mut self, times: &crate::gpu::PassTimes) {
        const KEEP: f64 = 0.7;
        let blend = |old: &mut f64, new: f64| *old = KEEP * *old + (1.0 - KEEP) * new;
        for (name, ms) in &times.passes {
            match self.passes.iter_mut().find(|(n, _)| n == name) {
                Some((_, v)) => blend(v, *ms),
                None => self.passes.push((name, *ms)),
            }
        }
        if self.frame_ms == 0.0 {
            self.frame_ms = times.total_ms();
        } else {
            blend(&mut self.frame_ms, times.total_ms());
        }
    }
}

/// The inspector's image target.
struct Inspector {
    map_view: MapView,
    render_view: wgpu::TextureView,
    texture_id: egui::TextureId,
    drawn: Option<(u64, usize, u32)>,
}

/// Side of the inspector image, pixels.
const INSPECTOR_PX: u32 = 256;
/// How long after the last change the viewer waits before rendering full resolution and
/// asking for the error against `exact`.
const SETTLE: Duration = Duration::from_millis(350);

/// The viewer application.
pub struct ViewerApp {
    pub state: ViewState,
    /// The scene as loaded (for "reset camera" and "revert").
    loaded_scene: Scene,
    pub scene_path: String,
    /// The last scene that validated (edits that do not are reverted to it).
    valid_scene: Scene,
    gpu: Option<Arc<Gpu>>,
    render_state: Option<egui_wgpu::RenderState>,
    sim: Simulation,
    particles: Arc<Vec<Particle>>,
    sim_inputs: (crate::scene::Emitter, crate::scene::Wind, f32),
    views: [Option<View>; 2],
    /// Sides rendered on the worker (see [`WorkerView`]).
    worker_views: [WorkerView; 2],
    analysis: Option<Analysis>,
    inspector: Option<Inspector>,
    /// Bumped whenever something that reaches the pixels changes.
    pub revision: u64,
    last_frame_state: Option<(Scene, bool, f32)>,
    last_change: Instant,
    reduced: bool,
    times: Smoothed,
    analysed: Option<Analysed>,
    /// Measurements asked for and not yet answered (or superseded): request id and key.
    requested: Vec<(u64, AnalysisKey)>,
    next_request: u64,
    probe: Option<Probed>,
    /// One-line problems shown in the panels: technique (A or B), scene, analysis.
    pub technique_error: Option<String>,
    pub scene_error: Option<String>,
    pub status: String,
    window_shot: Arc<Mutex<Option<Arc<egui::ColorImage>>>>,
    /// Frames rendered by view A (for tests and the numbers panel).
    pub frames_rendered: u64,
    last_render: Option<Instant>,
    ui_frame_ms: f64,
    /// Shows timings as "—" (snapshot tests: the numbers differ run to run).
    pub hide_timings: bool,
    /// Whether the current drag started on the split view's divider.
    dragging_divider: bool,
    /// Whether the current drag started on the spotlight's target handle.
    dragging_light_target: bool,
}

impl ViewerApp {
    pub fn new(cc: &eframe::CreationContext<'_>, scene: Scene, path: Option<String>) -> Self {
        let render_state = cc.wgpu_render_state.clone();
        let gpu = render_state.as_ref().map(|rs| {
            Arc::new(Gpu::from_device(
                rs.device.clone(),
                rs.queue.clone(),
                rs.adapter.get_info(),
            ))
        });
        let analysis = gpu.clone().map(Analysis::new);
        let inspector = render_state.as_ref().map(|rs| {
            let texture = rs.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("viewer.inspector"),
                size: wgpu::Extent3d {
                    width: INSPECTOR_PX,
                    height: INSPECTOR_PX,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: MAP_VIEW_FORMAT,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[wgpu::TextureFormat::Rgba8Unorm],
            });
            let egui_view = texture.create_view(&wgpu::TextureViewDescriptor {
                format: Some(wgpu::TextureFormat::Rgba8Unorm),
                ..Default::default()
            });
            let texture_id = rs.renderer.write().register_native_texture(
                &rs.device,
                &egui_view,
                wgpu::FilterMode::Nearest,
            );
            Inspector {
                map_view: MapView::new(&rs.device),
                render_view: texture.create_view(&Default::default()),
                texture_id,
                drawn: None,
            }
        });
        let time_s = scene.sim.duration_s;
        let mut sim = Simulation::new(&scene);
        sim.advance_to(time_s);
        let particles = Arc::new(sim.particles());
        let state = ViewState {
            orbit: Orbit::from_camera(&scene.camera),
            time_s,
            playing: false,
            a: Side {
                source: Source::Technique,
                technique: shadow::VIEWER_SIDES.0.to_owned(),
                channels: 8,
            },
            b: Side {
                source: Source::Exact,
                technique: shadow::VIEWER_SIDES.1.to_owned(),
                channels: 24,
            },
            mode: CompareMode::Single,
            split: 0.5,
            spherical: true,
            fit_window: false,
            inspect_channel: 0,
            inspect_scale: 1.0,
            show_help: false,
            scene: scene.clone(),
        };
        Self {
            sim_inputs: (scene.emitter.clone(), scene.wind.clone(), scene.sim.step_s),
            loaded_scene: scene.clone(),
            valid_scene: scene,
            scene_path: path.unwrap_or_else(|| "scene.toml".to_owned()),
            state,
            gpu,
            render_state,
            sim,
            particles,
            views: [None, None],
            worker_views: Default::default(),
            analysis,
            inspector,
            revision: 0,
            last_frame_state: None,
            last_change: Instant::now(),
            reduced: false,
            times: Smoothed::default(),
            analysed: None,
            requested: Vec::new(),
            next_request: 0,
            probe: None,
            technique_error: None,
            scene_error: None,
            status: String::new(),
            window_shot: Arc::default(),
            frames_rendered: 0,
            last_render: None,
            ui_frame_ms: 0.0,
            hide_timings: false,
            dragging_divider: false,
            dragging_light_target: false,
        }
    }

    /// Whether the view shows the current state at full resolution and its measurement against
    /// `exact` has arrived (nothing more will change without input).
    pub fn settled(&self) -> bool {
        let shown = |i: usize| {
            let side = if i == 0 { &self.state.a } else { &self.state.b };
            let config = self.config(side);
            if renders_on_worker(&config) {
                self.worker_views[i]
                    .shown
                    .as_ref()
                    .is_some_and(|(k, _, _)| k.revision == self.revision && k.config == config)
            } else {
                self.views[i]
                    .as_ref()
                    .is_some_and(|v| v.rendered_revision() == Some(self.revision))
            }
        };
        let key = self.analysis_key();
        !self.reduced
            && shown(0)
            && (!self.state.mode.shows_b() || shown(1))
            && self.analysed.as_ref().is_some_and(|a| a.key == key)
            && !self.analysis.as_ref().is_some_and(Analysis::busy)
    }

    /// Where the view's bookkeeping stands, in one line (for tests' timeout messages).
    pub fn progress(&self) -> String {
        format!(
            "revision {}, A shows {:?}, B shows {:?}, reduced {}, measured {:?} (with B: {}), requested {:?}, worker busy {}, status {:?}, technique error {:?}",
            self.revision,
            self.views[0].as_ref().and_then(View::rendered_revision),
            self.views[1].as_ref().and_then(View::rendered_revision),
            self.reduced,
            self.analysed.as_ref().map(|a| a.key.revision),
            self.analysed.as_ref().is_some_and(|a| a.b.is_some()),
            self.requested.last().map(|(_, k)| k.revision),
            self.analysis.as_ref().is_some_and(Analysis::busy),
            self.status,
            self.technique_error,
        )
    }

    /// Whether the A/B comparison images for the current state have arrived.
    pub fn has_comparison(&self) -> bool {
        let key = self.analysis_key();
        self.analysed
            .as_ref()
            .is_some_and(|a| a.key == key && a.b.is_some())
    }

    /// What a measurement of the current view would be of.
    fn analysis_key(&self) -> AnalysisKey {
        AnalysisKey {
            revision: self.revision,
            a: self.config(&self.state.a),
            b: self
                .state
                .mode
                .shows_b()
                .then(|| self.config(&self.state.b)),
        }
    }

    /// The technique configuration a side stands for.
    pub fn config(&self, side: &Side) -> TechniqueConfig {
        let (name, channels) = match side.source {
            Source::Technique => (side.technique.as_str(), side.channels),
            Source::Baseline24 => (side.technique.as_str(), 24),
            Source::Exact => (shadow::reference().name, 1),
        };
        TechniqueConfig {
            name: name.to_owned(),
            params: self.state.scene.shadow.params(channels),
        }
    }

    /// The frame view A shows, read back from the GPU (waits; for tests and checks).
    pub fn read_view_a(&self) -> Option<image::RgbaImage> {
        let gpu = self.gpu.as_ref()?;
        self.views[0].as_ref()?.read_image(gpu).ok()
    }

    /// Size view A last rendered at.
    pub fn view_a_size(&self) -> Option<(u32, u32)> {
        self.views[0].as_ref().map(View::size)
    }

    /// The scene as rendered: the orbit applied to the camera once the user moved it (until
    /// then the scene's own camera, bit for bit, so the view matches `render`).
    fn frame_scene(&self) -> Scene {
        let mut scene = self.state.scene.clone();
        if self.state.orbit != Orbit::from_camera(&scene.camera) {
            self.state.orbit.apply(&mut scene.camera);
        }
        scene
    }

    /// Brings the particles to the current time and emitter settings.
    fn update_particles(&mut self) {
        let s = &self.state.scene;
        let inputs = (s.emitter.clone(), s.wind.clone(), s.sim.step_s);
        if inputs != self.sim_inputs {
            self.sim = Simulation::new(s);
            self.sim_inputs = inputs;
        }
        if (self.sim.time_s() - self.state.time_s).abs() > s.sim.step_s * 0.5
            || self.particles.is_empty() && self.sim.time_s() > 0.0
        {
            self.sim.advance_to(self.state.time_s);
        }
        let state = (self.frame_scene(), self.state.spherical, self.state.time_s);
        if self.last_frame_state.as_ref() != Some(&state) {
            self.particles = Arc::new(self.sim.particles());
            self.last_frame_state = Some(state);
            self.revision += 1;
            self.last_change = Instant::now();
        }
    }

    /// Renders A (and B when the mode shows it) if anything changed.
    fn render_views(&mut self, viewport_px: (u32, u32)) {
        let (Some(gpu), Some(rs)) = (self.gpu.clone(), self.render_state.clone()) else {
            return;
        };
        let scene = self.frame_scene();
        let full = if self.state.fit_window {
            (viewport_px.0.clamp(16, 8192), viewport_px.1.clamp(16, 8192))
        } else {
            (scene.output.width_px, scene.output.height_px)
        };
        let size = if self.reduced {
            ((full.0 / 2).max(8), (full.1 / 2).max(8))
        } else {
            full
        };
        let options = RenderOptions {
            spherical: self.state.spherical,
            reuse_shadow_maps: true,
        };
        let sides = [self.state.a.clone(), self.state.b.clone()];
        let mut error = None;
        for (i, side) in sides.iter().enumerate() {
            if i == 1 && !self.state.mode.shows_b() {
                continue;
            }
            let config = self.config(side);
            if renders_on_worker(&config) {
                self.request_worker_view(i, config, size, &scene);
                continue;
            }
            let view = match &mut self.views[i] {
                Some(view) => {
                    if let Err(err) = view.set_config(&gpu, &config) {
                        error = Some(format!("{}: {err}", ["A", "B"][i]));
                    }
                    view
                }
                slot => match View::new(&gpu, &rs, &config, size) {
                    Ok(view) => slot.insert(view),
                    Err(err) => {
                        error = Some(format!("{}: {err}", ["A", "B"][i]));
                        continue;
                    }
                },
            };
            match view.render(
                &gpu,
                &rs,
                &scene,
                &self.particles,
                &options,
                self.revision,
                size,
            ) {
                Ok(true) if i == 0 => {
                    self.frames_rendered += 1;
                    self.last_render = Some(Instant::now());
                }
                Ok(_) => {}
                Err(err) => error = Some(format!("{}: {err}", ["A", "B"][i])),
            }
        }
        self.technique_error = error;
        if let Some(view) = &mut self.views[0]
            && let Some(times) = view.poll_times(&gpu)
        {
            self.times.add(&times);
        }
    }

    /// Asks the worker for side `i` unless it shows, or is rendering, this very frame.
    fn request_worker_view(
        &mut self,
        i: usize,
        config: TechniqueConfig,
        size: (u32, u32),
        scene: &Scene,
    ) {
        let Some(analysis) = &self.analysis else {
            return;
        };
        let key = WorkerKey {
            revision: self.revision,
            size,
            config,
        };
        let view = &mut self.worker_views[i];
        if view.shown.as_ref().is_some_and(|(k, _, _)| *k == key)
            || view.pending.as_ref().is_some_and(|(_, k)| *k == key)
        {
            return;
        }
        let mut scene = scene.clone();
        scene.output.width_px = size.0;
        scene.output.height_px = size.1;
        self.next_request += 1;
        analysis.send(Request::Render {
            id: self.next_request,
            side: i as u8,
            frame: Frame {
                scene,
                particles: self.particles.clone(),
                options: RenderOptions {
                    spherical: self.state.spherical,
                    ..RenderOptions::default()
                },
            },
            config: key.config.clone(),
        });
        view.pending = Some((self.next_request, key));
    }

    /// The texture side `i` shows now.
    fn side_texture(&self, i: usize) -> Option<egui::TextureId> {
        let side = if i == 0 { &self.state.a } else { &self.state.b };
        if renders_on_worker(&self.config(side)) {
            self.worker_views[i].shown.as_ref().map(|(_, t, _)| t.id())
        } else {
            self.views[i].as_ref().map(|v| v.texture_id)
        }
    }

    /// Handles what the worker sent back.
    fn receive(&mut self, ctx: &egui::Context) {
        let Some(analysis) = &self.analysis else {
            return;
        };
        while let Some(reply) = analysis.try_recv() {
            match reply {
                Reply::Compare {
                    id,
                    image_a,
                    a_vs_exact,
                    b_vs_a,
                    seconds,
                } => {
                    let b = b_vs_a.map(|boxed| {
                        let (metrics, x4, heat) = *boxed;
                        let load = |name: &str, image: image::RgbImage| {
                            let size = [image.width() as usize, image.height() as usize];
                            ctx.load_texture(
                                name,
                                egui::ColorImage::from_rgb(size, image.as_raw()),
                                egui::TextureOptions::LINEAR,
                            )
                        };
                        (
                            metrics,
                            load("viewer.difference", x4),
                            load("viewer.flip", heat),
                        )
                    });
                    if let Some(i) = self.requested.iter().position(|(r, _)| *r == id) {
                        let (_, key) = self.requested.remove(i);
                        // Answers to older requests were superseded and never come.
                        self.requested.retain(|(r, _)| *r > id);
                        self.analysed = Some(Analysed {
                            key,
                            image_a,
                            a_vs_exact,
                            seconds,
                            b,
                        });
                    }
                }
                Reply::Probe {
                    point,
                    point_distance_m,
                    series,
                    ..
                } => {
                    self.probe = Some(Probed {
                        point,
                        point_distance_m,
                        series,
                    });
                }
                Reply::Render { id, image, bytes } => {
                    for (i, view) in self.worker_views.iter_mut().enumerate() {
                        if view.pending.as_ref().is_some_and(|(r, _)| *r == id) {
                            let (_, key) = view.pending.take().expect("pending");
                            let size = [image.width() as usize, image.height() as usize];
                            let texture = ctx.load_texture(
                                format!("viewer.side{i}"),
                                egui::ColorImage::from_rgb(size, image.as_raw()),
                                egui::TextureOptions::LINEAR,
                            );
                            view.shown = Some((key, texture, bytes));
                        }
                    }
                }
                Reply::Screenshot { path } => {
                    self.status = format!("saved {}", path.display());
                }
                Reply::Error(err) => self.status = format!("analysis failed: {err}"),
            }
        }
    }

    /// Asks the worker for the error against `exact` (and the A/B comparison) once the view
    /// has settled.
    fn request_analysis(&mut self, force: bool) {
        let Some(analysis) = &self.analysis else {
            return;
        };
        let key = self.analysis_key();
        let settled = self.last_change.elapsed() >= SETTLE && !self.state.playing && !self.reduced;
        let asked = self.requested.last().map(|(_, k)| k) == Some(&key)
            || self.requested.is_empty() && self.analysed.as_ref().is_some_and(|a| a.key == key);
        if !(force || settled && !asked) {
            return;
        }
        let mut scene = self.frame_scene();
        if self.state.fit_window
            && let Some((w, h)) = self.view_a_size()
        {
            scene.output.width_px = w;
            scene.output.height_px = h;
        }
        let frame = Frame {
            scene,
            particles: self.particles.clone(),
            options: RenderOptions {
                spherical: self.state.spherical,
                ..RenderOptions::default()
            },
        };
        let exact = self.config(&Side {
            source: Source::Exact,
            technique: String::new(),
            channels: 1,
        });
        self.next_request += 1;
        analysis.send(Request::Compare {
            id: self.next_request,
            frame,
            a: key.a.clone(),
            b: key.b.clone(),
            exact,
        });
        self.requested.push((self.next_request, key));
    }

    /// T along the light ray through the point under `uv` (0..1 across the image).
    fn request_probe(&mut self, uv: Vec2) {
        let Some(analysis) = &self.analysis else {
            return;
        };
        let scene = self.frame_scene();
        let (w, h) = (scene.output.width_px, scene.output.height_px);
        let camera = crate::render::CameraMatrices::new(&scene, w, h);
        let ndc = glam::Vec2::new(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
        let far = camera
            .clip_from_world()
            .inverse()
            .project_point3(ndc.extend(1.0));
        let dir = (far - camera.position).normalize();
        let point = crate::render::shaded::first_opaque_hit(&scene, camera.position, dir)
            .map(|(p, _)| p)
            .unwrap_or_else(|| {
                // No surface: the point of the ray nearest the smoke's centre.
                let n = self.particles.len().max(1) as f32;
                let centre = self.particles.iter().map(|p| p.position).sum::<Vec3>() / n;
                camera.position + dir * (centre - camera.position).dot(dir).max(0.0)
            });
        let a = self.config(&self.state.a);
        let mut configs = vec![a.clone()];
        for entry in shadow::contenders() {
            let name = entry.name;
            let channels = a.params.channels.max(entry.min_channels);
            if name != a.name {
                configs.push(TechniqueConfig {
                    name: name.to_owned(),
                    params: self.state.scene.shadow.params(channels),
                });
            }
        }
        configs.push(self.config(&Side {
            source: Source::Exact,
            technique: String::new(),
            channels: 1,
        }));
        self.next_request += 1;
        analysis.send(Request::Probe {
            id: self.next_request,
            frame: Frame {
                scene,
                particles: self.particles.clone(),
                options: RenderOptions {
                    spherical: self.state.spherical,
                    ..RenderOptions::default()
                },
            },
            configs,
            point,
            samples: 96,
        });
        self.status = format!(
            "probing T along the light ray through ({:.2}, {:.2}, {:.2})",
            point.x, point.y, point.z
        );
    }

    /// Saves view A at the scene's full size (rendered by the worker, the CLI's path).
    fn save_viewport(&mut self) {
        let Some(analysis) = &self.analysis else {
            return;
        };
        let config = self.config(&self.state.a);
        let path = PathBuf::from(format!(
            "smokeshadow-{}-{}.png",
            config.name, config.params.channels
        ));
        analysis.send(Request::Screenshot {
            frame: Frame {
                scene: self.frame_scene(),
                particles: self.particles.clone(),
                options: RenderOptions {
                    spherical: self.state.spherical,
                    ..RenderOptions::default()
                },
            },
            config,
            path: path.clone(),
        });
        self.status = format!("saving {} ...", path.display());
    }

    fn save_window(&mut self, ctx: &egui::Context) {
        let slot = self.window_shot.clone();
        let repaint = ctx.clone();
        ctx.request_screenshot(move |image| {
            *slot.lock().expect("screenshot slot") = Some(image);
            repaint.request_repaint();
        });
        self.status = "saving the window ...".to_owned();
    }

    fn write_window_shot(&mut self) {
        let shot = self.window_shot.lock().expect("screenshot slot").take();
        if let Some(image) = shot {
            let path = PathBuf::from("smokeshadow-window.png");
            let rgba = image::RgbaImage::from_raw(
                image.size[0] as u32,
                image.size[1] as u32,
                image.pixels.iter().flat_map(|c| c.to_array()).collect(),
            );
            self.status = match rgba.map(|rgba| crate::output::write_png(&path, &rgba)) {
                Some(Ok(())) => format!("saved {}", path.display()),
                Some(Err(err)) => format!("{err:#}"),
                None => "the screenshot had an unexpected size".to_owned(),
            };
        }
    }

    /// Keyboard shortcuts (ignored while a text field has the keyboard).
    fn shortcuts(&mut self, ctx: &egui::Context) {
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        let pressed = |key| ctx.input(|i| i.key_pressed(key));
        for (mode, _, key) in CompareMode::ALL {
            if pressed(key) {
                self.state.mode = mode;
            }
        }
        if pressed(Key::Space) {
            self.state.playing = !self.state.playing;
        }
        if pressed(Key::H) || pressed(Key::F1) {
            self.state.show_help = !self.state.show_help;
        }
        if pressed(Key::R) {
            self.state.orbit = Orbit::from_camera(&self.loaded_scene.camera);
        }
        if pressed(Key::OpenBracket) || pressed(Key::CloseBracket) {
            let entry = shadow::find(&self.state.a.technique).expect("registered");
            let c = &mut self.state.a.channels;
            *c = if pressed(Key::OpenBracket) {
                c.saturating_sub(1)
            } else {
                *c + 1
            }
            .clamp(entry.min_channels, shadow::MAX_CHANNELS);
        }
        if pressed(Key::T) {
            let names = comparable_techniques();
            let i = names
                .iter()
                .position(|n| *n == self.state.a.technique)
                .unwrap_or(0);
            self.state.a.technique = names[(i + 1) % names.len()].to_owned();
            clamp_channels(&mut self.state.a);
        }
        if pressed(Key::E) {
            self.request_analysis(true);
        }
        let save_window = egui::KeyboardShortcut::new(egui::Modifiers::COMMAND, Key::S);
        if ctx.input_mut(|i| i.consume_shortcut(&save_window)) {
            self.save_window(ctx);
        } else if pressed(Key::S) {
            self.save_viewport();
        }
    }
}

/// Whether a configuration is rendered on the analysis worker instead of the UI thread.
fn renders_on_worker(config: &TechniqueConfig) -> bool {
    shadow::find(&config.name).is_ok_and(|e| e.build_reads_back)
}

/// Techniques a side can pick (everything but `none`, which the numbers use as a baseline).
fn comparable_techniques() -> Vec<&'static str> {
    shadow::contenders().map(|e| e.name).collect()
}

fn clamp_channels(side: &mut Side) {
    let entry = shadow::find(&side.technique).expect("registered");
    side.channels = side
        .channels
        .clamp(entry.min_channels, shadow::MAX_CHANNELS);
}

/// What a budget means for a technique, for the slider's caption.
pub fn budget_meaning(technique: &str, channels: u32) -> String {
    match shadow::find(technique) {
        Ok(entry) if entry.role == shadow::Role::Contender => (entry.budget_caption)(channels),
        _ => String::new(),
    }
}

impl eframe::App for ViewerApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        let dt = ctx.input(|i| i.stable_dt).min(0.1);
        self.ui_frame_ms = 0.9 * self.ui_frame_ms + 0.1 * f64::from(dt) * 1e3;
        self.receive(&ctx);
        self.write_window_shot();
        self.shortcuts(&ctx);
        if self.state.playing {
            let end = self.state.scene.sim.duration_s.max(20.0);
            self.state.time_s += dt;
            if self.state.time_s > end {
                self.state.time_s = 0.0;
            }
        }
        if self.gpu.is_none() {
            egui::CentralPanel::default().show(ui, |ui| {
                ui.colored_label(
                    Color32::RED,
                    "This window has no wgpu renderer: the viewer needs a Vulkan, Metal or DX12 adapter (on a machine without a GPU, Mesa's lavapipe: `apt-get install mesa-vulkan-drivers libvulkan1`).",
                );
            });
            return;
        }

        egui::Panel::left("compare")
            .resizable(false)
            .default_size(300.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.compare_panel(ui));
            });
        egui::Panel::right("scene")
            .resizable(false)
            .default_size(320.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.scene_panel(ui));
            });
        egui::Panel::bottom("time").show(ui, |ui| self.time_bar(ui));
        let mut viewport_px = (0, 0);
        let mut interacting = self.state.playing;
        egui::CentralPanel::default().show(ui, |ui| {
            let (px, dragging) = self.viewport(ui);
            viewport_px = px;
            interacting |= dragging;
        });
        interacting |= ctx.dragged_id().is_some();

        // Half resolution while the user drags or plays; full once the view has settled.
        self.update_particles();
        let settled = self.last_change.elapsed() >= SETTLE;
        let reduced = interacting || (self.reduced && !settled);
        if reduced != self.reduced {
            self.reduced = reduced;
            self.revision += 1;
        }
        self.render_views(viewport_px);
        self.request_analysis(false);
        self.draw_inspector();
        if self.state.show_help {
            self.help_window(&ctx);
        }
        let busy = self.analysis.as_ref().is_some_and(Analysis::busy);
        if self.state.playing || interacting {
            ctx.request_repaint();
        } else if self.reduced || busy || !self.settled() {
            ctx.request_repaint_after(Duration::from_millis(60));
        }
    }
}

impl ViewerApp {
    /// Left panel: the comparison (mode, A, B), shared technique settings, the numbers.
    fn compare_panel(&mut self, ui: &mut egui::Ui) {
        ui.heading("Compare");
        ui.horizontal_wrapped(|ui| {
            for (mode, label, _) in CompareMode::ALL {
                ui.radio_value(&mut self.state.mode, mode, label);
            }
        });
        if self.state.mode == CompareMode::Split {
            ui.add(egui::Slider::new(&mut self.state.split, 0.0..=1.0).text("Divider"));
        }
        ui.separator();
        for (i, label) in ["A", "B"].iter().enumerate() {
            let side = if i == 0 {
                &mut self.state.a
            } else {
                &mut self.state.b
            };
            side_editor(ui, label, side);
            ui.separator();
        }
        if let Some(err) = &self.technique_error {
            ui.colored_label(Color32::RED, err);
        }

        ui.heading("Shadow settings");
        let shadow = &mut self.state.scene.shadow;
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
            ui.radio_value(&mut shadow.splat, SplatMode::Point, "point (thesis)");
            ui.radio_value(&mut shadow.splat, SplatMode::Segment, "segment");
        });
        // Every technique parameter the registry declares: a slider over its range, and for one
        // whose default is derived per frame, a checkbox that fixes it.
        for (_, spec) in shadow::all_params() {
            let range = spec.min..=spec.max;
            let text = format!("{} ({})", spec.key, spec.unit);
            let logarithmic = spec.max / spec.min.max(1e-6) > 100.0;
            match spec.default {
                Some(default) => {
                    let value = shadow.params.entry(spec.key.to_owned()).or_insert(default);
                    ui.add(
                        egui::Slider::new(value, range)
                            .logarithmic(logarithmic)
                            .text(text),
                    )
                    .on_hover_text(spec.doc);
                    if *value == default {
                        // Unset and default are the same setting: keep the scene canonical.
                        shadow.params.remove(spec.key);
                    }
                }
                None => {
                    let mut fixed = shadow.params.contains_key(spec.key);
                    ui.checkbox(&mut fixed, format!("fixed {}", spec.key))
                        .on_hover_text(spec.doc);
                    if fixed {
                        let value = shadow
                            .params
                            .entry(spec.key.to_owned())
                            .or_insert(spec.min.max(1.0).min(spec.max));
                        ui.add(
                            egui::Slider::new(value, range)
                                .logarithmic(logarithmic)
                                .text(text),
                        );
                    } else {
                        shadow.params.remove(spec.key);
                    }
                }
            }
        }
        ui.checkbox(&mut self.state.spherical, "Spherical billboards");
        ui.checkbox(&mut self.state.fit_window, "Render at window size");
        ui.add(
            egui::Slider::new(&mut self.state.scene.shading.exposure, 0.1..=8.0)
                .logarithmic(true)
                .text("Exposure"),
        );
        ui.separator();
        self.numbers(ui);
    }

    /// GPU times, bytes and the live error.
    fn numbers(&mut self, ui: &mut egui::Ui) {
        ui.heading("Numbers");
        if let Some((key, _, bytes)) = &self.worker_views[0].shown
            && renders_on_worker(&self.config(&self.state.a))
        {
            ui.label(format!(
                "A: exact at {} px, rendered on the worker; {} of lists",
                format_size(key.size.0, key.size.1),
                crate::report::bytes(*bytes)
            ));
            return;
        }
        let Some(view) = &self.views[0] else {
            return;
        };
        let (w, h) = view.size();
        ui.label(format!(
            "A: {} at {} px{}",
            view.config().name,
            format_size(w, h),
            if self.reduced {
                " (reduced while moving)"
            } else {
                ""
            }
        ));
        let hide = self.hide_timings;
        let ms = |v: f64, digits: usize| {
            if hide {
                "—".to_owned()
            } else {
                format!("{v:.digits$} ms")
            }
        };
        egui::Grid::new("numbers").striped(true).show(ui, |ui| {
            for (name, t) in &self.times.passes {
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
            ui.label(ms(self.times.frame_ms, 2));
            ui.end_row();
            if let Some(stats) = &view.stats {
                ui.label("CPU sort");
                ui.label(ms(stats.sort_ms, 3));
                ui.end_row();
            }
            ui.label("UI frame");
            ui.label(ms(self.ui_frame_ms, 1));
            ui.end_row();
            let memory = view.renderer().technique().memory();
            ui.label("Shadow memory");
            ui.label(crate::report::bytes(memory.total_bytes()))
                .on_hover_text(
                    memory
                        .entries()
                        .iter()
                        .map(|(l, b)| format!("{l}: {b} bytes"))
                        .collect::<Vec<_>>()
                        .join("\n"),
                );
            ui.end_row();
            if let Some(b) = &self.views[1]
                && self.state.mode.shows_b()
            {
                ui.label("B memory");
                ui.label(crate::report::bytes(
                    b.renderer().technique().memory().total_bytes(),
                ));
                ui.end_row();
            }
        });
        ui.add_space(4.0);
        match &self.analysed {
            Some(a) => {
                let stale = a.key != self.analysis_key();
                ui.label(format!(
                    "A vs exact: FLIP {:.4}, RMSE {:.4}{}",
                    a.a_vs_exact.flip_mean,
                    a.a_vs_exact.rmse_srgb,
                    if stale { " (updating)" } else { "" }
                ))
                .on_hover_text(format!("measured at full resolution in {:.2} s", a.seconds));
                if let Some((m, _, _)) = &a.b {
                    ui.label(format!(
                        "B vs A: FLIP {:.4}, RMSE {:.4}",
                        m.flip_mean, m.rmse_srgb
                    ));
                }
            }
            None => {
                ui.label("A vs exact: measuring when the view settles");
            }
        }
        if ui.button("Measure now (E)").clicked() {
            self.request_analysis(true);
        }
    }

    /// Right panel: scene, light, inspector and probe.
    fn scene_panel(&mut self, ui: &mut egui::Ui) {
        ui.heading("Scene");
        ui.horizontal(|ui| {
            let label = ui.label("File");
            ui.text_edit_singleline(&mut self.scene_path)
                .labelled_by(label.id);
        });
        ui.horizontal(|ui| {
            if ui.button("Load").clicked() {
                self.load_scene();
            }
            if ui.button("Save").clicked() {
                let path = PathBuf::from(&self.scene_path);
                let mut scene = self.frame_scene();
                scene.sim.duration_s = self.state.time_s;
                self.status = match crate::output::write_atomic(&path, scene.to_toml().as_bytes()) {
                    Ok(()) => format!("saved {}", path.display()),
                    Err(err) => format!("{err:#}"),
                };
            }
            if ui.button("Thesis scene").clicked() {
                self.set_scene(Scene::thesis_plume());
            }
            if ui.button("Reset camera").clicked() {
                self.state.orbit = Orbit::from_camera(&self.loaded_scene.camera);
            }
        });
        if let Some(err) = &self.scene_error {
            ui.colored_label(Color32::RED, err);
        }
        let before = self.state.scene.clone();
        {
            let s = &mut self.state.scene;
            let e = &mut s.emitter;
            egui::CollapsingHeader::new("Emitter")
                .default_open(true)
                .show(ui, |ui| {
                    egui::Grid::new("emitter").show(ui, |ui| {
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
            egui::CollapsingHeader::new("Spotlight").show(ui, |ui| {
                egui::Grid::new("light").show(ui, |ui| {
                    drag(ui, "Position x", &mut l.position.x, 0.05, -100.0..=100.0);
                    drag(ui, "Position y", &mut l.position.y, 0.05, -100.0..=100.0);
                    drag(ui, "Position z", &mut l.position.z, 0.05, -100.0..=100.0);
                    drag(ui, "Target x", &mut l.target.x, 0.05, -100.0..=100.0);
                    drag(ui, "Target y", &mut l.target.y, 0.05, -100.0..=100.0);
                    drag(ui, "Target z", &mut l.target.z, 0.05, -100.0..=100.0);
                    drag(ui, "Cone (deg)", &mut l.cone_angle_deg, 0.2, 1.0..=79.0);
                    drag(ui, "Intensity", &mut l.intensity, 1.0, 0.0..=1e5);
                });
                ui.label("In the view: drag the yellow ring to aim the light; shift-drag moves the light around its target.");
            });
        }
        if self.state.scene != before {
            match self.state.scene.validate() {
                Ok(()) => {
                    self.valid_scene = self.state.scene.clone();
                    self.scene_error = None;
                }
                Err(message) => {
                    self.scene_error = Some(message);
                    self.state.scene = self.valid_scene.clone();
                }
            }
        }
        ui.separator();
        self.inspector_ui(ui);
        ui.separator();
        self.probe_ui(ui);
    }

    /// Loads the scene named in the path field; on an error the current scene stays.
    fn load_scene(&mut self) {
        match Scene::load(std::path::Path::new(&self.scene_path)) {
            Ok(scene) => {
                self.set_scene(scene);
                self.status = format!("loaded {}", self.scene_path);
            }
            Err(err) => self.scene_error = Some(err.to_string()),
        }
    }

    fn set_scene(&mut self, scene: Scene) {
        self.state.orbit = Orbit::from_camera(&scene.camera);
        self.state.time_s = scene.sim.duration_s;
        self.loaded_scene = scene.clone();
        self.valid_scene = scene.clone();
        self.state.scene = scene;
        self.scene_error = None;
    }

    /// The inspector: A's shadow maps, one channel at a time.
    fn inspector_ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Inspector: A's shadow maps")
            .default_open(true)
            .show(ui, |ui| {
                let Some(view) = &self.views[0] else {
                    return;
                };
                let channels = inspect_channels(view);
                if channels.is_empty() {
                    ui.label(format!(
                        "{} keeps no maps to show (exact stores per-texel segment lists).",
                        view.config().name
                    ));
                    return;
                }
                self.state.inspect_channel = self.state.inspect_channel.min(channels.len() - 1);
                ui.horizontal(|ui| {
                    let label = ui.label("Channel");
                    egui::ComboBox::from_id_salt("inspect_channel")
                        .selected_text(channels[self.state.inspect_channel].2.clone())
                        .width(220.0)
                        .show_ui(ui, |ui| {
                            for (i, (_, _, name, _)) in channels.iter().enumerate() {
                                ui.selectable_value(&mut self.state.inspect_channel, i, name);
                            }
                        })
                        .response
                        .labelled_by(label.id);
                });
                ui.add(
                    egui::Slider::new(&mut self.state.inspect_scale, 0.01..=100.0)
                        .logarithmic(true)
                        .text("Scale"),
                );
                if let Some(inspector) = &self.inspector {
                    ui.image((inspector.texture_id, Vec2::splat(INSPECTOR_PX as f32)));
                }
            });
    }

    /// Draws the selected channel into the inspector image when it or A changed.
    fn draw_inspector(&mut self) {
        if renders_on_worker(&self.config(&self.state.a)) {
            return;
        }
        let (Some(gpu), Some(view), Some(inspector)) =
            (&self.gpu, &self.views[0], &mut self.inspector)
        else {
            return;
        };
        let channels = inspect_channels(view);
        let Some(&(map, component, _, kind)) = channels.get(self.state.inspect_channel) else {
            return;
        };
        let key = (
            self.revision,
            self.state.inspect_channel,
            self.state.inspect_scale.to_bits(),
        );
        if inspector.drawn == Some(key) {
            return;
        }
        let maps = view.renderer().technique().debug_maps();
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("viewer.inspector"),
            });
        inspector.map_view.draw(
            &gpu.device,
            &gpu.queue,
            &mut encoder,
            maps[map].view,
            component,
            kind,
            self.state.inspect_scale,
            &inspector.render_view,
        );
        gpu.queue.submit([encoder.finish()]);
        inspector.drawn = Some(key);
    }

    /// The transmittance probe's plot.
    fn probe_ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Transmittance probe").default_open(true).show(ui, |ui| {
            ui.label("Click the view: T along the light ray through that point, for A's technique, the others at its budget, and exact.");
            let Some(probe) = &self.probe else {
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

    /// Bottom bar: time, play, screenshots, status.
    fn time_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            let label = if self.state.playing { "Pause" } else { "Play" };
            if ui.button(label).clicked() {
                self.state.playing = !self.state.playing;
            }
            let end = self.state.scene.sim.duration_s.max(20.0);
            ui.add(egui::Slider::new(&mut self.state.time_s, 0.0..=end).text("Time (s)"));
            let wind = &self.state.scene.wind;
            if wind.strength_m_per_s > 0.0 {
                ui.label(format!("wind gust at {:.1} s", wind.start_s));
            }
            if ui.button("Save view PNG (S)").clicked() {
                self.save_viewport();
            }
            if ui.button("Save window PNG (Ctrl+S)").clicked() {
                let ctx = ui.ctx().clone();
                self.save_window(&ctx);
            }
            if ui.button("Help (H)").clicked() {
                self.state.show_help = !self.state.show_help;
            }
            ui.label(&self.status);
        });
    }

    /// The viewport: the images of the current mode and the camera/light/probe interactions.
    /// Returns the image's size in physical pixels and whether the user is dragging in it.
    fn viewport(&mut self, ui: &mut egui::Ui) -> ((u32, u32), bool) {
        let available = ui.available_size();
        let (full_w, full_h) = (
            self.state.scene.output.width_px as f32,
            self.state.scene.output.height_px as f32,
        );
        let aspect = if self.state.fit_window {
            available.x / available.y.max(1.0)
        } else {
            full_w / full_h
        };
        let side_by_side = self.state.mode == CompareMode::SideBySide;
        let slot = if side_by_side {
            Vec2::new(available.x * 0.5, available.y)
        } else {
            available
        };
        let size = if slot.x / slot.y.max(1.0) > aspect {
            Vec2::new(slot.y * aspect, slot.y)
        } else {
            Vec2::new(slot.x, slot.x / aspect)
        };
        let total = if side_by_side {
            Vec2::new(size.x * 2.0, size.y)
        } else {
            size
        };
        let (rect, response) = ui.allocate_exact_size(total, egui::Sense::click_and_drag());
        let image_rect = Rect::from_min_size(rect.min, size);
        let ppp = ui.ctx().pixels_per_point();
        let px = ((size.x * ppp) as u32, (size.y * ppp) as u32);

        let whole = Rect::from_min_max(pos2(0.0, 0.0), pos2(1.0, 1.0));
        let painter = ui.painter_at(rect);
        let id = |i: usize| self.side_texture(i);
        match self.state.mode {
            CompareMode::Single => {
                if let Some(a) = id(0) {
                    painter.image(a, image_rect, whole, Color32::WHITE);
                }
            }
            CompareMode::Split => {
                let x = image_rect.left() + image_rect.width() * self.state.split;
                if let Some(a) = id(0) {
                    painter.image(
                        a,
                        Rect::from_min_max(image_rect.min, pos2(x, image_rect.max.y)),
                        Rect::from_min_max(pos2(0.0, 0.0), pos2(self.state.split, 1.0)),
                        Color32::WHITE,
                    );
                }
                if let Some(b) = id(1) {
                    painter.image(
                        b,
                        Rect::from_min_max(pos2(x, image_rect.min.y), image_rect.max),
                        Rect::from_min_max(pos2(self.state.split, 0.0), pos2(1.0, 1.0)),
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
                let show_b =
                    ui.input(|i| i.key_down(Key::B)) && !ui.ctx().egui_wants_keyboard_input();
                if let Some(t) = id(usize::from(show_b)) {
                    painter.image(t, image_rect, whole, Color32::WHITE);
                }
                if show_b {
                    ui.ctx().request_repaint();
                }
            }
            CompareMode::Difference | CompareMode::FlipMap => {
                let picture =
                    self.analysed
                        .as_ref()
                        .and_then(|a| a.b.as_ref())
                        .map(|(m, x4, heat)| {
                            if self.state.mode == CompareMode::Difference {
                                (x4.id(), m)
                            } else {
                                (heat.id(), m)
                            }
                        });
                match picture {
                    Some((texture, _)) => {
                        painter.image(texture, image_rect, whole, Color32::WHITE);
                    }
                    None => {
                        if let Some(a) = id(0) {
                            painter.image(a, image_rect, whole, Color32::from_gray(90));
                        }
                    }
                }
            }
        }
        // Labels in the corners.
        let label = |side: &Side| match side.source {
            Source::Technique => format!("{} {} ch", side.technique, side.channels),
            Source::Baseline24 => format!("{} 24 ch (baseline)", side.technique),
            Source::Exact => shadow::reference().name.to_owned(),
        };
        let text = match self.state.mode {
            CompareMode::Single | CompareMode::Flip => format!("A: {}", label(&self.state.a)),
            CompareMode::Difference | CompareMode::FlipMap => {
                let what = if self.state.mode == CompareMode::Difference {
                    "|A - B| x 4"
                } else {
                    "FLIP of B vs A"
                };
                let key = self.analysis_key();
                match self
                    .analysed
                    .as_ref()
                    .and_then(|a| a.b.as_ref().map(|(m, _, _)| (&a.key, m)))
                {
                    Some((measured, m)) => format!(
                        "{what}: A {} / B {}, FLIP mean {:.4}{}",
                        label(&self.state.a),
                        label(&self.state.b),
                        m.flip_mean,
                        if *measured != key { " (updating)" } else { "" }
                    ),
                    None => format!("{what}: computing ..."),
                }
            }
            _ => format!("A: {}    B: {}", label(&self.state.a), label(&self.state.b)),
        };
        painter.text(
            rect.left_top() + Vec2::new(8.0, 8.0),
            egui::Align2::LEFT_TOP,
            text,
            egui::FontId::proportional(15.0),
            Color32::WHITE,
        );

        // The spotlight's handle: where its axis meets the scene, and the axis towards the light.
        let scene = self.frame_scene();
        // (The camera's aspect is the image's, whatever size it renders at.)
        let (w, h) = (
            (image_rect.width().round() as u32).max(1),
            (image_rect.height().round() as u32).max(1),
        );
        let camera = crate::render::CameraMatrices::new(&scene, w, h);
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
        let mut dragging = false;
        let shift = ui.input(|i| i.modifiers.shift);
        if response.drag_started()
            && let Some(p) = response.interact_pointer_pos()
        {
            let x = image_rect.left() + image_rect.width() * self.state.split;
            self.dragging_divider = self.state.mode == CompareMode::Split && (p.x - x).abs() < 10.0;
            self.dragging_light_target =
                !self.dragging_divider && handle.is_some_and(|h| h.distance(p) < 12.0);
        }
        if response.dragged_by(PointerButton::Primary) {
            let d = response.drag_delta();
            if self.dragging_divider {
                self.state.split = (self.state.split + d.x / image_rect.width()).clamp(0.0, 1.0);
            } else if self.dragging_light_target
                && let Some(p) = response.interact_pointer_pos()
            {
                // Slide the target in its horizontal plane to where the pointer's ray meets it.
                let uv = (p - image_rect.min) / image_rect.size();
                let ndc = glam::Vec2::new(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
                let far = camera
                    .clip_from_world()
                    .inverse()
                    .project_point3(ndc.extend(1.0));
                let dir = (far - camera.position).normalize();
                let target = &mut self.state.scene.light.target;
                if dir.y.abs() > 1e-4 {
                    let t = (target.y - camera.position.y) / dir.y;
                    if t > 0.0 {
                        let hit = camera.position + dir * t;
                        *target = Vec3::new(hit.x, target.y, hit.z);
                    }
                }
            } else if shift {
                let light = &mut self.state.scene.light;
                let mut orbit = Orbit::from_camera(&crate::scene::Camera {
                    position: light.position,
                    target: light.target,
                    ..self.state.scene.camera.clone()
                });
                orbit.orbit(d.x, d.y);
                light.position = orbit.position();
            } else {
                self.state.orbit.orbit(d.x, d.y);
            }
            dragging = true;
        }
        if response.dragged_by(PointerButton::Secondary)
            || response.dragged_by(PointerButton::Middle)
        {
            let d = response.drag_delta();
            self.state.orbit.pan(
                d.x,
                d.y,
                image_rect.height(),
                self.state.scene.camera.fov_y_deg,
            );
            dragging = true;
        }
        if response.drag_stopped() {
            self.dragging_divider = false;
            self.dragging_light_target = false;
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.state.orbit.zoom(scroll / 50.0);
                dragging = true;
            }
            if let Some(p) = response.hover_pos()
                && image_rect.contains(p)
            {
                let uv = (p - image_rect.min) / image_rect.size();
                response
                    .clone()
                    .on_hover_text_at_pointer(self.pixel_readout(uv));
            }
        }
        if response.clicked()
            && let Some(p) = response.interact_pointer_pos()
        {
            let local = if side_by_side && p.x > image_rect.right() {
                p - Vec2::new(size.x, 0.0)
            } else {
                p
            };
            if image_rect.contains(local) {
                self.request_probe((local - image_rect.min) / image_rect.size());
            }
        }
        (px, dragging)
    }

    /// The pixel values under the cursor, from the worker's full-size image of A (once the
    /// view has settled and been measured).
    fn pixel_readout(&self, uv: Vec2) -> String {
        let key = self.analysis_key();
        let values = match self.analysed.as_ref().filter(|a| a.key == key) {
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

    fn help_window(&mut self, ctx: &egui::Context) {
        let mut open = true;
        egui::Window::new("Keyboard and mouse")
            .open(&mut open)
            .collapsible(false)
            .show(ctx, |ui| {
                egui::Grid::new("help").striped(true).show(ui, |ui| {
                    for (keys, what) in [
                        (
                            "1 .. 6",
                            "single, split, side by side, flip, difference x4, FLIP map",
                        ),
                        ("B (hold)", "show B in flip mode"),
                        ("Space", "play / pause the simulation"),
                        ("[  ]", "A: one channel fewer / more"),
                        ("T", "A: next technique"),
                        ("E", "measure A against exact now"),
                        ("S", "save A at full size as PNG"),
                        ("Ctrl+S", "save the whole window as PNG"),
                        ("R", "reset the camera"),
                        ("H, F1", "this help"),
                        ("drag", "orbit the camera (in split view, drag the divider)"),
                        ("right / middle drag", "pan"),
                        ("wheel", "zoom"),
                        ("drag the yellow ring", "move where the spotlight aims"),
                        ("shift + drag", "move the spotlight around its target"),
                        ("click", "probe T along the light ray through the point"),
                    ] {
                        ui.monospace(keys);
                        ui.label(what);
                        ui.end_row();
                    }
                });
            });
        if !open {
            self.state.show_help = false;
        }
    }
}

/// The inspectable channels of a view's technique: (map index, component, label, kind).
fn inspect_channels(view: &View) -> Vec<(usize, u32, String, MapKind)> {
    view.renderer()
        .technique()
        .debug_maps()
        .iter()
        .enumerate()
        .flat_map(|(m, map)| {
            map.channels
                .iter()
                .enumerate()
                .map(move |(c, name)| (m, c as u32, name.clone(), map.kind))
        })
        .collect()
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
            egui::Slider::new(
                &mut side.channels,
                entry.min_channels..=shadow::MAX_CHANNELS,
            )
            .text(format!("Channels {label}")),
        );
        ui.label(budget_meaning(&side.technique, side.channels));
    }
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

fn format_size(w: u32, h: u32) -> String {
    format!("{w}x{h}")
}
