//! The viewer's controller: what the user set ([`ViewState`]), what each control does to it
//! (pick a technique, a budget, a mode, a scene ...), and the bookkeeping that decides when to
//! render (only when something changed, at half resolution while the user drags, full
//! resolution when idle) and when to ask the analysis worker for numbers.
//!
//! It knows nothing of egui: the panels, the viewport and the shortcut table call it, and tests
//! drive it directly, with or without a GPU ([`Controller::new`] with `None` renders nothing).
//! What egui needs to show its pictures (texture ids, uploaded images) lives in
//! [`super::textures`], which mirrors the GPU outputs and worker images held here. A new
//! control adds a method here and calls it from its panel (and, if it has a key, from a row of
//! [`super::shortcuts::SHORTCUTS`]).

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use glam::{DVec3, Vec2, Vec3};

use super::analysis::{Analysis, Frame, ProbeSeries, Reply, Request};
use super::camera::Orbit;
use super::map_view::{MAP_VIEW_FORMAT, MapView};
use super::view::View;
use crate::diff::Metrics;
use smokeshadow_core::gpu::Gpu;
use smokeshadow_core::render::{
    CameraMatrices, ParticleRes, RenderOptions, SortOrder, TechniqueConfig,
};
use smokeshadow_core::scene::{Scene, VolumeSpec};
use smokeshadow_core::shadow::{self, MapKind};
use smokeshadow_core::sim::{Particle, Simulation};

/// How A and B are shown.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
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
    /// A's change from the frame before beside `exact`'s, and the difference of the two.
    Motion,
}

impl CompareMode {
    /// Every mode with its label (their keys are rows of [`super::shortcuts::SHORTCUTS`]).
    pub const ALL: [(CompareMode, &'static str); 7] = [
        (CompareMode::Single, "Single"),
        (CompareMode::Split, "Split"),
        (CompareMode::SideBySide, "Side by side"),
        (CompareMode::Flip, "Flip (hold B)"),
        (CompareMode::Difference, "Difference x4"),
        (CompareMode::FlipMap, "FLIP map"),
        (CompareMode::Motion, "Change vs exact"),
    ];

    /// Whether B is rendered in this mode.
    pub fn shows_b(self) -> bool {
        !matches!(self, CompareMode::Single | CompareMode::Motion)
    }

    /// Whether the picture comes from the analysis worker (A and B read back and compared).
    pub fn analysed(self) -> bool {
        matches!(
            self,
            CompareMode::Difference | CompareMode::FlipMap | CompareMode::Motion
        )
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

impl Side {
    /// The side's caption in the viewport's corner.
    pub fn label(&self) -> String {
        match self.source {
            Source::Technique => format!("{} {} ch", self.technique, self.channels),
            Source::Baseline24 => format!("{} 24 ch (baseline)", self.technique),
            Source::Exact => shadow::reference().name.to_owned(),
        }
    }
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
    /// The particle pass's resolution (mixed-resolution particles).
    pub particle_res: ParticleRes,
    /// The order of the frame's one sort (view depth, or the half-angle shared with `has`).
    pub sort: SortOrder,
    /// `view --animate`: play the animated sweep's frames, one a UI frame, looping over the
    /// span (else play in real time from 0 to the scene's time, or 20 s).
    pub span: Option<smokeshadow_core::motion::Span>,
    /// Render at the viewport's size instead of the scene's output size.
    pub fit_window: bool,
    /// Inspector: the selected map channel (index into the flattened list) and its scale.
    pub inspect_channel: usize,
    pub inspect_scale: f32,
    pub show_help: bool,
}

/// What a measurement is of: the frame's revision and the configurations compared.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct AnalysisKey {
    revision: u64,
    a: TechniqueConfig,
    b: Option<TechniqueConfig>,
    /// With A's change: the time between the two frames.
    motion: Option<f32>,
}

/// B measured against A, and the two pictures of their difference.
pub(super) struct Comparison {
    pub(super) metrics: Metrics,
    /// |A − B| × 4.
    pub(super) difference_x4: image::RgbImage,
    /// The FLIP error map as a heat map.
    pub(super) flip_heat: image::RgbImage,
}

/// What the worker last measured, and of what.
pub(super) struct Analysed {
    /// The request it answered (the UI's textures of it are keyed by this).
    pub(super) id: u64,
    pub(super) key: AnalysisKey,
    /// A as the worker rendered it (full size), for the cursor's pixel values.
    pub(super) image_a: image::RgbImage,
    pub(super) a_vs_exact: Metrics,
    pub(super) seconds: f64,
    pub(super) b: Option<Comparison>,
    /// A's change beside `exact`'s (the temporal compare) and the earlier frame's time.
    pub(super) motion: Option<(smokeshadow_core::motion::ChangePictures, f32)>,
}

/// The last probe's curves.
pub(super) struct Probed {
    pub(super) point: Vec3,
    pub(super) point_distance_m: f32,
    pub(super) series: Vec<ProbeSeries>,
}

/// What a side rendered by the worker shows.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct WorkerKey {
    revision: u64,
    pub(super) size: (u32, u32),
    config: TechniqueConfig,
}

/// A frame the worker rendered for a side.
pub(super) struct WorkerImage {
    /// The request it answered (the UI's texture of it is keyed by this).
    pub(super) id: u64,
    pub(super) key: WorkerKey,
    pub(super) image: image::RgbImage,
    /// Bytes of the technique's lists.
    pub(super) bytes: u64,
}

/// A side shown through the analysis worker: `exact`, whose build reads its list sizes back
/// from the GPU, which the UI thread never waits for.
#[derive(Default)]
pub(super) struct WorkerView {
    pub(super) shown: Option<WorkerImage>,
    pending: Option<(u64, WorkerKey)>,
}

/// GPU pass times, smoothed over the frames that ran them (the shadow build is skipped while
/// only the camera moves, so its figure is that of the last build), and the frame total.
#[derive(Default)]
pub(super) struct Smoothed {
    pub(super) passes: Vec<(&'static str, f64)>,
    pub(super) frame_ms: f64,
}

impl Smoothed {
    fn add(&mut self, times: &smokeshadow_core::gpu::PassTimes) {
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

/// The inspector's image target: drawn here, shown by the UI through `display_view`.
pub(super) struct Inspector {
    map_view: MapView,
    render_view: wgpu::TextureView,
    /// The `Rgba8Unorm` view the UI samples (it expects already-encoded values).
    pub(super) display_view: wgpu::TextureView,
    drawn: Option<(u64, usize, u32)>,
}

impl Inspector {
    fn new(device: &wgpu::Device) -> Self {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
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
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[wgpu::TextureFormat::Rgba8Unorm],
        });
        let display_view = texture.create_view(&wgpu::TextureViewDescriptor {
            format: Some(wgpu::TextureFormat::Rgba8Unorm),
            ..Default::default()
        });
        Self {
            map_view: MapView::new(device),
            render_view: texture.create_view(&Default::default()),
            display_view,
            drawn: None,
        }
    }
}

/// When the UI should draw its next frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Repaint {
    /// Right away: playing or being dragged.
    Now,
    /// Shortly: a full-resolution frame or a measurement is on its way.
    After(Duration),
    /// Only on input: nothing will change by itself.
    OnInput,
}

/// Side of the inspector image, pixels.
pub const INSPECTOR_PX: u32 = 256;
/// How long after the last change the viewer waits before rendering full resolution and
/// asking for the error against `exact`.
const SETTLE: Duration = Duration::from_millis(350);

/// The viewer's state and logic (see the module header).
pub struct Controller {
    pub state: ViewState,
    /// The scene as loaded (for "reset camera" and "revert").
    loaded_scene: Scene,
    pub scene_path: String,
    /// The last scene that validated (edits that do not are reverted to it).
    valid_scene: Scene,
    pub(super) gpu: Option<Arc<Gpu>>,
    sim: Simulation,
    particles: Arc<Vec<Particle>>,
    sim_inputs: smokeshadow_core::sim::SimInputs,
    /// For a scene of a particle file: the file (the sequence's frame) the particles were read
    /// from, so that a frame is read once, and again only when time picks another.
    read_from: Option<PathBuf>,
    /// What the particles on screen are: count, bounds, extinction range (the scene panel).
    pub particle_summary: crate::particles::Summary,
    pub(super) views: [Option<View>; 2],
    /// Sides rendered on the worker (see [`WorkerView`]).
    pub(super) worker_views: [WorkerView; 2],
    analysis: Option<Analysis>,
    pub(super) inspector: Option<Inspector>,
    /// Bumped whenever something that reaches the pixels changes.
    pub revision: u64,
    last_frame_state: Option<(Scene, bool, ParticleRes, SortOrder, f32)>,
    last_change: Instant,
    pub(super) reduced: bool,
    pub(super) times: Smoothed,
    pub(super) analysed: Option<Analysed>,
    /// Measurements asked for and not yet answered (or superseded): request id and key.
    requested: Vec<(u64, AnalysisKey)>,
    next_request: u64,
    pub(super) probe: Option<Probed>,
    /// One-line problems shown in the panels: technique (A or B), scene, analysis.
    pub technique_error: Option<String>,
    pub scene_error: Option<String>,
    pub status: String,
    /// Frames rendered by view A (for tests and the numbers panel).
    pub frames_rendered: u64,
    last_render: Option<Instant>,
    pub(super) ui_frame_ms: f64,
    /// Shows timings as "—" (snapshot tests: the numbers differ run to run).
    pub hide_timings: bool,
}

impl Controller {
    /// The viewer on `scene` (`path`: the scene file's name, for the file field), rendering on
    /// `gpu`; without one it keeps and edits the state but renders and measures nothing.
    pub fn new(scene: Scene, path: Option<String>, gpu: Option<Arc<Gpu>>) -> Self {
        let analysis = gpu.clone().map(Analysis::new);
        let inspector = gpu.as_ref().map(|gpu| Inspector::new(&gpu.device));
        let time_s = scene.sim.duration_s;
        let mut sim = Simulation::new(&scene);
        sim.advance_to(time_s);
        // A particle file's frame is read by the first update (`update_particles`), as every
        // later one.
        let particles = match &scene.particles {
            Some(_) => Vec::new(),
            None => sim.particles(),
        };
        let particle_summary = crate::particles::Summary::of(&particles);
        let particles = Arc::new(particles);
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
            particle_res: ParticleRes::Full,
            sort: SortOrder::View,
            span: None,
            fit_window: false,
            inspect_channel: 0,
            inspect_scale: 1.0,
            show_help: false,
            scene: scene.clone(),
        };
        Self {
            sim_inputs: Simulation::inputs(&scene),
            loaded_scene: scene.clone(),
            valid_scene: scene,
            scene_path: path.unwrap_or_else(|| "scene.toml".to_owned()),
            state,
            gpu,
            sim,
            particles,
            read_from: None,
            particle_summary,
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
            frames_rendered: 0,
            last_render: None,
            ui_frame_ms: 0.0,
            hide_timings: false,
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
                    .is_some_and(|s| s.key.revision == self.revision && s.key.config == config)
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
    pub(super) fn analysis_key(&self) -> AnalysisKey {
        AnalysisKey {
            revision: self.revision,
            a: self.config(&self.state.a),
            b: self
                .state
                .mode
                .shows_b()
                .then(|| self.config(&self.state.b)),
            motion: (self.state.mode == CompareMode::Motion).then(|| self.frame_interval_s()),
        }
    }

    /// The time between two frames of the temporal compare: the span's, or a particle or
    /// volume sequence's own, else [`crate::motion::DEFAULT_FPS`]'s.
    pub fn frame_interval_s(&self) -> f32 {
        let fps = match &self.state.span {
            Some(span) => span.fps,
            None => smokeshadow_core::motion::default_fps(&self.state.scene),
        };
        1.0 / fps
    }

    /// Whether A's change beside `exact`'s has arrived for the current state.
    pub fn has_motion(&self) -> bool {
        let key = self.analysis_key();
        self.analysed
            .as_ref()
            .is_some_and(|a| a.key == key && a.motion.is_some())
    }

    /// The temporal compare's measures of the frame pair shown: temporal error, its 99.9th
    /// percentile, pops, and `exact`'s own change (once it arrived).
    pub fn motion_measures(&self) -> Option<(f64, f64, u64, f64)> {
        let (p, _) = self.analysed.as_ref()?.motion.as_ref()?;
        Some((p.temporal_error, p.temporal_p999, p.pops, p.exact_change))
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

    /// The reference's configuration (what a side showing `exact` stands for).
    pub fn exact_config(&self) -> TechniqueConfig {
        self.config(&Side {
            source: Source::Exact,
            technique: String::new(),
            channels: 1,
        })
    }

    /// Whether side `i` is shown through the worker's images instead of a [`View`].
    pub fn side_on_worker(&self, i: usize) -> bool {
        let side = if i == 0 { &self.state.a } else { &self.state.b };
        renders_on_worker(&self.config(side))
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

    /// The frame switches the panels set.
    fn render_options(&self) -> RenderOptions {
        RenderOptions {
            spherical: self.state.spherical,
            particle_res: self.state.particle_res,
            sort: self.state.sort,
            ..RenderOptions::default()
        }
    }

    /// The scene as rendered: the orbit applied to the camera once the user moved it (until
    /// then the scene's own camera, bit for bit, so the view matches `render`).
    pub fn frame_scene(&self) -> Scene {
        // At the time shown: a volume's frame (a sequence's, the cloud's drift) follows it.
        let mut scene = self.state.scene.at_time(self.state.time_s);
        if self.state.orbit != Orbit::from_camera(&scene.camera) {
            self.state.orbit.apply(&mut scene.camera);
        }
        scene
    }

    /// The technique parameters the panel offers, one group a technique: A's, then B's unless
    /// B shows the same technique (then A's group is both sides'); none for a side that shows
    /// `exact`.
    pub fn shown_params(&self) -> Vec<ParamGroup> {
        let mut groups: Vec<ParamGroup> = Vec::new();
        for (label, side) in [("A", &self.state.a), ("B", &self.state.b)] {
            if side.source == Source::Exact {
                continue;
            }
            let Ok(entry) = shadow::find(&side.technique) else {
                continue;
            };
            match groups.iter_mut().find(|g| g.technique == entry.name) {
                Some(group) => group.sides.push(label),
                None => groups.push(ParamGroup {
                    technique: entry.name,
                    sides: vec![label],
                    params: entry.params,
                }),
            }
        }
        groups
    }

    /// What the scene on screen holds, for the scene panel: its particles (count, bounds,
    /// extinction), its density volume (its grid's voxels and world box once a view has made
    /// it), both, or that it holds no smoke. Never a range of nothing (infinite bounds).
    pub fn scene_summary(&self) -> String {
        let scene = &self.state.scene;
        let mut lines = Vec::new();
        let s = self.particle_summary;
        if s.count > 0 {
            let source = match &scene.particles {
                Some(source) => format!("from {}", source.path_at(self.state.time_s).display()),
                None => "simulated".to_owned(),
            };
            lines.push(format!(
                "{} particles {source}\nbounds {} m\nextinction {:.3} .. {:.3} /m",
                s.count,
                world_box(s.min.as_dvec3(), s.max.as_dvec3()),
                s.min_density_per_m,
                s.max_density_per_m
            ));
        } else if scene.particles.is_some() || !scene.emitters.is_empty() {
            lines.push("no particles at this time".to_owned());
        }
        if let Some(volume) = &scene.volume {
            lines.push(self.volume_summary(volume));
        }
        if lines.is_empty() {
            lines.push("no smoke: no emitter, particle file or volume".to_owned());
        }
        lines.join("\n")
    }

    /// The scene's volume: what its settings say (a file's grid, the procedural cloud, a
    /// shape), and once a view has made its grid, the grid's voxels and world box.
    fn volume_summary(&self, spec: &VolumeSpec) -> String {
        let said = spec.summary();
        let what = said.strip_prefix("volume: ").unwrap_or(&said);
        // The grid a view's renderer made of this volume (its source, not a previous scene's).
        let wanted = spec.at_time(self.state.time_s);
        let made = self.views.iter().flatten().find_map(|view| {
            let medium = view.renderer().medium();
            let same = medium.spec().is_some_and(|m| same_grid_source(m, &wanted));
            let grid = medium.grid().filter(|_| same)?;
            Some((grid.dims, grid.world_bounds()?))
        });
        match made {
            Some((dims, (lo, hi))) => format!(
                "a density volume: {}x{}x{} voxels, {} m\n({what})",
                dims.x,
                dims.y,
                dims.z,
                world_box(lo, hi)
            ),
            None => format!("a density volume: {what}"),
        }
    }

    // ---- What the controls do -------------------------------------------------------------

    /// Play / pause the simulation.
    pub fn toggle_play(&mut self) {
        self.state.playing = !self.state.playing;
    }

    /// Show / hide the help.
    pub fn toggle_help(&mut self) {
        self.state.show_help = !self.state.show_help;
    }

    /// Back to the camera of the scene as loaded.
    pub fn reset_camera(&mut self) {
        self.state.orbit = Orbit::from_camera(&self.loaded_scene.camera);
    }

    /// A: one channel fewer (not below the technique's minimum).
    pub fn fewer_channels(&mut self) {
        self.step_channels(|c| c.saturating_sub(1));
    }

    /// A: one channel more (not above its technique's largest).
    pub fn more_channels(&mut self) {
        self.step_channels(|c| c + 1);
    }

    fn step_channels(&mut self, step: impl FnOnce(u32) -> u32) {
        let entry = shadow::find(&self.state.a.technique).expect("registered");
        let c = &mut self.state.a.channels;
        *c = step(*c).clamp(entry.min_channels, entry.max_channels);
    }

    /// A: the next technique a side can pick (wrapping round), its budget clamped to it.
    pub fn next_technique(&mut self) {
        let names = comparable_techniques();
        let i = names
            .iter()
            .position(|n| *n == self.state.a.technique)
            .unwrap_or(0);
        self.state.a.technique = names[(i + 1) % names.len()].to_owned();
        clamp_channels(&mut self.state.a);
    }

    /// Measure A against exact now, settled or not.
    pub fn measure_now(&mut self) {
        self.request_analysis(true);
    }

    /// Changes the scene through `edit` (the scene panel's fields); an edit that does not
    /// validate is reverted to the last scene that did and reported in `scene_error`.
    pub fn edit_scene(&mut self, edit: impl FnOnce(&mut Scene)) {
        let before = self.state.scene.clone();
        edit(&mut self.state.scene);
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
    }

    /// Loads the scene named in the path field; on an error the current scene stays.
    pub fn load_scene(&mut self) {
        match crate::particles::open_scene(Some(std::path::Path::new(&self.scene_path))) {
            Ok(scene) => {
                self.set_scene(scene);
                self.status = format!("loaded {}", self.scene_path);
            }
            Err(err) => self.scene_error = Some(format!("{err:#}")),
        }
    }

    /// Saves the scene as shown (camera included, its duration the current time) to the path
    /// field's file.
    pub fn save_scene(&mut self) {
        let path = PathBuf::from(&self.scene_path);
        let mut scene = self.frame_scene();
        scene.sim.duration_s = self.state.time_s;
        self.status = match crate::output::write_atomic(&path, scene.to_toml().as_bytes()) {
            Ok(()) => format!("saved {}", path.display()),
            Err(err) => format!("{err:#}"),
        };
    }

    /// Replaces the scene (camera, time and the "reset" and "revert" points with it).
    pub fn set_scene(&mut self, scene: Scene) {
        self.state.orbit = Orbit::from_camera(&scene.camera);
        self.state.time_s = scene.sim.duration_s;
        self.loaded_scene = scene.clone();
        self.valid_scene = scene.clone();
        self.state.scene = scene;
        self.scene_error = None;
        self.read_from = None;
    }

    /// Slides the spotlight's target in its horizontal plane to where the ray through `uv`
    /// (0..1 across the image seen through `camera`) meets it.
    pub fn aim_light(&mut self, camera: &CameraMatrices, uv: Vec2) {
        let ndc = Vec2::new(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
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
    }

    /// Moves the spotlight around its target as the orbit moves the camera (a drag of
    /// `dx`, `dy` points).
    pub fn orbit_light(&mut self, dx: f32, dy: f32) {
        let light = &mut self.state.scene.light;
        let mut orbit = Orbit::from_camera(&smokeshadow_core::scene::Camera {
            position: light.position,
            target: light.target,
            ..self.state.scene.camera.clone()
        });
        orbit.orbit(dx, dy);
        light.position = orbit.position();
    }

    // ---- Each UI frame --------------------------------------------------------------------

    /// Plays `span` (the frames an animated sweep renders): from its first frame, one frame
    /// a UI frame, looping.
    pub fn play_span(&mut self, span: smokeshadow_core::motion::Span) {
        self.state.span = Some(span);
        self.state.time_s = span.start_s;
        self.state.playing = true;
    }

    /// The time range the time bar and play cover: the span, or 0 to the scene's time (at
    /// least 20 s).
    pub fn time_range(&self) -> (f32, f32) {
        match &self.state.span {
            Some(s) => (s.start_s, s.times().last().copied().unwrap_or(s.end_s)),
            None => (0.0, self.state.scene.sim.duration_s.max(20.0)),
        }
    }

    /// Time passes: the UI frame time's average, and the simulation while playing (looping
    /// at the scene's duration, or 20 s if shorter; a span frame by frame).
    pub fn advance(&mut self, dt_s: f32) {
        self.ui_frame_ms = 0.9 * self.ui_frame_ms + 0.1 * f64::from(dt_s) * 1e3;
        if let (true, Some(span)) = (self.state.playing, self.state.span) {
            // The frame after the nearest one, so that a scrubbed time rejoins the frames.
            let times = span.times();
            let k = ((self.state.time_s - span.start_s) * span.fps).round() as i64 + 1;
            self.state.time_s = match usize::try_from(k).ok().and_then(|k| times.get(k)) {
                Some(&t) => t,
                None => times[0],
            };
            return;
        }
        if self.state.playing {
            let end = self.state.scene.sim.duration_s.max(20.0);
            self.state.time_s += dt_s;
            if self.state.time_s > end {
                self.state.time_s = 0.0;
            }
        }
    }

    /// After the panels ran: brings the particles up to date, renders A (and B) into
    /// `viewport_px` if anything changed (half resolution while `interacting`), asks for a
    /// measurement once the view has settled and draws the inspector.
    pub fn update(&mut self, viewport_px: (u32, u32), interacting: bool) {
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
    }

    /// When the UI should draw again, `interacting` as given to [`Controller::update`].
    pub fn repaint(&self, interacting: bool) -> Repaint {
        let busy = self.analysis.as_ref().is_some_and(Analysis::busy);
        if self.state.playing || interacting {
            Repaint::Now
        } else if self.reduced || busy || !self.settled() {
            Repaint::After(Duration::from_millis(60))
        } else {
            Repaint::OnInput
        }
    }

    /// Brings the particles to the current time and emitter settings, or for a scene of a
    /// particle file, reads the file (a sequence's frame at the current time) when it changes.
    fn update_particles(&mut self) {
        let s = &self.state.scene;
        let fresh = match &s.particles {
            Some(source) => {
                let path = source.path_at(self.state.time_s);
                match self.read_from.as_ref() == Some(&path) {
                    true => None,
                    false => {
                        self.read_from = Some(path);
                        match source.particles_at(self.state.time_s) {
                            Ok(ps) => Some(ps),
                            Err(err) => {
                                // Keep the last frame on screen and say why there is no new one.
                                self.scene_error = Some(err.to_string());
                                None
                            }
                        }
                    }
                }
            }
            None => {
                self.read_from = None;
                let inputs = Simulation::inputs(s);
                if inputs != self.sim_inputs {
                    self.sim = Simulation::new(s);
                    self.sim_inputs = inputs;
                }
                if (self.sim.time_s() - self.state.time_s).abs() > s.sim.step_s * 0.5
                    || self.particles.is_empty() && self.sim.time_s() > 0.0
                {
                    self.sim.advance_to(self.state.time_s);
                }
                None
            }
        };
        let state = (
            self.frame_scene(),
            self.state.spherical,
            self.state.particle_res,
            self.state.sort,
            self.state.time_s,
        );
        if fresh.is_some() || self.last_frame_state.as_ref() != Some(&state) {
            // A file's particles stay as read until another frame is read.
            let particles = match (fresh, &self.state.scene.particles) {
                (Some(ps), _) => Some(ps),
                (None, Some(_)) => None,
                (None, None) => Some(self.sim.particles()),
            };
            if let Some(particles) = particles {
                self.particle_summary = crate::particles::Summary::of(&particles);
                self.particles = Arc::new(particles);
            }
            self.last_frame_state = Some(state);
            self.revision += 1;
            self.last_change = Instant::now();
        }
    }

    /// Renders A (and B when the mode shows it) if anything changed.
    fn render_views(&mut self, viewport_px: (u32, u32)) {
        let Some(gpu) = self.gpu.clone() else {
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
            reuse_shadow_maps: true,
            ..self.render_options()
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
                slot => match View::new(&gpu, &config, size) {
                    Ok(view) => slot.insert(view),
                    Err(err) => {
                        error = Some(format!("{}: {err}", ["A", "B"][i]));
                        continue;
                    }
                },
            };
            match view.render(&gpu, &scene, &self.particles, &options, self.revision, size) {
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
        let options = self.render_options();
        let view = &mut self.worker_views[i];
        if view.shown.as_ref().is_some_and(|s| s.key == key)
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
                options,
            },
            config: key.config.clone(),
        });
        view.pending = Some((self.next_request, key));
    }

    /// Handles what the worker sent back.
    pub fn receive(&mut self) {
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
                    motion,
                    seconds,
                } => {
                    if let Some(i) = self.requested.iter().position(|(r, _)| *r == id) {
                        let (_, key) = self.requested.remove(i);
                        // Answers to older requests were superseded and never come.
                        self.requested.retain(|(r, _)| *r > id);
                        self.analysed = Some(Analysed {
                            id,
                            key,
                            image_a,
                            a_vs_exact,
                            seconds,
                            b: b_vs_a.map(|boxed| {
                                let (metrics, difference_x4, flip_heat) = *boxed;
                                Comparison {
                                    metrics,
                                    difference_x4,
                                    flip_heat,
                                }
                            }),
                            motion: motion.map(|boxed| *boxed),
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
                    // Request ids are unique: at most one side waits for this one.
                    if let Some(view) = self
                        .worker_views
                        .iter_mut()
                        .find(|v| v.pending.as_ref().is_some_and(|(r, _)| *r == id))
                    {
                        let (_, key) = view.pending.take().expect("pending");
                        view.shown = Some(WorkerImage {
                            id,
                            key,
                            image,
                            bytes,
                        });
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
    /// has settled, or now when `force`d.
    pub fn request_analysis(&mut self, force: bool) {
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
        let exact = self.exact_config();
        self.next_request += 1;
        analysis.send(Request::Compare {
            id: self.next_request,
            frame,
            a: key.a.clone(),
            b: key.b.clone(),
            exact,
            motion: key.motion,
        });
        self.requested.push((self.next_request, key));
    }

    /// T along the light ray through the point under `uv` (0..1 across the image).
    pub fn request_probe(&mut self, uv: Vec2) {
        let Some(analysis) = &self.analysis else {
            return;
        };
        let scene = self.frame_scene();
        let (w, h) = (scene.output.width_px, scene.output.height_px);
        let camera = CameraMatrices::new(&scene, w, h);
        let ndc = Vec2::new(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
        let far = camera
            .clip_from_world()
            .inverse()
            .project_point3(ndc.extend(1.0));
        let dir = (far - camera.position).normalize();
        let point =
            smokeshadow_core::render::shaded::first_opaque_hit(&scene, camera.position, dir)
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
        configs.push(self.exact_config());
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
    pub fn save_viewport(&mut self) {
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
                options: self.render_options(),
            },
            config,
            path: path.clone(),
        });
        self.status = format!("saving {} ...", path.display());
    }

    /// Writes the window's screenshot, once it arrived (`None`: it had an unexpected size).
    pub fn save_window_image(&mut self, rgba: Option<image::RgbaImage>) {
        let path = PathBuf::from("smokeshadow-window.png");
        self.status = match rgba.map(|rgba| crate::output::write_png(&path, &rgba)) {
            Some(Ok(())) => format!("saved {}", path.display()),
            Some(Err(err)) => format!("{err:#}"),
            None => "the screenshot had an unexpected size".to_owned(),
        };
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
}

/// One group of the parameter panel: a technique A or B shows, the sides that show it ("A",
/// "B", or both) and the parameters it declares (none for some).
#[derive(Clone, Debug, PartialEq)]
pub struct ParamGroup {
    pub technique: &'static str,
    pub sides: Vec<&'static str>,
    pub params: &'static [shadow::ParamSpec],
}

impl ParamGroup {
    /// The group's heading: the technique and its sides, "osm (A)", "fom (A and B)".
    pub fn heading(&self) -> String {
        format!("{} ({})", self.technique, self.sides.join(" and "))
    }
}

/// A world box for the scene panel, "[x, y, z] .. [x, y, z]" (metres, two decimals).
fn world_box(lo: DVec3, hi: DVec3) -> String {
    format!(
        "[{:.2}, {:.2}, {:.2}] .. [{:.2}, {:.2}, {:.2}]",
        lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
    )
}

/// Whether two volume settings make the same grid: they differ at most in the march's steps
/// and the shading, which the grid does not hold.
fn same_grid_source(a: &VolumeSpec, b: &VolumeSpec) -> bool {
    let a_with_bs_shading = VolumeSpec {
        albedo: b.albedo,
        eye_steps: b.eye_steps,
        build_steps: b.build_steps,
        jitter: b.jitter,
        powder: b.powder,
        ..a.clone()
    };
    a_with_bs_shading == *b
}

/// Whether a configuration is rendered on the analysis worker instead of the UI thread.
fn renders_on_worker(config: &TechniqueConfig) -> bool {
    shadow::find(&config.name).is_ok_and(|e| e.build_reads_back)
}

/// Techniques a side can pick (everything but `none`, which the numbers use as a baseline).
pub fn comparable_techniques() -> Vec<&'static str> {
    shadow::contenders().map(|e| e.name).collect()
}

/// Keeps a side's budget within what its technique accepts.
pub fn clamp_channels(side: &mut Side) {
    let entry = shadow::find(&side.technique).expect("registered");
    side.channels = side.channels.clamp(entry.min_channels, entry.max_channels);
}

/// What a budget means for a technique, for the slider's caption.
pub fn budget_meaning(technique: &str, channels: u32) -> String {
    match shadow::find(technique) {
        Ok(entry) if entry.role == shadow::Role::Contender => (entry.budget_caption)(channels),
        _ => String::new(),
    }
}

/// The inspectable channels of a view's technique: (map index, component, label, kind).
pub(super) fn inspect_channels(view: &View) -> Vec<(usize, u32, String, MapKind)> {
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
