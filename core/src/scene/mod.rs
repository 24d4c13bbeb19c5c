//! Scene files: the typed, validated description of one experiment.
//!
//! A scene is a TOML file (see `scenes/README.md` for every field with its unit, default and
//! range). It fixes everything that reaches pixels: output size, camera, the spotlight, the
//! opaque geometry, the smoke emitter (thesis chapter 4: 2500 particles, 1024x768, 512x512 shadow
//! map, one spotlight, fixed camera and light), the wind gust, the simulation clock and the
//! shading constants. Parsing denies unknown fields; [`Scene::validate`] checks every range and
//! names the field, the value and the allowed range when one is wrong.
//!
//! To add a field: add it to the struct with a `///` doc line giving unit and range, give it a
//! default in the `Default` impl, check it in `validate`, and document it in `scenes/README.md`.

pub mod sequence;
pub mod technique;
mod validate;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::files::{Files, Folder};

use glam::Vec3;
use serde::{Deserialize, Serialize};

pub use crate::medium::scene::VolumeSpec;

pub use technique::{Framing, OccluderMode, ParamValue, SplatMode, TechniqueParams};
pub use validate::LIMITS;

/// The thesis experiment (chapter 4), embedded so the binary runs without any file.
pub const THESIS_PLUME_TOML: &str = include_str!("../../../scenes/thesis_plume.toml");
/// The same plume after a wind gust.
pub const THESIS_WIND_TOML: &str = include_str!("../../../scenes/thesis_wind.toml");
/// The scaling family's base: the thesis plume, meant to be run at other particle counts with
/// `--particles N` ([`Scene::with_particles`]).
pub const PLUME_SCALED_TOML: &str = include_str!("../../../scenes/plume_scaled.toml");
/// `plume_scaled` at 65,536 particles, the scaling rule applied.
pub const PLUME_65K_TOML: &str = include_str!("../../../scenes/plume_65k.toml");

/// Gallery: two plumes with clear air between them along the light's rays (gaps along a ray).
pub const TWO_PLUMES_TOML: &str = include_str!("../../../scenes/two_plumes.toml");
/// Gallery: the thesis plume with a stray puff between it and the light (stretched depth bounds).
pub const OUTLIER_TOML: &str = include_str!("../../../scenes/outlier.toml");
/// Gallery: a thin, wide layer lit almost edge-on (long paths through a thin slab).
pub const THIN_SHEET_TOML: &str = include_str!("../../../scenes/thin_sheet.toml");
/// Gallery: a tall, dense column lit from above (long, dense paths along its axis).
pub const COLUMN_TOML: &str = include_str!("../../../scenes/column.toml");
/// Gallery: a low, wide layer with the camera inside it (particles containing the eye).
pub const GROUND_FOG_TOML: &str = include_str!("../../../scenes/ground_fog.toml");

/// Training scenes of `smokeshadow tune` ([`TRAINING`]), kept apart from the thesis and the
/// gallery, on which the answers are given: puffs with gaps along the rays.
pub const TRAIN_PUFFS_TOML: &str = include_str!("../../../scenes/train_puffs.toml");
/// Training: a wide, faint haze (long, thin paths).
pub const TRAIN_HAZE_TOML: &str = include_str!("../../../scenes/train_haze.toml");
/// Training: a plume bent by wind, lit from behind.
pub const TRAIN_BACKLIT_TOML: &str = include_str!("../../../scenes/train_backlit.toml");
/// Held-out scenes ([`HOLDOUT`]), apart from training, the thesis and the gallery: a jet
/// spreading sideways along the light's rays.
pub const HOLDOUT_JET_TOML: &str = include_str!("../../../scenes/holdout_jet.toml");
/// Held out: a dense smoulder under a faint veil (two layers of very different density).
pub const HOLDOUT_STACK_TOML: &str = include_str!("../../../scenes/holdout_stack.toml");
/// The procedural cloudscape (`[volume] procedural = "cloud"`), ray marched.
pub const CLOUD_TOML: &str = include_str!("../../../scenes/cloud.toml");
/// A real smoke simulation's density grid (OpenUSD's test file, built in), ray marched.
pub const VDB_SMOKE_TOML: &str = include_str!("../../../scenes/vdb_smoke.toml");

/// The scenes embedded in the binary, by name.
pub const EMBEDDED: &[(&str, &str)] = &[
    ("thesis_plume", THESIS_PLUME_TOML),
    ("thesis_wind", THESIS_WIND_TOML),
    ("plume_scaled", PLUME_SCALED_TOML),
    ("plume_65k", PLUME_65K_TOML),
    ("two_plumes", TWO_PLUMES_TOML),
    ("outlier", OUTLIER_TOML),
    ("thin_sheet", THIN_SHEET_TOML),
    ("column", COLUMN_TOML),
    ("ground_fog", GROUND_FOG_TOML),
    ("train_puffs", TRAIN_PUFFS_TOML),
    ("train_haze", TRAIN_HAZE_TOML),
    ("train_backlit", TRAIN_BACKLIT_TOML),
    ("holdout_jet", HOLDOUT_JET_TOML),
    ("holdout_stack", HOLDOUT_STACK_TOML),
    ("cloud", CLOUD_TOML),
    ("vdb_smoke", VDB_SMOKE_TOML),
];

/// The training scenes `smokeshadow tune` chooses the techniques' parameters on: none of them is
/// a thesis or gallery scene, where the answers are given (`tests/gallery.rs` holds them apart).
pub const TRAINING: &[&str] = &["train_puffs", "train_haze", "train_backlit"];

/// Scenes held out from everything: `tune` refuses them (neither training nor its check), no
/// answer is given on them, and the convergence tests hold every converging technique's error
/// to fall with its budget there too, on smoke no parameter was chosen for.
pub const HOLDOUT: &[&str] = &["holdout_jet", "holdout_stack"];

/// The gallery: the embedded scenes that `sweep --scenes all` runs, each a different kind of
/// smoke stressing one failure mode (`scenes/README.md` says what each one tests;
/// `tests/gallery.rs` checks that it does).
pub const GALLERY: &[&str] = &[
    "thesis_plume",
    "two_plumes",
    "outlier",
    "thin_sheet",
    "column",
    "ground_fog",
    "cloud",
    "vdb_smoke",
    "plume_65k",
];

/// The embedded scenes with committed baselines (`baselines/<scene>/`): the thesis experiment, and the density volume's cloudscape.
/// The scaling family is for timing; its smoke is the thesis plume's at other counts.
pub const BASELINE_SCENES: &[&str] = &["thesis_plume", "thesis_wind", "cloud"];

/// The embedded scenes' names, comma-separated.
pub fn embedded_names() -> String {
    EMBEDDED
        .iter()
        .map(|(n, _)| *n)
        .collect::<Vec<_>>()
        .join(", ")
}

/// One line on what the embedded scene `name` is, for `smokeshadow info`: its `description`, or
/// for a scene without one (the thesis scenes keep theirs empty so that their content hash, which
/// the baselines record, does not change) the first sentence of the file's header comment.
pub fn embedded_summary(name: &str) -> Option<String> {
    let (_, text) = EMBEDDED.iter().find(|(n, _)| *n == name)?;
    let scene = Scene::embedded(name)?;
    if !scene.description.is_empty() {
        return Some(scene.description);
    }
    let header: Vec<&str> = text
        .lines()
        .map_while(|l| l.strip_prefix('#'))
        .map(str::trim)
        .collect();
    let header = header.join(" ");
    let sentence = match header.find(". ") {
        Some(end) => &header[..=end],
        None => header.as_str(),
    };
    Some(sentence.trim().to_owned())
}

/// Errors from loading or validating a scene. Each renders as one line for the user.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("cannot read scene file {path}: {cause}{hint}")]
    Read {
        path: PathBuf,
        cause: std::io::Error,
        /// For a file that does not exist: the embedded scenes a name could have meant.
        hint: String,
    },
    #[error("{origin}: line {line}, column {column}: {message}")]
    Parse {
        origin: String,
        line: usize,
        column: usize,
        message: String,
    },
    #[error("{origin}: {message}")]
    Invalid { origin: String, message: String },
}

/// One experiment: everything that reaches the pixels of a frame.
///
/// Read and written through `SceneFile`, the TOML's shape: the emitters come from one
/// `[emitter]` table or from an array of `[[emitters]]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "SceneFile", into = "SceneFile")]
pub struct Scene {
    /// A short name used in file names and reports.
    pub name: String,
    /// One sentence on what kind of smoke the scene is and what it tests, for reports and
    /// `smokeshadow info` (empty by default).
    pub description: String,
    pub output: Output,
    pub camera: Camera,
    pub light: Spotlight,
    pub ground: Ground,
    /// Axis-aligned boxes standing on (or above) the ground.
    pub boxes: Vec<BoxShape>,
    /// The smoke's emitters, at least one; each is simulated on its own (its own seed, source,
    /// forces and lifetime) in the one wind, and their particles are listed emitter by emitter.
    pub emitters: Vec<Emitter>,
    /// Particles from a file instead of the emitters (`[particles]`): then `emitters` is empty.
    pub particles: Option<ParticleSource>,
    /// A density volume (`[volume]`, `crate::medium::scene`): with no emitter and no
    /// `[particles]`, the scene's smoke is the volume alone (`emitters` is empty).
    pub volume: Option<VolumeSpec>,
    pub wind: Wind,
    pub sim: SimClock,
    pub shadow: ShadowSettings,
    pub shading: Shading,
}

/// A scene as its TOML is written: [`Scene`] with either one `[emitter]` table (the original
/// form, and what a one-emitter scene is written back as, so its canonical text and
/// [`Scene::content_hash`] do not change) or an array of `[[emitters]]`.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct SceneFile {
    name: String,
    #[serde(skip_serializing_if = "String::is_empty")]
    description: String,
    output: Output,
    camera: Camera,
    light: Spotlight,
    ground: Ground,
    boxes: Vec<BoxShape>,
    #[serde(skip_serializing_if = "Option::is_none")]
    emitter: Option<Emitter>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    emitters: Vec<Emitter>,
    #[serde(skip_serializing_if = "Option::is_none")]
    particles: Option<ParticleSource>,
    #[serde(skip_serializing_if = "Option::is_none")]
    volume: Option<VolumeSpec>,
    wind: Wind,
    sim: SimClock,
    shadow: ShadowSettings,
    shading: Shading,
}

// Not derivable, whatever clippy says: the fields' defaults are the scene's ("untitled", the
// thesis-like camera ...), not their types'.
#[allow(clippy::derivable_impls)]
impl Default for SceneFile {
    fn default() -> Self {
        Self {
            emitter: None,
            ..Scene::default().into()
        }
    }
}

impl TryFrom<SceneFile> for Scene {
    type Error = String;

    fn try_from(f: SceneFile) -> Result<Self, String> {
        let from_file = f.particles.is_some();
        // A volume scene has particles only where it names them.
        let volume_only = f.volume.is_some() && f.emitter.is_none() && f.emitters.is_empty();
        if from_file && (f.emitter.is_some() || !f.emitters.is_empty()) {
            return Err(
                "both [particles] and an emitter are given: the particles come from \
                        the file or from the emitters, not both"
                    .to_owned(),
            );
        }
        let emitters = match (f.emitter, f.emitters.is_empty()) {
            _ if from_file || volume_only => Vec::new(),
            (Some(_), false) => {
                return Err(
                    "both [emitter] and [[emitters]] are given: use one [emitter] table or an \
                     array of [[emitters]]"
                        .to_owned(),
                );
            }
            (Some(one), true) => vec![one],
            (None, false) => f.emitters,
            (None, true) => vec![Emitter::default()],
        };
        Ok(Self {
            name: f.name,
            description: f.description,
            output: f.output,
            camera: f.camera,
            light: f.light,
            ground: f.ground,
            boxes: f.boxes,
            emitters,
            particles: f.particles,
            volume: f.volume,
            wind: f.wind,
            sim: f.sim,
            shadow: f.shadow,
            shading: f.shading,
        })
    }
}

impl From<Scene> for SceneFile {
    fn from(s: Scene) -> Self {
        let (emitter, emitters) = match <[Emitter; 1]>::try_from(s.emitters) {
            Ok([one]) => (Some(one), Vec::new()),
            Err(several) => (None, several),
        };
        Self {
            name: s.name,
            description: s.description,
            output: s.output,
            camera: s.camera,
            light: s.light,
            ground: s.ground,
            boxes: s.boxes,
            emitter,
            emitters,
            particles: s.particles,
            volume: s.volume,
            wind: s.wind,
            sim: s.sim,
            shadow: s.shadow,
            shading: s.shading,
        }
    }
}

/// Output image size.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Output {
    /// Width in pixels, 1..=8192. Default 1024 (the thesis screen).
    pub width_px: u32,
    /// Height in pixels, 1..=8192. Default 768.
    pub height_px: u32,
}

/// A pinhole camera.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Camera {
    /// Eye position in world metres (y is up).
    pub position: Vec3,
    /// Point the camera looks at, world metres; must differ from `position`.
    pub target: Vec3,
    /// Vertical field of view in degrees, (1, 170).
    pub fov_y_deg: f32,
    /// Near clip distance in metres, (0, far_m).
    pub near_m: f32,
    /// Far clip distance in metres.
    pub far_m: f32,
}

/// The one spotlight that lights (and shadows) the scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Spotlight {
    /// `spot` (default): a cone from `position` towards `target`; `point`: an omnidirectional
    /// light at `position` (it ignores `target`, `cone_angle_deg` and `penumbra`), whose shadows
    /// every technique builds on the six faces of a cube around it.
    #[serde(skip_serializing_if = "LightKind::is_spot")]
    pub kind: LightKind,
    /// Light position, world metres.
    pub position: Vec3,
    /// Point the cone axis aims at, world metres; must differ from `position`.
    pub target: Vec3,
    /// Half-angle of the cone in degrees, (0, 80).
    pub cone_angle_deg: f32,
    /// Fraction of the cone (from its edge inwards) over which intensity falls smoothly to 0, [0, 1].
    pub penumbra: f32,
    /// Linear RGB colour of the light, each component >= 0.
    pub color: Vec3,
    /// Radiant intensity on the axis (W/sr-like units; irradiance = intensity / distance²), >= 0.
    pub intensity: f32,
}

/// What shape of light `[light]` is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum LightKind {
    /// A spotlight: one light space covering its cone.
    #[default]
    Spot,
    /// A point light: six cube-face light spaces, one per axis direction.
    Point,
}

impl LightKind {
    pub fn is_spot(&self) -> bool {
        *self == LightKind::Spot
    }

    /// The light spaces (shadow-map faces) a technique builds for this light.
    pub fn faces(self) -> usize {
        match self {
            LightKind::Spot => 1,
            LightKind::Point => 6,
        }
    }
}

/// The ground plane: a square centred under the origin.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Ground {
    /// Height of the plane (world y) in metres.
    pub height_m: f32,
    /// Edge length of the square in metres, > 0.
    pub size_m: f32,
    /// Diffuse albedo (linear RGB), each component in [0, 1].
    pub albedo: Vec3,
}

/// An opaque axis-aligned box.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxShape {
    /// Centre in world metres.
    pub center: Vec3,
    /// Edge lengths in metres, each > 0.
    pub size: Vec3,
    /// Diffuse albedo (linear RGB), each component in [0, 1].
    pub albedo: Vec3,
}

/// The smoke emitter: a fixed pool of particles born at a steady rate and recycled when they die.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Emitter {
    /// Number of particles in the pool, 1..=4_000_000. The thesis uses 2500.
    pub count: u32,
    /// Seed of the emitter's PRNG (PCG-32); same seed, same smoke.
    pub seed: u64,
    /// Centre of the source disc, world metres.
    pub position: Vec3,
    /// Radius of the source disc (horizontal) in metres, >= 0.
    pub source_radius_m: f32,
    /// Mean initial velocity in m/s.
    pub velocity_m_per_s: Vec3,
    /// Random spread added to the initial velocity (per axis, uniform ±), m/s, >= 0.
    pub velocity_spread_m_per_s: f32,
    /// Upward acceleration while the particle is young and hot, m/s², >= 0.
    pub buoyancy_m_per_s2: f32,
    /// Age over which buoyancy decays to 1/e, seconds, > 0.
    pub buoyancy_decay_s: f32,
    /// Strength of the turbulent acceleration field, m/s², >= 0.
    pub turbulence_m_per_s2: f32,
    /// Length scale of the turbulent field's largest eddies, metres, > 0.
    pub turbulence_scale_m: f32,
    /// Drag rate towards the air velocity (wind), 1/s, >= 0.
    pub drag_per_s: f32,
    /// Life of a particle in seconds, > 0. The pool emits `count / lifetime_s` particles per second.
    pub lifetime_s: f32,
    /// Radius at birth in metres, > 0.
    pub radius_birth_m: f32,
    /// Radius growth rate in m/s, >= 0.
    pub growth_m_per_s: f32,
    /// Extinction coefficient τ inside a particle (thesis 3.2.2.3), 1/m, >= 0.
    pub density_per_m: f32,
    /// Fraction of the life over which a particle fades in (start) and out (end), each in [0, 0.5].
    pub fade_in: f32,
    pub fade_out: f32,
    /// Single-scattering albedo (linear RGB), each component in [0, 1].
    pub albedo: Vec3,
    /// Per-particle random brightness variation of the albedo, [0, 0.999].
    pub albedo_jitter: f32,
}

/// Particles from a file (`[particles]`): a PLY or CSV file, or a numbered sequence of them
/// (`smoke.%04d.ply`) of which the scene's time picks the frame. `crate::particles` reads them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ParticleSource {
    /// The file, relative to the scene file's folder; `%04d` (or `%d`) makes it a sequence.
    pub file: String,
    /// A sequence's frames per second, > 0.
    pub frame_rate_hz: f32,
    /// The frame number at t = 0 (Houdini's first frame is 1).
    pub frame_at_zero: i64,
    /// The radius of particles whose file has none, metres, > 0.
    pub radius_m: f32,
    /// The extinction of particles whose file has none, 1/m, >= 0.
    pub density_per_m: f32,
    /// The albedo of particles whose file has none, linear RGB, each in [0, 1].
    pub albedo: Vec3,
    /// The folder `file` is relative to, and the files it is read from: the scene file's (set
    /// when a scene file is loaded; not written).
    #[serde(skip)]
    pub folder: Folder,
}

impl Default for ParticleSource {
    fn default() -> Self {
        Self {
            file: String::new(),
            frame_rate_hz: 24.0,
            frame_at_zero: 0,
            radius_m: 0.1,
            density_per_m: 2.0,
            albedo: Vec3::splat(0.8),
            folder: Folder::default(),
        }
    }
}

/// A wind gust: the air starts moving at `start_s` and ramps up over `ramp_s`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Wind {
    /// Direction the air moves towards (normalised on use; ignored when strength is 0).
    pub direction: Vec3,
    /// Air speed once the gust is established, m/s, >= 0. 0 disables wind.
    pub strength_m_per_s: f32,
    /// Simulation time at which the gust starts, seconds, >= 0.
    pub start_s: f32,
    /// Time for the gust to ramp from 0 to full strength, seconds, >= 0.
    pub ramp_s: f32,
}

/// The simulation clock: fixed steps from t = 0 to `duration_s`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimClock {
    /// Simulated time at which the frame is rendered, seconds, [0, 600].
    pub duration_s: f32,
    /// Fixed time step, seconds, (0, 1).
    pub step_s: f32,
}

/// The most boxes a scene may hold (`scene.boxes`): the exact test
/// (`shaders/common/occluders_exact.wgsl`) loops over every box at every point it lights, and on
/// llvmpipe those iterations count against the loop budget the reference's walk shares
/// (`crate::frame::occluders::OCCLUDER_LOOP_RESERVE`).
pub const MAX_BOXES: usize = 1024;

/// The opaque occluders' depth map side unless a scene says otherwise: 4 MiB, and at the
/// thesis scene's framing about 1 cm per texel where the box stands.
pub const DEFAULT_OCCLUDER_RESOLUTION_PX: u32 = 1024;

/// Shadow-map settings shared by every technique.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ShadowSettings {
    /// Shadow-map resolution (square), pixels, 1..=8192. The thesis uses 512.
    pub resolution_px: u32,
    /// Resolution (square, pixels, 16..=8192) of the depth map of the opaque geometry (ground
    /// and boxes) seen from the light, whose filtered (PCF) visibility every technique's T is
    /// multiplied by; its bytes are reported apart from the technique's. Default 1024.
    pub occluder_resolution_px: u32,
    /// Where the layered techniques put a particle's optical depth along the light ray:
    /// `segment` (default: over the chord, the reference's own density model) or `point` (the
    /// thesis' model: at the centre).
    pub splat: SplatMode,
    /// How the lighting tests the opaque occluders: `exact` (default: the segment to the light
    /// against the boxes and the ground, as the reference does, so compared images differ only
    /// in the smoke's shadow) or `map` (a filtered depth map of `occluder_resolution_px`, as an
    /// engine would; the reference stays exact).
    pub occluders: OccluderMode,
    /// How a spotlight's light space frames the smoke: `fit` (default: the smoke's light-space
    /// bounds within the cone, fitted each frame, as engines fit shadow frusta) or `cone` (the
    /// whole cone: the thesis' framing). A point light's cube faces are always whole.
    pub framing: Framing,
    /// Technique-specific parameters (`[shadow.params]`, e.g. `dom_layer_growth = 2` or
    /// `osm_interp = "cubic"`): each key is declared, documented and checked by its technique's
    /// registry entry (`smokeshadow info` lists them); absent keys take the entry's defaults.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub params: BTreeMap<String, ParamValue>,
    /// The shadow's temporal history at the particles' lighting points, its weight w in
    /// [0, 0.99]: each frame T' = (1 − w) T + w T'_prev per particle, as engines filter a
    /// flickering shadow (0.9 their default; it lags about w / (1 − w) frames). 0, the default,
    /// is off; the reference is never filtered (`crate::render::history`).
    #[serde(skip_serializing_if = "is_zero_f32")]
    pub history: f32,
}

fn is_zero_f32(v: &f32) -> bool {
    *v == 0.0
}

/// The largest `[shadow] history` weight: a weight of 1 would never let the shadow change.
pub const MAX_HISTORY: f32 = 0.99;

impl ShadowSettings {
    /// The technique parameters these settings give for a `channels` budget.
    pub fn params(&self, channels: u32) -> TechniqueParams {
        TechniqueParams {
            channels,
            resolution_px: self.resolution_px,
            splat: self.splat,
            occluders: self.occluders,
            values: self.params.clone(),
            memory_limit_bytes: None,
        }
    }
}

/// Shading constants.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Shading {
    /// Henyey–Greenstein asymmetry g of the smoke's phase function, (-1, 1).
    pub hg_g: f32,
    /// Ambient (sky) radiance added to every surface and particle, linear RGB, each >= 0.
    pub ambient: Vec3,
    /// Background radiance where nothing is drawn, linear RGB, each >= 0.
    pub background: Vec3,
    /// Exposure multiplier applied before tone mapping, > 0.
    pub exposure: f32,
}

impl Default for Scene {
    fn default() -> Self {
        Self {
            name: "untitled".into(),
            description: String::new(),
            output: Output::default(),
            camera: Camera::default(),
            light: Spotlight::default(),
            ground: Ground::default(),
            boxes: Vec::new(),
            emitters: vec![Emitter::default()],
            particles: None,
            volume: None,
            wind: Wind::default(),
            sim: SimClock::default(),
            shadow: ShadowSettings::default(),
            shading: Shading::default(),
        }
    }
}

impl Default for Output {
    fn default() -> Self {
        Self {
            width_px: 1024,
            height_px: 768,
        }
    }
}

impl Default for Camera {
    fn default() -> Self {
        Self {
            position: Vec3::new(0.0, 2.5, 10.0),
            target: Vec3::new(0.0, 2.0, 0.0),
            fov_y_deg: 45.0,
            near_m: 0.1,
            far_m: 100.0,
        }
    }
}

impl Default for Spotlight {
    fn default() -> Self {
        Self {
            kind: LightKind::Spot,
            position: Vec3::new(-6.0, 8.0, 4.0),
            target: Vec3::new(0.0, 2.0, 0.0),
            cone_angle_deg: 30.0,
            penumbra: 0.25,
            color: Vec3::ONE,
            intensity: 100.0,
        }
    }
}

impl Default for Ground {
    fn default() -> Self {
        Self {
            height_m: 0.0,
            size_m: 40.0,
            albedo: Vec3::splat(0.5),
        }
    }
}

impl Default for Emitter {
    fn default() -> Self {
        Self {
            count: 2500,
            seed: 1,
            position: Vec3::ZERO,
            source_radius_m: 0.3,
            velocity_m_per_s: Vec3::new(0.0, 1.0, 0.0),
            velocity_spread_m_per_s: 0.2,
            buoyancy_m_per_s2: 0.5,
            buoyancy_decay_s: 2.0,
            turbulence_m_per_s2: 0.5,
            turbulence_scale_m: 1.5,
            drag_per_s: 0.5,
            lifetime_s: 6.0,
            radius_birth_m: 0.2,
            growth_m_per_s: 0.08,
            density_per_m: 2.0,
            fade_in: 0.1,
            fade_out: 0.4,
            albedo: Vec3::splat(0.8),
            albedo_jitter: 0.1,
        }
    }
}

impl Emitter {
    /// The same smoke with `count` particles: the rule of the scaling family (`plume_scaled`,
    /// `plume_65k`, `--particles`). With N0 = `self.count`, the birth radius and the growth rate
    /// (so every radius at every age) are multiplied by (N0/N)^(1/3) and τ is kept. Each sphere's
    /// optical depth integrated over its projected area is ∝ τ r³ (for the extinction
    /// τ(1 − d/r) of [`crate::shadow::closed_form`]), so the plume's total N·τ·r³, hence its mean
    /// optical depth along light rays, stays that of N0 particles, as does the total sphere
    /// volume N·r³ that fills its silhouette. The birth schedule (count / lifetime per second)
    /// and the flow are unchanged, so the particles sample the same plume, more finely; its
    /// outline's soft fringe, as wide as the radii, gets thinner (`tests/scaling.rs` measures
    /// both).
    pub fn scaled_to(&self, count: u32) -> Self {
        // In f64 so that a scale of 1 and exact cubes round-trip the f32 radii exactly.
        let k = (f64::from(self.count) / f64::from(count.max(1))).cbrt();
        let scale = |v: f32| (f64::from(v) * k) as f32;
        Self {
            count,
            radius_birth_m: scale(self.radius_birth_m),
            growth_m_per_s: scale(self.growth_m_per_s),
            ..self.clone()
        }
    }
}

impl Default for Wind {
    fn default() -> Self {
        Self {
            direction: Vec3::X,
            strength_m_per_s: 0.0,
            start_s: 0.0,
            ramp_s: 1.0,
        }
    }
}

impl Default for SimClock {
    fn default() -> Self {
        Self {
            duration_s: 8.0,
            step_s: 1.0 / 60.0,
        }
    }
}

impl Default for ShadowSettings {
    fn default() -> Self {
        let defaults = TechniqueParams::new(1, 512);
        Self {
            resolution_px: defaults.resolution_px,
            occluder_resolution_px: DEFAULT_OCCLUDER_RESOLUTION_PX,
            splat: defaults.splat,
            occluders: defaults.occluders,
            framing: Framing::default(),
            params: BTreeMap::new(),
            history: 0.0,
        }
    }
}

impl Default for Shading {
    fn default() -> Self {
        Self {
            hg_g: 0.3,
            ambient: Vec3::splat(0.05),
            background: Vec3::new(0.02, 0.025, 0.035),
            exposure: 1.0,
        }
    }
}

impl Scene {
    /// The embedded thesis experiment (`scenes/thesis_plume.toml`).
    pub fn thesis_plume() -> Self {
        Self::from_toml_str(THESIS_PLUME_TOML, "embedded thesis_plume")
            .expect("the embedded thesis scene is valid (checked by tests)")
    }

    /// An embedded scene by name (see [`EMBEDDED`]).
    pub fn embedded(name: &str) -> Option<Self> {
        EMBEDDED.iter().find(|(n, _)| *n == name).map(|(n, text)| {
            Self::from_toml_str(text, &format!("embedded {n}"))
                .expect("the embedded scenes are valid (checked by tests)")
        })
    }

    /// The frame rate of the scene's file sequence (its particles', else its volume's), if it
    /// reads one: the rate an animation of it takes unless told otherwise.
    pub fn sequence_rate_hz(&self) -> Option<f32> {
        let particles = self
            .particles
            .as_ref()
            .filter(|p| sequence::is_sequence(&p.file))
            .map(|p| p.frame_rate_hz);
        let volume = self
            .volume
            .as_ref()
            .filter(|v| v.is_sequence())
            .map(|v| v.frame_rate_hz);
        particles.or(volume)
    }

    /// The same scene at simulated time `time_s` (its `sim.duration_s`): what a frame of an
    /// animation renders.
    pub fn at_time(&self, time_s: f32) -> Self {
        let mut scene = self.clone();
        scene.sim.duration_s = time_s;
        scene
    }

    /// What the scene is, in a sentence: its `description`, or for an embedded scene that has
    /// none (the thesis scenes keep theirs empty, so their baselines' hash stays) and whose smoke,
    /// camera and light are the embedded scene's, the first sentence of its header comment
    /// ([`embedded_summary`]); empty otherwise.
    pub fn summary(&self) -> String {
        if !self.description.is_empty() {
            return self.description.clone();
        }
        match Self::embedded(&self.name) {
            Some(e)
                if e.emitters == self.emitters
                    && e.particles == self.particles
                    && e.camera == self.camera
                    && e.light == self.light =>
            {
                embedded_summary(&self.name).unwrap_or_default()
            }
            _ => String::new(),
        }
    }

    /// SHA-256 of the scene as the tool reads it (its canonical TOML, so comments and
    /// formatting do not count), hex-encoded: names what a baseline was rendered from.
    pub fn content_hash(&self) -> String {
        use sha2::Digest;
        let mut hasher = sha2::Sha256::new();
        hasher.update(self.to_toml().as_bytes());
        // A scene of a particle file is its frame's bytes too (an unreadable file hashes as
        // absent; reading it will report the problem).
        if let Some(source) = &self.particles {
            let path = source.path_at(self.sim.duration_s);
            hasher.update(source.folder.files.read(&path).unwrap_or_default());
        }
        if let Some(volume) = self.volume.as_ref().filter(|v| !v.file.is_empty()) {
            // A sequence's frame at the scene's time.
            let volume = volume.at_time(self.sim.duration_s);
            hasher.update(volume.file_bytes().unwrap_or_default());
        }
        let digest = hasher.finalize();
        digest.iter().map(|b| format!("{b:02x}")).collect()
    }

    /// Parses and validates a scene from TOML text; `origin` names it in error messages.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, SceneError> {
        let scene: Scene = toml::from_str(text).map_err(|err: toml::de::Error| {
            let message = err.message().trim().to_owned();
            match err.span() {
                // An error of the whole document (both `[emitter]` and `[[emitters]]`) has no
                // line of its own.
                None => SceneError::Invalid {
                    origin: origin.to_owned(),
                    message,
                },
                Some(span) => {
                    let (line, column) = line_column(text, span.start);
                    SceneError::Parse {
                        origin: origin.to_owned(),
                        line,
                        column,
                        message,
                    }
                }
            }
        })?;
        scene.validate().map_err(|message| SceneError::Invalid {
            origin: origin.to_owned(),
            message,
        })?;
        Ok(scene)
    }

    /// Reads, parses and validates a scene file of `files`; the files it names are read from
    /// its folder of `files`.
    pub fn load(path: &Path, files: &Files) -> Result<Self, SceneError> {
        let text = files
            .read_to_string(path)
            .map_err(|cause| SceneError::Read {
                path: path.to_owned(),
                hint: if cause.kind() == std::io::ErrorKind::NotFound {
                    format!("; embedded scenes: {}", embedded_names())
                } else {
                    String::new()
                },
                cause,
            })?;
        let mut scene = Self::from_toml_str(&text, &path.display().to_string())?;
        let folder = Folder::new(
            path.parent().map(Path::to_owned).unwrap_or_default(),
            files.clone(),
        );
        if let Some(source) = &mut scene.particles {
            source.folder = folder.clone();
        }
        if let Some(volume) = &mut scene.volume {
            volume.folder = folder;
        }
        Ok(scene)
    }

    /// A scene argument: the name of an embedded scene (`thesis_wind`), else a file path of
    /// `files`.
    pub fn open(name_or_path: &Path, files: &Files) -> Result<Self, SceneError> {
        match name_or_path.to_str().and_then(Self::embedded) {
            Some(scene) => Ok(scene),
            None => Self::load(name_or_path, files),
        }
    }

    /// The particles every emitter of the scene holds together.
    pub fn particle_count(&self) -> u64 {
        self.emitters.iter().map(|e| u64::from(e.count)).sum()
    }

    /// The scene with `count` particles in all, validated (the counts against [`LIMITS`]):
    /// each emitter keeps its share of the pool (at least one particle) and is scaled to its
    /// new count by [`Emitter::scaled_to`], so every emitter's smoke keeps its optical depth.
    pub fn with_particles(mut self, count: u32) -> Result<Self, SceneError> {
        if self.emitters.is_empty() {
            return Err(SceneError::Invalid {
                origin: self.name.clone(),
                message: "--particles scales the emitters, and this scene's particles come from \
                          a file ([particles])"
                    .to_owned(),
            });
        }
        let total = self.particle_count().max(1);
        let mut left = u64::from(count);
        let last = self.emitters.len() - 1;
        for (i, e) in self.emitters.iter_mut().enumerate() {
            let share = if i == last {
                left
            } else {
                (u64::from(count) * u64::from(e.count) / total).min(left)
            };
            left -= share;
            *e = e.scaled_to(share.clamp(1, u64::from(u32::MAX)) as u32);
        }
        self.validate().map_err(|message| SceneError::Invalid {
            origin: format!("{} at {count} particles", self.name),
            message,
        })?;
        Ok(self)
    }

    /// [`Scene::open`] of `arg`, or the embedded thesis scene when `arg` is `None`.
    pub fn load_or_default(arg: Option<&Path>, files: &Files) -> Result<Self, SceneError> {
        match arg {
            Some(arg) => Self::open(arg, files),
            None => Ok(Self::thesis_plume()),
        }
    }

    /// Serialises the scene back to TOML.
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).expect("a scene always serialises")
    }

    /// Checks every range; the error names the field, the value and the allowed range.
    pub fn validate(&self) -> Result<(), String> {
        validate::validate(self)
    }
}

/// 1-based line and column of a byte offset.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}
