//! A sweep's records and the answer read from them, for every app: the cells a sweep measured
//! ([`CellResult`]) and what they were measured on and against, the tables `results.csv` and
//! `results.json` as bytes ([`table`]), the cells that answer each budget ([`answer`]), and the
//! SVG charts ([`charts`]). The CLI's sweep (planning, the cells' files, shards, the HTML report)
//! and the web page's write the same records through these, so that their tables are one format.
//!
//! - [`plan`]: the cells a grid of techniques x budgets x resolutions lays out, and when a cell
//!   has timed enough frames;
//! - [`cell`]: one cell's warm-up, probe and timed frames on a renderer, up to its comparisons.

pub mod answer;
pub mod cell;
pub mod charts;
pub mod plan;
pub mod table;

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::render::ParticleRes;
use crate::shadow::SplatMode;

pub use crate::render::shaded::SHADED_STRIDE_PX;

/// The resolutions `tune` chose: technique -> memory budget (total bytes) -> map resolution.
/// A sweep's answer at equal total memory takes each technique at its chosen resolution (where
/// it swept it), so that shapes, like parameters, are chosen on scenes apart from the answer's.
pub type Shapes = BTreeMap<String, BTreeMap<u64, u32>>;

/// A technique's shape at one memory budget, as a parameter file's `[shapes]` records it: the
/// map resolution whose largest fitting configuration had the lowest mean RMS T error over the
/// training scenes, and that error.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Shape {
    pub resolution: u32,
    pub training: f64,
}

/// A parameter file's `[shapes]` table (technique -> memory budget in bytes, as a string key ->
/// shape) as [`Shapes`]; a key that is not a whole number is skipped.
pub fn shapes_of(table: &BTreeMap<String, BTreeMap<String, Shape>>) -> Shapes {
    table
        .iter()
        .map(|(technique, by_memory)| {
            let by_memory = by_memory
                .iter()
                .filter_map(|(total, s)| Some((total.parse().ok()?, s.resolution)))
                .collect();
            (technique.clone(), by_memory)
        })
        .collect()
}

/// The shapes the shipped defaults come with (`docs/tuned_params.toml`'s `[shapes]`, built in):
/// what the CLI's sweep and the page's answer at equal total memory take each technique at.
pub fn shipped_shapes() -> Shapes {
    /// The file's `[shapes]`, its other tables left to the CLI's reader.
    #[derive(Deserialize)]
    struct ShapesOnly {
        #[serde(default)]
        shapes: BTreeMap<String, BTreeMap<String, Shape>>,
    }
    toml::from_str::<ShapesOnly>(include_str!("../../../docs/tuned_params.toml"))
        .map(|f| shapes_of(&f.shapes))
        .unwrap_or_default()
}

/// Median, minimum and maximum of a measurement over the timed frames, milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    pub median: f64,
    pub min: f64,
    pub max: f64,
}

impl Timing {
    /// Median, minimum and maximum of `samples` (all zero when there are none).
    pub fn of(samples: &[f64]) -> Self {
        let mut v = samples.to_vec();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n == 0 {
            return Self::default();
        }
        let median = if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        };
        Self {
            median,
            min: v[0],
            max: v[n - 1],
        }
    }
}

/// Image error of a cell against a reference image.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImageError {
    /// FLIP mean (0 = identical).
    pub flip_mean: f64,
    /// RMSE of the sRGB values in [0, 1].
    pub rmse: f64,
}

impl ImageError {
    /// An image against itself (a cell that is its own baseline).
    pub const NONE: Self = Self {
        flip_mean: 0.0,
        rmse: 0.0,
    };

    /// The error a comparison's `metrics` give.
    pub fn of(metrics: &crate::diff::Metrics) -> Self {
        Self {
            flip_mean: metrics.flip_mean,
            rmse: metrics.rmse_srgb,
        }
    }
}

/// One finished cell of the sweep.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellResult {
    /// Registry name; `none` is the frame-time baseline the overhead ratios divide by.
    pub technique: String,
    /// The channel budget asked for (for a cell of a byte budget: the one that fits it).
    pub channels: u32,
    /// The byte budgets per shadow-map texel (`--bytes-per-texel`) this cell is the
    /// technique's configuration for ([`crate::shadow::fit_bytes_per_texel`]); empty when it
    /// answers none (and in cells written before the axis existed).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub byte_budgets: Vec<u32>,
    /// The memory budgets, total bytes (`--memory`), this cell is the technique's
    /// configuration for at its resolution; empty when it answers none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub memory_budgets: Vec<u64>,
    /// Whether `channels` is one of the channel budgets asked for (`--channels`): the thesis'
    /// channel view; a cell only a byte budget asked for is `false`.
    #[serde(default = "channel_axis_default")]
    pub channel_axis: bool,
    /// The channels the technique uses under it (e.g. fom: 2n + 1).
    pub channels_used: u32,
    /// Shadow-map resolution (texels per side).
    pub shadow_res: u32,
    pub splat: SplatMode,
    /// The particle pass's resolution (`1` in cells written before it was an axis).
    #[serde(default)]
    pub particle_res: ParticleRes,
    /// Bytes the technique held at its peak, scratch included (its memory ledger's
    /// [`crate::gpu::MemoryLedger::peak_bytes`], summed over the light's faces): what byte
    /// budgets, the answer and the Pareto fronts count. Cells written before the name changed
    /// called it `bytes` (and counted the allocations then live).
    #[serde(alias = "bytes")]
    pub resident_bytes: u64,
    /// The part of `resident_bytes` that is build scratch the lookup never reads (a deep
    /// capture's lists, the volume's voxelisation); 0 for most techniques, and in cells written
    /// before it existed.
    #[serde(default)]
    pub transient_bytes: u64,
    /// Texels of the light's `shadow_res`² map (summed over a point light's faces) whose ray
    /// crosses smoke in this cell's frame ([`crate::shadow::LightSpace::texels_covering_smoke`]),
    /// in the scene's framing (`shadow.framing`): what a map's resolution buys on this smoke.
    /// The same for every technique at one resolution; 0 in cells written before it existed.
    #[serde(default)]
    pub smoke_texels: u64,
    /// GPU time of the technique's shadow build passes.
    pub gpu_shadow_ms: Timing,
    /// GPU time of everything else in the frame: opaque, particles (with their lighting), tone
    /// map.
    pub gpu_render_ms: Timing,
    /// CPU time of the particle sort(s).
    pub cpu_sort_ms: Timing,
    /// Per frame: all GPU passes plus the CPU sort (the thesis' "build + render, sorting
    /// included").
    pub frame_ms: Timing,
    /// Per frame: wall-clock time of the render call until its GPU work finished.
    pub wall_ms: Timing,
    /// GPU time of the `particles` passes (their lighting and the draw, at `particle_res`).
    #[serde(default)]
    pub particles_ms: Timing,
    /// GPU time of a lower particle resolution's depth downsample and upsample (0 at full).
    #[serde(default)]
    pub upsample_ms: Timing,
    /// Fragment shader invocations of the last frame's particle pass (pipeline-statistics
    /// query; `None` without one, or for a technique that draws its own particle pass).
    #[serde(default)]
    pub particle_fragments: Option<u64>,
    /// Frames the medians are over (fewer than asked when the cell ran out of its seconds).
    #[serde(default)]
    pub frames_timed: u32,
    /// `frame_ms.median` / the `none` cell's `frame_ms.median` from the same run.
    pub overhead_ratio: Option<f64>,
    /// `gpu_shadow_ms.median` / the `none` cell's `frame_ms.median` from the same run: the
    /// build's share of an unshadowed frame.
    #[serde(default)]
    pub shadow_ratio: Option<f64>,
    /// Against the same technique at 24 channels (same resolution and splat); `None` for `none`.
    pub vs_own_24: Option<ImageError>,
    /// Against the `exact` reference image; `None` for `none`.
    pub vs_exact: Option<ImageError>,
    /// Against the same cell with its particles at full resolution (0 for a full-resolution
    /// cell); `None` for `none`.
    #[serde(default)]
    pub vs_full_res: Option<ImageError>,
    /// RMS difference of T from `exact` over the points the camera view shades (particle
    /// lighting points and lit opaque points); `None` for `none`.
    pub rms_transmittance_error: Option<f64>,
    /// Files, relative to the sweep folder.
    pub image: String,
    pub diff_own_24: Option<String>,
    pub flip_own_24: Option<String>,
    pub diff_exact: Option<String>,
    pub flip_exact: Option<String>,
    /// The linear HDR frame as OpenEXR (`--exr`).
    #[serde(default)]
    pub hdr_image: Option<String>,
    /// Identifies the settings this cell was measured with (scene, size, frames, warm-up, the
    /// technique's parameters, tool version): `--resume` reuses a cell only when it matches,
    /// and `--merge` merges only shards whose cells agree on it.
    pub settings_key: String,
    /// What this cell's ratios and errors were measured against, in the process that measured
    /// it (a shard measures its own `none` and `exact`); `None` in cells written before it
    /// existed, whose ratios are against the `none` cell of the results.
    #[serde(default)]
    pub measured_against: Option<MeasuredAgainst>,
    /// With `--animate`: the cell over the span against `exact` over it ([`crate::motion`]);
    /// `None` for `none` and in a still sweep.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion: Option<crate::motion::Motion>,
}

impl CellResult {
    /// The bytes it keeps for the lookup: its resident bytes less the transient build scratch
    /// (reported apart; byte budgets count the resident bytes).
    pub fn persistent_bytes(&self) -> u64 {
        self.resident_bytes.saturating_sub(self.transient_bytes)
    }

    /// Sets its overhead and shadow ratios: against the `none` frame time of the process that
    /// measured it, or for a cell written before that was recorded, against `results_none`
    /// (the `none` cell of the results).
    pub fn set_ratios(&mut self, results_none: Option<f64>) {
        let baseline = self
            .measured_against
            .as_ref()
            .map(|a| a.none_frame_ms)
            .or(results_none)
            .filter(|b| b.is_finite() && *b > 0.0);
        self.overhead_ratio = baseline.map(|b| self.frame_ms.median / b);
        self.shadow_ratio = baseline.map(|b| self.gpu_shadow_ms.median / b);
    }
}

/// Position of a technique in the registry (reports list and break ties in its order); past
/// the end for a name it does not hold.
pub fn registry_index(name: &str) -> usize {
    crate::shadow::REGISTRY
        .iter()
        .position(|e| e.name == name)
        .unwrap_or(usize::MAX)
}

fn channel_axis_default() -> bool {
    true
}

/// What techniques are compared at: a channel budget (the thesis' view) or a byte budget per
/// shadow-map texel (equal memory, the answer's).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Budget {
    Channels(u32),
    BytesPerTexel(u32),
}

impl Budget {
    /// Sorts byte budgets before channel budgets, the larger first in each.
    pub fn order(self) -> (u8, std::cmp::Reverse<u32>) {
        match self {
            Self::BytesPerTexel(b) => (0, std::cmp::Reverse(b)),
            Self::Channels(c) => (1, std::cmp::Reverse(c)),
        }
    }

    /// Whether the advice counts it as small: at most 8 channels, or 16 bytes a texel (what
    /// `osm`'s 8 half-float slices keep).
    pub fn is_small(self) -> bool {
        match self {
            Self::Channels(c) => c <= 8,
            Self::BytesPerTexel(b) => b <= 16,
        }
    }
}

impl std::fmt::Display for Budget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Channels(c) => write!(f, "{c} channels"),
            Self::BytesPerTexel(b) => write!(f, "{b} bytes a texel"),
        }
    }
}

/// The machine a cell was measured on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Machine {
    pub adapter: String,
    pub backend: String,
    pub driver: String,
    /// Whether the GPU times come from timestamp queries (if not, they are absent: 0).
    pub timestamp_queries: bool,
    /// The round trip of an empty submission on it ([`crate::gpu::Gpu::clock_floor_ms`]).
    #[serde(default)]
    pub clock_floor_ms: f64,
}

impl Machine {
    pub async fn of(gpu: &crate::gpu::Gpu) -> Self {
        Self {
            adapter: gpu.info.name.clone(),
            backend: format!("{:?}", gpu.info.backend),
            driver: format!("{} {}", gpu.info.driver, gpu.info.driver_info)
                .trim()
                .to_owned(),
            timestamp_queries: gpu.has_timestamps(),
            clock_floor_ms: gpu.clock_floor_ms().await,
        }
    }
}

/// The SHA-256 of an image's 8-bit pixels, hex ([`MeasuredAgainst::exact_image_sha256`]).
pub fn image_sha256(image: &image::RgbImage) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(image.as_raw())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The framing of results and plans written before `shadow.framing` existed.
pub fn cone_framing() -> crate::scene::Framing {
    crate::scene::Framing::Cone
}

/// What a cell's ratios and errors depend on, recorded in the cell by the process that measured
/// it: every process that measures cells of a scene measures `none` and renders `exact` itself
/// first, so a cell is self-contained wherever it was measured.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeasuredAgainst {
    /// The median frame time of `none` measured by the same process just before its first cell
    /// of the scene: `overhead_ratio` = `frame_ms.median` / this.
    pub none_frame_ms: f64,
    /// The `exact` reference the errors are against: its bytes, light tiles per side, and the
    /// SHA-256 of its 8-bit RGB pixels (equal across processes on one machine, which lavapipe
    /// renders bit-identically; another CPU may differ by 1/255 in a few pixels).
    pub exact_bytes: u64,
    pub exact_tiles: u32,
    pub exact_image_sha256: String,
    /// `exact`'s self-check against the f64 closed form (core/src/render/reference_check.rs): the
    /// shaded points compared and the worst |ΔT| (`None` in cells measured before the check).
    #[serde(default)]
    pub exact_check_points: usize,
    #[serde(default)]
    pub exact_check_worst: Option<f64>,
    pub machine: Machine,
    /// The shard that measured it (`None`: an unsharded run).
    pub shard: Option<Shard>,
    /// With `--animate`: the span and `exact`'s own change over it (the scale the cells'
    /// temporal errors are read against), and its self-check over every frame of it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion: Option<MotionReference>,
}

/// `exact` over an animated sweep's span ([`MeasuredAgainst::motion`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MotionReference {
    pub change: crate::motion::ReferenceChange,
    /// The fewest points a frame's self-check compared, and the worst |ΔT| over the frames.
    pub check_points: usize,
    pub check_worst: f64,
}

/// A requested cell that was not run, and why (a budget below the technique's minimum).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SkippedCell {
    pub technique: String,
    pub channels: u32,
    /// The byte budget per texel it was skipped at (`channels` is then 0), if it was one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bytes_per_texel: Option<u32>,
    /// The memory budget (total bytes) and the resolution it was skipped at, if it was one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub memory: Option<(u64, u32)>,
    pub reason: String,
}

impl SkippedCell {
    /// The budget it was skipped at, as the CLI, the report and the page name it: "24 bytes a
    /// texel", "12.0 MiB at 512²" (a memory budget in all, at a map resolution) or "8 channels".
    pub fn budget(&self) -> String {
        match (self.bytes_per_texel, self.memory) {
            (Some(b), _) => format!("{b} bytes a texel"),
            (None, Some((total, res))) => format!("{} at {res}²", crate::gpu::memory::bytes(total)),
            (None, None) => format!("{} channels", self.channels),
        }
    }
}

/// What a sweep ran on and with.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SweepMetadata {
    pub tool_version: String,
    pub scene: String,
    /// The scene's `shadow.framing`, every technique's (`cone` in results written before it
    /// existed, which all framed the cone).
    #[serde(default = "cone_framing")]
    pub framing: crate::scene::Framing,
    /// The map resolution `tune` chose per technique and memory budget (total bytes) on the
    /// training scenes: the answer at equal total memory takes each technique at it.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub shapes: Shapes,
    /// The scene's one-sentence description (may be empty).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    /// SHA-256 of the scene's canonical TOML.
    pub scene_sha256: String,
    pub seed: u64,
    pub particles: u32,
    pub width_px: u32,
    pub height_px: u32,
    /// The adapter, backend and driver the cells were measured on (several, `; `-separated,
    /// when shards ran on different machines).
    pub adapter: String,
    pub backend: String,
    pub driver: String,
    /// Whether the GPU times come from timestamp queries (if not, they are absent: 0).
    pub timestamp_queries: bool,
    /// The largest round trip of an empty submission among the machines
    /// ([`crate::gpu::Gpu::clock_floor_ms`]): what a frame's wall time pays beyond its passes.
    #[serde(default)]
    pub clock_floor_ms: f64,
    pub frames: u32,
    pub warmup: u32,
    /// Light-space tiles per side of the `exact` reference every cell is compared with.
    pub exact_tiles: u32,
    /// Bytes `exact` allocated.
    pub exact_bytes: u64,
    /// `exact`'s self-check over every process that measured cells: the fewest points one
    /// compared, and the worst |ΔT| against the f64 closed form (`None`: cells from before it).
    #[serde(default)]
    pub exact_check_points: usize,
    #[serde(default)]
    pub exact_check_worst: Option<f64>,
    /// RFC 3339 (UTC) start of this run, and its wall time in seconds (for results merged
    /// from shards: the earliest shard's start and the sum of the shards' wall times).
    pub started: String,
    pub wall_s: f64,
    /// The shards the cells came from, `K/N` each (empty for an unsharded run).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub shards: Vec<String>,
    /// With `--animate`: the span and `exact`'s change over it ([`MeasuredAgainst::motion`], of
    /// the first cell that has it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion: Option<MotionReference>,
}

/// The scene a sweep's results are of, as its plan records it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneHeader {
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub scene_sha256: String,
    pub seed: u64,
    pub particles: u32,
    pub width_px: u32,
    pub height_px: u32,
    /// The scene's `shadow.framing` (plans written before it existed framed the cone).
    #[serde(default = "cone_framing")]
    pub framing: crate::scene::Framing,
    /// The map resolutions `tune` chose, per technique and memory budget.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub shapes: Shapes,
}

impl SceneHeader {
    /// The header of `scene` holding `particles` particles, whose
    /// [`crate::scene::Scene::content_hash`] is `scene_sha256`.
    pub fn of(
        scene: &crate::scene::Scene,
        particles: u32,
        scene_sha256: String,
        shapes: Shapes,
    ) -> Self {
        Self {
            name: scene.name.clone(),
            description: scene.summary(),
            scene_sha256,
            seed: scene.emitters.first().map_or(0, |e| e.seed),
            particles,
            width_px: scene.output.width_px,
            height_px: scene.output.height_px,
            framing: scene.shadow.framing,
            shapes,
        }
    }
}

/// What a scene's results are assembled from besides its header and cells
/// ([`SweepResults::assemble`]).
#[derive(Clone, Debug)]
pub struct RunRecord<'a> {
    pub tool_version: &'a str,
    pub frames: u32,
    pub warmup: u32,
    /// The machine, for a scene none of whose cells record one yet.
    pub fallback: Option<&'a Machine>,
    /// `exact`'s bytes and tiles, for cells written before they recorded them.
    pub exact: Option<(u64, u32)>,
    /// RFC 3339 (UTC) start, wall seconds, and the shards the cells came from (`K/N` each).
    pub started: String,
    pub wall_s: f64,
    pub shards: Vec<String>,
    /// Relative paths of `exact`'s image and of its HDR frame (if written).
    pub exact_image: String,
    pub exact_hdr_image: Option<String>,
}

/// Everything a sweep produced: written as `results.json` (and, a row per cell, `results.csv`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SweepResults {
    pub metadata: SweepMetadata,
    /// In run order: the `none` baseline first, then technique by technique.
    pub cells: Vec<CellResult>,
    pub skipped: Vec<SkippedCell>,
    /// Relative path of the `exact` reference image.
    pub exact_image: String,
    /// And of its HDR frame as OpenEXR (`--exr`).
    #[serde(default)]
    pub exact_hdr_image: Option<String>,
    /// With `--animate`: the span's frames of `exact` and a few chosen cells side by side, as
    /// an animated PNG ([`Animation`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub animation: Option<Animation>,
}

impl SweepResults {
    /// A scene's results from its header, its cells finished so far (in plan order) and the
    /// cells it skipped, with the overhead ratios against its `none` cell
    /// ([`CellResult::set_ratios`]). The machine and the `exact` figures come from the cells'
    /// records ([`CellResult::measured_against`]); `run`'s fallbacks stand in for cells
    /// written before those existed.
    pub fn assemble(
        header: &SceneHeader,
        run: RunRecord<'_>,
        cells: &[CellResult],
        skipped: Vec<SkippedCell>,
    ) -> Self {
        let against: Vec<&MeasuredAgainst> = cells
            .iter()
            .filter_map(|c| c.measured_against.as_ref())
            .collect();
        let distinct = |field: &dyn Fn(&Machine) -> String, fallback: Option<String>| {
            let mut values: Vec<String> = Vec::new();
            for a in &against {
                let v = field(&a.machine);
                if !values.contains(&v) {
                    values.push(v);
                }
            }
            if values.is_empty() {
                values.extend(fallback);
            }
            values.join("; ")
        };
        let exact = against
            .first()
            .map(|a| (a.exact_bytes, a.exact_tiles))
            .or(run.exact)
            .unwrap_or((0, 0));
        let metadata = SweepMetadata {
            tool_version: run.tool_version.to_owned(),
            scene: header.name.clone(),
            description: header.description.clone(),
            scene_sha256: header.scene_sha256.clone(),
            seed: header.seed,
            particles: header.particles,
            width_px: header.width_px,
            height_px: header.height_px,
            framing: header.framing,
            shapes: header.shapes.clone(),
            adapter: distinct(
                &|m| m.adapter.clone(),
                run.fallback.map(|m| m.adapter.clone()),
            ),
            backend: distinct(
                &|m| m.backend.clone(),
                run.fallback.map(|m| m.backend.clone()),
            ),
            driver: distinct(
                &|m| m.driver.clone(),
                run.fallback.map(|m| m.driver.clone()),
            ),
            timestamp_queries: match against.is_empty() {
                true => run.fallback.is_some_and(|m| m.timestamp_queries),
                false => against.iter().all(|a| a.machine.timestamp_queries),
            },
            clock_floor_ms: against
                .iter()
                .map(|a| a.machine.clock_floor_ms)
                .chain(run.fallback.map(|m| m.clock_floor_ms))
                .fold(0.0, f64::max),
            frames: run.frames,
            warmup: run.warmup,
            exact_tiles: exact.1,
            exact_bytes: exact.0,
            exact_check_points: against
                .iter()
                .map(|a| a.exact_check_points)
                .min()
                .unwrap_or(0),
            exact_check_worst: against
                .iter()
                .map(|a| a.exact_check_worst)
                .reduce(|a, b| Some(a?.max(b?)))
                .flatten(),
            started: run.started,
            wall_s: run.wall_s,
            shards: run.shards,
            motion: against.iter().find_map(|a| a.motion.clone()),
        };
        let baseline = cells
            .iter()
            .find(|c| c.technique == crate::shadow::frame_baseline().name)
            .map(|c| c.frame_ms.median);
        let cells = cells
            .iter()
            .cloned()
            .map(|mut c| {
                c.set_ratios(baseline);
                c
            })
            .collect();
        SweepResults {
            metadata,
            cells,
            skipped,
            exact_image: run.exact_image,
            exact_hdr_image: run.exact_hdr_image,
            animation: None,
        }
    }
}

/// An animated sweep's side-by-side: `exact` and the cells [`answer::animated_cells`] chose,
/// left to right, each frame of the span at half size, as an animated PNG (APNG: every
/// browser plays it, and a viewer that does not shows its first frame).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Animation {
    /// Relative to the scene's folder.
    pub file: String,
    /// The tiles' labels, left to right (`exact` first).
    pub tiles: Vec<String>,
}

/// `--shard K/N`: this process runs the cells whose stable index is K mod N.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    pub k: u32,
    pub n: u32,
}

impl Shard {
    /// Whether the cell with stable index `index` is this shard's.
    pub fn owns(&self, index: usize) -> bool {
        index % self.n as usize == self.k as usize
    }

    /// The shard a cell with stable index `index` belongs to in a split of `n`.
    pub fn of(index: usize, n: u32) -> Self {
        Self {
            k: (index % n as usize) as u32,
            n,
        }
    }

    /// The manifest's file name, `K-of-N.json`.
    pub fn manifest_name(&self) -> String {
        format!("{}-of-{}.json", self.k, self.n)
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.k, self.n)
    }
}

impl std::str::FromStr for Shard {
    type Err = String;
    /// `K/N` with 0 <= K < N.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || format!("\"{s}\" is not K/N (shard K of N, 0 <= K < N, e.g. 0/4)");
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let k: u32 = k.trim().parse().map_err(|_| bad())?;
        let n: u32 = n.trim().parse().map_err(|_| bad())?;
        if n == 0 {
            return Err(format!("\"{s}\": N must be at least 1"));
        }
        if k >= n {
            return Err(format!(
                "\"{s}\": K must be below N (shards of {n} are 0..={})",
                n - 1
            ));
        }
        Ok(Self { k, n })
    }
}
