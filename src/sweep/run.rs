//! The sweep engine: plans the cells, renders and times each one on one long-lived renderer
//! (pipelines are rebuilt only when the technique changes; the particles are simulated once),
//! compares it with its own 24-channel image and with `exact`, and persists it.

use crate::Wait;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;

use super::cells::{EXACT_HDR_IMAGE, EXACT_IMAGE, assemble, read_cell, with_ratios, write_results};
use super::shard::{self, PlannedCell, PlannedScene, Shard, ShardManifest};
use super::{CellResult, ImageError, Machine, MeasuredAgainst, SkippedCell, SweepResults, Timing};
use crate::diff;
use crate::progress::Progress;
use smokeshadow_core::gpu::Gpu;
use smokeshadow_core::render::shaded::{frame_points, rms_difference};
use smokeshadow_core::render::{
    OUTPUT_FORMAT, OffscreenTarget, ParticleRes, RenderOptions, Renderer, TechniqueConfig,
};
use smokeshadow_core::scene::Scene;
use smokeshadow_core::shadow::{self, SplatMode};
use smokeshadow_core::sim::Particle;

/// What to sweep. [`SweepOptions::default`] is the thesis experiment (chapter 4.2.1).
#[derive(Clone, Debug)]
pub struct SweepOptions {
    pub techniques: Vec<String>,
    pub channels: Vec<u32>,
    /// Byte budgets per shadow-map texel (`--bytes-per-texel`): each technique at the largest
    /// configuration whose resident bytes fit each ([`shadow::fit_bytes_per_texel`]); may be
    /// empty.
    pub bytes_per_texel: Vec<u32>,
    /// Memory budgets in total bytes (`--memory`): at each map resolution, each technique at
    /// the largest configuration whose resident bytes fit (a whole number of bytes a texel at
    /// that resolution), and the answer at each names every technique at its tuned resolution
    /// ([`Self::shapes`]) or its most accurate of the swept; may be empty.
    pub memory: Vec<u64>,
    pub shadow_res: Vec<u32>,
    pub splats: Vec<SplatMode>,
    /// Resolutions of the particle pass (`--particle-res`; each its own cell).
    pub particle_res: Vec<ParticleRes>,
    /// Timed frames per cell (medians over these) and untimed warm-up frames before them.
    pub frames: u32,
    pub warmup: u32,
    /// Seconds of timed frames a cell keeps within (`timed_enough`: after at least
    /// `MIN_TIMED_FRAMES`, or `MIN_SLOW_FRAMES` of frames each longer than this), so a slow
    /// technique does not hold the sweep: its medians are over fewer frames, and the cell says
    /// how many (`frames_timed`).
    pub cell_seconds: f64,
    /// Reuse cells already finished with identical settings.
    pub resume: bool,
    /// Also write every cell's linear HDR frame as OpenEXR beside its PNG.
    pub exr: bool,
    /// The gallery layout (`--scenes`): each scene's sweep in `DIR/<scene name>/`, and a gallery
    /// report over them at `DIR`.
    pub gallery: bool,
    /// Run only the cells whose stable index is K mod N, and write a shard manifest instead of
    /// the tables and report.
    pub shard: Option<Shard>,
    /// The map resolution `tune` chose per technique and memory budget on the training scenes
    /// (the shipped `docs/tuned_params.toml`'s, or a `--params FILE`'s): the answer at equal
    /// total memory takes each technique at it where it was swept.
    pub shapes: crate::tune::Shapes,
    /// `--animate`: every cell also rendered over these consecutive frames beside `exact` at
    /// each, its temporal measures in the cell ([`crate::motion`]).
    pub animate: Option<smokeshadow_core::motion::Span>,
}

impl Default for SweepOptions {
    fn default() -> Self {
        Self {
            techniques: shadow::default_sweep(),
            channels: vec![24, 16, 8, 6],
            bytes_per_texel: DEFAULT_BYTES_PER_TEXEL.to_vec(),
            memory: Vec::new(),
            shadow_res: vec![512],
            splats: vec![SplatMode::Segment],
            particle_res: vec![ParticleRes::Full],
            frames: 20,
            warmup: 1,
            cell_seconds: 0.5,
            resume: false,
            exr: false,
            gallery: false,
            shard: None,
            shapes: crate::tune::shipped_shapes(),
            animate: None,
        }
    }
}

/// The default byte budgets per texel: what `osm`'s half-float slices take at 6, 12 and 24
/// channels, the thesis' range.
pub const DEFAULT_BYTES_PER_TEXEL: [u32; 3] = [48, 24, 12];

/// Timed frames a cell takes at least, whatever `cell_seconds` says (fewer only when
/// `frames` asks for fewer, or [`MIN_SLOW_FRAMES`] when each frame outlasts `cell_seconds`).
pub const MIN_TIMED_FRAMES: u32 = 3;
/// Timed frames a cell takes at least when every frame took longer than `cell_seconds` on its
/// own: a deep capture's frames of seconds on lavapipe vary by a few percent, and a third one
/// would cost `dsm` 2.3 s a cell.
pub const MIN_SLOW_FRAMES: u32 = 2;

/// Whether a cell has timed enough frames (`frame_s`, wall seconds each) after `elapsed_s` of
/// timing: `frames` of them; or at least [`MIN_TIMED_FRAMES`], once one more frame, as long as
/// the frames so far took on average, would take the timing past `cell_seconds`; or
/// [`MIN_SLOW_FRAMES`] when each of them alone took longer than `cell_seconds`.
pub fn timed_enough(frame_s: &[f64], elapsed_s: f64, frames: u32, cell_seconds: f64) -> bool {
    let n = frame_s.len() as u32;
    if n >= frames {
        return true;
    }
    if n >= MIN_TIMED_FRAMES {
        return elapsed_s + elapsed_s / f64::from(n) > cell_seconds;
    }
    n >= MIN_SLOW_FRAMES && frame_s.iter().all(|&s| s > cell_seconds)
}

/// The budget every cell's "own baseline" uses (the thesis' baselines).
const BASELINE_CHANNELS: u32 = 24;

/// One planned cell.
#[derive(Clone, Debug)]
struct Plan {
    name: String,
    config: TechniqueConfig,
    particle_res: ParticleRes,
    /// The byte budgets per texel this cell is the technique's configuration for.
    byte_budgets: Vec<u32>,
    /// The memory budgets (total bytes) it is the configuration for at its resolution.
    memory_budgets: Vec<u64>,
    /// Whether a channel budget asked for it (else only byte budgets did).
    channel_axis: bool,
}

impl Plan {
    fn new(scene: &Scene, technique: &str, channels: u32, res: u32, splat: SplatMode) -> Self {
        let mut params = scene.shadow.params(channels);
        params.resolution_px = res;
        params.splat = splat;
        let name = if technique == shadow::frame_baseline().name {
            technique.to_owned()
        } else {
            format!("{technique}_{channels}_{res}_{}", splat.name())
        };
        Self {
            name,
            config: TechniqueConfig {
                name: technique.to_owned(),
                params,
            },
            particle_res: ParticleRes::Full,
            byte_budgets: Vec::new(),
            memory_budgets: Vec::new(),
            channel_axis: true,
        }
    }

    /// The same cell with the particle pass at `res`: its name gains `_p2` or `_p4` (a
    /// full-resolution cell keeps the name it always had).
    fn at(mut self, res: ParticleRes) -> Self {
        if res != ParticleRes::Full {
            self.name = format!("{}_p{}", self.name, res.divisor());
        }
        self.particle_res = res;
        self
    }

    /// Its frame's file, relative to the scene's folder.
    fn image(&self) -> String {
        format!("images/{}.png", self.name)
    }

    fn options(&self) -> RenderOptions {
        RenderOptions {
            particle_res: self.particle_res,
            ..RenderOptions::default()
        }
    }
}

/// Checks the options and lays out the cells: the `none` baseline, then per resolution, splat
/// mode and technique its budgets. Budgets below a technique's minimum are skipped with a note;
/// techniques that ignore the splat mode run once per resolution.
fn plan(scene: &Scene, options: &SweepOptions) -> anyhow::Result<(Vec<Plan>, Vec<SkippedCell>)> {
    let non_empty = |what: &str, empty: bool| {
        if empty {
            anyhow::bail!("--{what} is empty: give at least one value");
        }
        Ok(())
    };
    non_empty("techniques", options.techniques.is_empty())?;
    non_empty("channels", options.channels.is_empty())?;
    // The largest channel budget any technique takes (`has`'s slices, above the maps' 32).
    let most_channels = shadow::REGISTRY
        .iter()
        .map(|e| e.max_channels)
        .max()
        .unwrap_or(shadow::MAX_CHANNELS);
    non_empty("shadow-res", options.shadow_res.is_empty())?;
    non_empty("splat", options.splats.is_empty())?;
    non_empty("particle-res", options.particle_res.is_empty())?;
    if options.frames == 0 {
        anyhow::bail!("--frames 0: time at least one frame");
    }
    for &res in &options.shadow_res {
        if !(1..=8192).contains(&res) {
            anyhow::bail!("--shadow-res {res} is out of range: allowed 1..=8192");
        }
    }
    if let Some(span) = options.animate {
        check_sequence_frames(scene, &span)?;
    }
    let mut cells = vec![
        Plan::new(
            scene,
            shadow::frame_baseline().name,
            1,
            options.shadow_res[0],
            options.splats[0],
        )
        .at(options.particle_res[0]),
    ];
    let mut skipped = Vec::new();
    // What the scene's smoke holds, for the techniques that cannot shadow it (`srm` particles,
    // `has` a density volume): noted, not measured.
    let smoke = (
        scene.volume.is_some(),
        crate::particles::count(scene) as usize,
    );
    // Why a technique cannot run on this scene at all: its smoke, or its shadow history.
    let refused = |entry: &shadow::TechniqueEntry| {
        entry
            .refusal(smoke.0, smoke.1)
            .or_else(|| entry.history_refusal(scene.shadow.history))
    };
    for name in &options.techniques {
        let entry = shadow::find(name)?;
        if entry.role != shadow::Role::Contender {
            anyhow::bail!(
                "--techniques {name}: `{}` and `{}` are the sweep's baseline and reference, always measured; list the techniques to compare",
                shadow::frame_baseline().name,
                shadow::reference().name
            );
        }
        if let Some(refusal) = refused(entry) {
            skipped.push(SkippedCell {
                technique: entry.name.to_owned(),
                channels: first_budget(entry, &options.channels).unwrap_or(options.channels[0]),
                bytes_per_texel: None,
                memory: None,
                reason: refusal.to_string(),
            });
            continue;
        }
        for &b in &options.channels {
            if !(1..=most_channels).contains(&b) {
                let beyond: Vec<String> = shadow::REGISTRY
                    .iter()
                    .filter(|e| e.max_channels > shadow::MAX_CHANNELS)
                    .map(|e| format!("{} to {}", e.name, e.max_channels))
                    .collect();
                anyhow::bail!(
                    "--channels {b} is out of range: allowed 1..={most_channels} (above {}: {})",
                    shadow::MAX_CHANNELS,
                    beyond.join(", ")
                );
            }
            if let Err(err) = shadow::check_channels(entry, b) {
                skipped.push(SkippedCell {
                    technique: entry.name.to_owned(),
                    channels: b,
                    bytes_per_texel: None,
                    memory: None,
                    reason: err.to_string(),
                });
            } else if !entry.uses_budget && Some(b) != first_budget(entry, &options.channels) {
                skipped.push(SkippedCell {
                    technique: entry.name.to_owned(),
                    channels: b,
                    bytes_per_texel: None,
                    memory: None,
                    reason: format!(
                        "{} gives the same result at any budget ({}): measured once, at {} channels",
                        entry.name,
                        (entry.budget_caption)(b),
                        first_budget(entry, &options.channels).unwrap_or(b)
                    ),
                });
            }
        }
    }
    for &particle_res in &options.particle_res {
        if particle_res == ParticleRes::Full {
            continue;
        }
        for name in &options.techniques {
            let entry = shadow::find(name)?;
            if entry.owns_particle_pass
                && let Some(b) = first_budget(entry, &options.channels)
            {
                skipped.push(SkippedCell {
                    technique: entry.name.to_owned(),
                    channels: b,
                    bytes_per_texel: None,
                    memory: None,
                    reason: shadow::ShadowError::ParticleResUnsupported {
                        technique: entry.name,
                        res: particle_res.name(),
                    }
                    .to_string(),
                });
            }
        }
    }
    for &res in &options.shadow_res {
        for &particle_res in &options.particle_res {
            for (s, &splat) in options.splats.iter().enumerate() {
                for name in &options.techniques {
                    let entry = shadow::find(name)?;
                    if s > 0 && !entry.uses_splat
                        || particle_res != ParticleRes::Full && entry.owns_particle_pass
                        || refused(entry).is_some()
                    {
                        continue;
                    }
                    for &b in &options.channels {
                        let once =
                            entry.uses_budget || Some(b) == first_budget(entry, &options.channels);
                        if shadow::check_channels(entry, b).is_ok() && once {
                            cells
                                .push(Plan::new(scene, entry.name, b, res, splat).at(particle_res));
                        }
                    }
                    let first_axes = s == 0 && particle_res == options.particle_res[0];
                    for &total in &options.memory {
                        let planned = shadow::memory_per_texel(total, res).and_then(|bytes| {
                            plan_byte_budget(
                                scene,
                                entry,
                                Budget::Memory(bytes, total),
                                (res, splat, particle_res),
                                &mut cells,
                            )
                        });
                        if let Err(reason) = planned
                            && first_axes
                        {
                            skipped.push(SkippedCell {
                                technique: entry.name.to_owned(),
                                channels: 0,
                                bytes_per_texel: None,
                                memory: Some((total, res)),
                                reason,
                            });
                        }
                    }
                    for &bytes in &options.bytes_per_texel {
                        if let Err(reason) = plan_byte_budget(
                            scene,
                            entry,
                            Budget::PerTexel(bytes),
                            (res, splat, particle_res),
                            &mut cells,
                        ) && first_axes
                            && res == options.shadow_res[0]
                        {
                            skipped.push(SkippedCell {
                                technique: entry.name.to_owned(),
                                channels: 0,
                                bytes_per_texel: Some(bytes),
                                memory: None,
                                reason,
                            });
                        }
                    }
                }
            }
        }
    }
    Ok((cells, skipped))
}

/// Every frame of `span` of the scene's file sequences (its particles', its volume's) is there
/// before anything is rendered; else one line naming the first missing file.
fn check_sequence_frames(
    scene: &Scene,
    span: &smokeshadow_core::motion::Span,
) -> anyhow::Result<()> {
    // (what, its pattern, each time's frame and path) of each sequence the scene reads.
    let particles = scene
        .particles
        .as_ref()
        .filter(|s| crate::particles::is_sequence(&s.file))
        .map(|s| {
            let at: Vec<_> = span
                .times()
                .into_iter()
                .map(|t| (t, s.frame_at(t), s.path_at(t)))
                .collect();
            ("particle file", s.file.as_str(), at)
        });
    let volume = scene.volume.as_ref().filter(|v| v.is_sequence()).map(|v| {
        let at: Vec<_> = span
            .times()
            .into_iter()
            .map(|t| (t, v.frame_at(t), v.at_time(t).path()))
            .collect();
        ("volume file", v.file.as_str(), at)
    });
    for (what, pattern, at) in particles.into_iter().chain(volume) {
        if let Some((t, frame, path)) = at.into_iter().find(|(_, _, path)| !path.is_file()) {
            anyhow::bail!(
                "--animate: {}'s {what} at t = {t} s is frame {frame} of {pattern}, and {} does not exist",
                scene.name,
                path.display()
            );
        }
    }
    Ok(())
}

/// Adds `bytes` per texel to the cell of `entry`'s configuration that fits it (the
/// [`shadow::fit_bytes_per_texel`] at the scene's particles and frame): a cell already planned
/// with the same channels used (a channel budget's, or another byte budget's) answers it too;
/// else a new cell, off the channel axis. A technique whose result does not depend on the
/// budget answers every byte budget it fits with its one cell. The cell's technique is held to
/// the smallest budget's bytes ([`shadow::TechniqueParams::memory_limit_bytes`]). `Err`: why
/// it fits none.
fn plan_byte_budget(
    scene: &Scene,
    entry: &'static shadow::TechniqueEntry,
    budget: Budget,
    (res, splat, particle_res): (u32, SplatMode, ParticleRes),
    cells: &mut Vec<Plan>,
) -> Result<(), String> {
    let bytes = match budget {
        Budget::PerTexel(b) | Budget::Memory(b, _) => b,
    };
    let record = |p: &mut Plan| match budget {
        Budget::PerTexel(b) => p.byte_budgets.push(b),
        Budget::Memory(_, total) => p.memory_budgets.push(total),
    };
    let base = Plan::new(scene, entry.name, entry.min_channels, res, splat).at(particle_res);
    let particles = crate::particles::count(scene);
    let pixels = u64::from(scene.output.width_px) * u64::from(scene.output.height_px);
    let fit = shadow::fit_bytes_per_texel(entry, &base.config.params, bytes, particles, pixels)?;
    let used = |p: &Plan| shadow::planned_use(entry, &p.config.params, particles, pixels);
    let same = cells.iter_mut().find(|p| {
        p.config.name == entry.name
            && p.config.params.resolution_px == res
            && p.config.params.splat == splat
            && p.particle_res == particle_res
            && (!entry.uses_budget || used(p) == (fit.channels_used, fit.bytes_per_texel))
    });
    // The cell holds itself to the smallest byte budget it answers: its build sheds scratch
    // to fit (more slabs or bands: time for bytes), so its resident bytes are within each.
    let limit = u64::from(bytes) * u64::from(res).pow(2);
    let hold = |p: &mut Plan| {
        let params = &mut p.config.params;
        params.memory_limit_bytes = Some(params.memory_limit_bytes.map_or(limit, |l| l.min(limit)));
    };
    match same {
        Some(p) => {
            record(p);
            hold(p);
        }
        None => {
            let mut p = Plan::new(scene, entry.name, fit.channels, res, splat).at(particle_res);
            record(&mut p);
            p.channel_axis = false;
            hold(&mut p);
            cells.push(p);
        }
    }
    Ok(())
}

/// A byte budget: per texel (`--bytes-per-texel`), or a total (`--memory`) with the bytes a
/// texel it is at the cell's resolution.
#[derive(Clone, Copy, Debug)]
enum Budget {
    PerTexel(u32),
    Memory(u32, u64),
}

/// The first of `budgets` that `entry` accepts: where a technique whose result does not depend
/// on the budget is measured.
fn first_budget(entry: &shadow::TechniqueEntry, budgets: &[u32]) -> Option<u32> {
    budgets
        .iter()
        .copied()
        .find(|&b| shadow::check_channels(entry, b).is_ok())
}

/// What a cell's measurement depends on, as a string (`--resume` reuses a cell only when equal).
/// `scene_sha256` is the scene's [`Scene::content_hash`], computed once per scene (for a particle
/// file it reads and hashes the file).
fn settings_key(scene: &Scene, scene_sha256: &str, options: &SweepOptions, plan: &Plan) -> String {
    // A full-resolution cell's key is the one it had before the particle resolution was an
    // axis, so earlier sweeps' cells stay reusable.
    let particle_res = match plan.particle_res {
        ParticleRes::Full => String::new(),
        res => format!(" particle_res={res}"),
    };
    // Likewise a still cell's: the span (all of it, as its record writes it) is added only to
    // an animated sweep's.
    let animate = options.animate.map_or(String::new(), |s| {
        format!(
            " animate={}",
            serde_json::to_string(&s).expect("a span serialises")
        )
    });
    format!(
        "tool={} scene={} size={}x{} frames={} warmup={} cell_seconds={} exact=closed-form technique={} params={}{particle_res}{animate}",
        env!("CARGO_PKG_VERSION"),
        scene_sha256,
        scene.output.width_px,
        scene.output.height_px,
        options.frames,
        options.warmup,
        options.cell_seconds,
        plan.config.name,
        serde_json::to_string(&plan.config.params).expect("params serialise"),
    )
}

/// A technique's counter by name (0 when absent).
fn counter(counters: &[(&'static str, u64)], name: &str) -> u64 {
    counters
        .iter()
        .find(|(n, _)| *n == name)
        .map_or(0, |(_, v)| *v)
}

/// The long-lived state of one scene's sweep in this process: the particles, one renderer, the
/// `exact` reference and the `none` frame time every cell it measures is measured against.
struct Sweeper<'a> {
    gpu: &'a Gpu,
    scene: &'a Scene,
    options: &'a SweepOptions,
    dir: &'a Path,
    particles: Vec<Particle>,
    renderer: Renderer,
    target: OffscreenTarget,
    /// Points the transmittance error is measured at, the particle each lights (its owner, for
    /// `Renderer::probe_shaded`), and `exact`'s T there.
    points: Vec<glam::Vec3>,
    owners: Vec<u32>,
    exact_t: Vec<f32>,
    /// Shared with each cell's comparison thread.
    exact_image: std::sync::Arc<image::RgbImage>,
    /// Recorded in every cell measured here (`none_frame_ms` is NaN until `none` ran).
    against: MeasuredAgainst,
    /// The planned cells' settings keys by name: an image on disk stands in for a technique's
    /// own 24-channel image only when its cell record, with this run's settings, vouches for it
    /// (another shard, or an earlier run with other settings, may have left it).
    keys: &'a BTreeMap<String, String>,
    /// The 24-channel images rendered or read by this process, by cell name.
    own_images: BTreeMap<String, image::RgbImage>,
    /// With `--animate`: `exact` over the span, every cell's frames compared with it.
    motion: Option<std::sync::Arc<super::animate::ExactFrames>>,
}

impl<'a> Sweeper<'a> {
    /// Simulates the particles and renders the `exact` reference (its image into `images/`, its
    /// T at the shaded points kept).
    fn start(
        gpu: &'a Gpu,
        scene: &'a Scene,
        options: &'a SweepOptions,
        dir: &'a Path,
        keys: &'a BTreeMap<String, String>,
        progress: &mut Progress,
    ) -> anyhow::Result<Self> {
        progress.start(&format!("{}: exact reference", scene.name));
        let particles = progress.suspend(|| crate::particles::scene_particles(scene))?;
        let (w, h) = (scene.output.width_px, scene.output.height_px);
        let mut exact_config = Plan::new(
            scene,
            shadow::reference().name,
            1,
            options.shadow_res[0],
            options.splats[0],
        )
        .config;
        exact_config.name = shadow::reference().name.to_owned();
        let mut renderer = Renderer::new(gpu, w, h, OUTPUT_FORMAT, &exact_config).wait()?;
        let target = OffscreenTarget::new(gpu, w, h);
        renderer
            .render(
                gpu,
                scene,
                &particles,
                &RenderOptions::default(),
                &target.view,
            )
            .wait()?;
        let exact_bytes = renderer.shadow_bytes().0;
        let exact_tiles = counter(&renderer.technique().counters(), "tiles_per_side") as u32;
        let exact_image = target.read_rgb(gpu).wait()?;
        crate::output::write_png_rgb(&dir.join(EXACT_IMAGE), &exact_image)?;
        if options.exr {
            let hdr =
                smokeshadow_core::gpu::read_texture_rgba16f(gpu, renderer.hdr_texture()).wait()?;
            crate::output::write_exr(&dir.join(EXACT_HDR_IMAGE), &hdr)?;
        }
        let (points, owners) = frame_points(&renderer, scene, &particles);
        let exact_t = renderer
            .probe_shaded(gpu, scene, &particles, &points, &owners)
            .wait()?;
        // No error is measured against a reference that disagrees with the closed form.
        let check = progress.suspend(|| {
            smokeshadow_core::render::reference_check::verify(&mut renderer, gpu, scene, &particles)
                .wait()
        })?;
        progress.finish(format!(
            "{}: exact reference ({}² light tiles): {} bytes, T at {} shaded points; {check}",
            scene.name,
            exact_tiles,
            exact_bytes,
            points.len()
        ));
        let motion = match options.animate {
            None => None,
            Some(span) => {
                progress.start(&format!("{}: exact over {}", scene.name, span.describe()));
                let frames = super::animate::ExactFrames::render(
                    gpu,
                    &mut renderer,
                    &target,
                    scene,
                    span,
                    progress,
                )?;
                progress.finish(format!(
                    "{}: exact over {}: it changes by {:.3e} a frame (mean |ΔL|, linear luminance), T by {:.3e}; checked at every frame, worst |ΔT| {:.1e}",
                    scene.name,
                    span.describe(),
                    frames.change.luminance,
                    frames.change.transmittance,
                    frames.check_worst
                ));
                Some(std::sync::Arc::new(frames))
            }
        };
        let against = MeasuredAgainst {
            none_frame_ms: f64::NAN,
            exact_bytes,
            exact_tiles,
            exact_image_sha256: sha256_hex(exact_image.as_raw()),
            exact_check_points: check.points,
            exact_check_worst: Some(check.worst_difference),
            machine: Machine::of(gpu),
            shard: options.shard,
            motion: motion.as_ref().map(|m| super::MotionReference {
                change: m.change,
                check_points: m.check_points,
                check_worst: m.check_worst,
            }),
        };
        Ok(Self {
            gpu,
            scene,
            options,
            dir,
            particles,
            renderer,
            target,
            points,
            owners,
            exact_t,
            exact_image: std::sync::Arc::new(exact_image),
            against,
            keys,
            own_images: BTreeMap::new(),
            motion,
        })
    }

    /// With `--animate`: `exact` and the cells [`super::answer::animated_cells`] chooses of
    /// `results` side by side over the span, written to the scene's folder.
    fn write_animation(
        &mut self,
        plans: &[Plan],
        results: &SweepResults,
    ) -> anyhow::Result<Option<super::Animation>> {
        let Some(exact) = self.motion.clone() else {
            return Ok(None);
        };
        let chosen: Vec<(&Plan, &CellResult)> = super::answer::animated_cells(results)
            .into_iter()
            .filter_map(|c| {
                let plan = plans.iter().find(|p| c.image == p.image())?;
                Some((plan, c))
            })
            .collect();
        let cells: Vec<(&TechniqueConfig, RenderOptions)> = chosen
            .iter()
            .map(|(p, _)| (&p.config, p.options()))
            .collect();
        let file = super::animate::ANIMATION_FILE;
        exact.write_animation(
            self.gpu,
            &mut self.renderer,
            &self.target,
            &cells,
            &self.dir.join(file),
        )?;
        let mut tiles = vec![shadow::reference().name.to_owned()];
        tiles.extend(
            chosen
                .iter()
                .map(|(_, c)| format!("{} {}", c.technique, c.channels)),
        );
        Ok(Some(super::Animation {
            file: file.to_owned(),
            tiles,
        }))
    }

    /// Renders `config` once and returns the frame.
    fn render_image(&mut self, plan: &Plan) -> anyhow::Result<image::RgbImage> {
        self.renderer.set_technique(self.gpu, &plan.config).wait()?;
        self.renderer
            .render(
                self.gpu,
                self.scene,
                &self.particles,
                &plan.options(),
                &self.target.view,
            )
            .wait()?;
        Ok(self.target.read_rgb(self.gpu).wait()?)
    }

    /// The technique's own 24-channel image at the cell's resolution, splat and particle
    /// resolution ([`Sweeper::reference`]).
    fn own_baseline(&mut self, plan: &Plan) -> anyhow::Result<image::RgbImage> {
        let p = &plan.config.params;
        let baseline = Plan::new(
            self.scene,
            &plan.config.name,
            BASELINE_CHANNELS,
            p.resolution_px,
            p.splat,
        )
        .at(plan.particle_res);
        self.reference(baseline)
    }

    /// The same cell with its particles at full resolution ([`Sweeper::reference`]): what a
    /// lower `--particle-res` is compared with.
    fn full_res_baseline(&mut self, plan: &Plan) -> anyhow::Result<image::RgbImage> {
        let p = &plan.config.params;
        let baseline = Plan::new(
            self.scene,
            &plan.config.name,
            p.channels,
            p.resolution_px,
            p.splat,
        );
        self.reference(baseline)
    }

    /// The image of the cell `baseline`: one this process has, else its cell's image when the
    /// cell record has this run's settings, else rendered now (kept in memory only: in a folder
    /// shards share, the file belongs to the shard whose cell it is).
    fn reference(&mut self, baseline: Plan) -> anyhow::Result<image::RgbImage> {
        if let Some(image) = self.own_images.get(&baseline.name) {
            return Ok(image.clone());
        }
        let vouched = self.keys.get(&baseline.name).and_then(|key| {
            read_cell(&self.dir.join(format!("cells/{}.json", baseline.name)))
                .filter(|cell| &cell.settings_key == key)
                .map(|cell| self.dir.join(cell.image))
                .filter(|path| path.is_file())
        });
        let image = match vouched {
            Some(path) => diff::load_png(&path)?,
            None => self.render_image(&baseline)?,
        };
        self.own_images.insert(baseline.name, image.clone());
        Ok(image)
    }

    /// Times, images and compares one cell, start to end ([`Sweeper::prepare`],
    /// [`Sweeper::time`], [`PendingCell::finish`]); `record: false` (only for `none`) measures
    /// the frame baseline for this process's ratios without writing its image.
    fn measure(&mut self, plan: &Plan, key: String, record: bool) -> anyhow::Result<CellResult> {
        let prepared = self.prepare(plan)?;
        self.time(plan, prepared, key, record)?.finish()
    }

    /// Everything a cell does before its timed frames: the technique, the transmittance probe
    /// and the warm-up frames.
    ///
    /// The probe comes first: it builds the maps once (compiling the build's shaders), and the
    /// warm-up frames reuse them, so that a technique whose build takes seconds pays for it once
    /// before the timed frames rather than once per warm-up frame. None of it is timed, so the
    /// previous cell's comparisons may run beside it ([`Sweeper::time`]).
    fn prepare(&mut self, plan: &Plan) -> anyhow::Result<Prepared> {
        self.renderer.set_technique(self.gpu, &plan.config).wait()?;
        let probed = if plan.config.name == shadow::frame_baseline().name {
            None
        } else {
            Some(
                self.renderer
                    .probe_shaded(
                        self.gpu,
                        self.scene,
                        &self.particles,
                        &self.points,
                        &self.owners,
                    )
                    .wait()?,
            )
        };
        let warm = RenderOptions {
            reuse_shadow_maps: true,
            ..plan.options()
        };
        // The last warm-up frame counts the particle pass's fragments (never a timed frame).
        let mut particle_fragments = None;
        for i in 0..self.options.warmup {
            let count =
                i + 1 == self.options.warmup && self.renderer.set_count_fragments(self.gpu, true);
            self.renderer
                .render(
                    self.gpu,
                    self.scene,
                    &self.particles,
                    &warm,
                    &self.target.view,
                )
                .wait()?;
            if count {
                particle_fragments = self.renderer.particle_fragments(self.gpu).wait()?;
                self.renderer.set_count_fragments(self.gpu, false);
            }
            self.gpu.wait_idle()?;
        }
        Ok(Prepared {
            probed,
            particle_fragments,
        })
    }

    /// Times the cell `prepare` readied (which must be the last one it readied), reads its
    /// image, renders the baselines it is compared with when this process has not got them,
    /// and starts the comparisons and file writes on a thread of their own: the last GPU work of
    /// the cell is done when this returns. The timed frames build their maps every frame.
    ///
    /// A sweep finishes the returned cell after preparing the next one and before timing it, so
    /// that the comparisons (CPU work on every core) overlap only untimed work.
    fn time(
        &mut self,
        plan: &Plan,
        prepared: Prepared,
        key: String,
        record: bool,
    ) -> anyhow::Result<PendingCell> {
        let is_frame_baseline = plan.config.name == shadow::frame_baseline().name;
        let options = plan.options();
        let (mut shadow_ms, mut render_ms, mut sort_ms, mut frame_ms, mut wall_ms) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let (mut particles_ms, mut upsample_ms) = (Vec::new(), Vec::new());
        let cell_start = Instant::now();
        while !timed_enough(
            &wall_ms.iter().map(|ms| ms / 1e3).collect::<Vec<f64>>(),
            cell_start.elapsed().as_secs_f64(),
            self.options.frames,
            self.options.cell_seconds,
        ) {
            let start = Instant::now();
            let stats = self
                .renderer
                .render(
                    self.gpu,
                    self.scene,
                    &self.particles,
                    &options,
                    &self.target.view,
                )
                .wait()?;
            let times = self.renderer.gpu_times(self.gpu).wait()?;
            wall_ms.push(start.elapsed().as_secs_f64() * 1e3);
            let shadow = times.get("shadow").unwrap_or(0.0);
            shadow_ms.push(shadow);
            particles_ms.push(times.get("particles").unwrap_or(0.0));
            upsample_ms.push(
                times.get("downsample").unwrap_or(0.0) + times.get("upsample").unwrap_or(0.0),
            );
            render_ms.push(times.total_ms() - shadow);
            sort_ms.push(stats.sort_ms);
            frame_ms.push(stats.frame_ms(&times));
        }
        if is_frame_baseline {
            self.against.none_frame_ms = Timing::of(&frame_ms).median;
        }
        let (resident_bytes, transient_bytes) = self.renderer.shadow_bytes();
        let channels_used = self.renderer.technique().channels_used();
        let image = self.target.read_rgb(self.gpu).wait()?;
        let image_path = plan.image();
        let hdr = match self.options.exr && record {
            true => Some((
                format!("images/{}.exr", plan.name),
                smokeshadow_core::gpu::read_texture_rgba16f(self.gpu, self.renderer.hdr_texture())
                    .wait()?,
            )),
            false => None,
        };
        // The cell over the span (not `none`, which is compared with nothing).
        let animated = match (&self.motion, is_frame_baseline) {
            (Some(exact), false) => {
                let exact = std::sync::Arc::clone(exact);
                let (recorder, frames) =
                    exact.record(self.gpu, &mut self.renderer, &self.target, &options)?;
                Some((recorder, frames, std::sync::Arc::clone(&exact.images)))
            }
            _ => None,
        };

        let mut cell = CellResult {
            technique: plan.config.name.clone(),
            channels: plan.config.params.channels,
            byte_budgets: plan.byte_budgets.clone(),
            memory_budgets: plan.memory_budgets.clone(),
            channel_axis: plan.channel_axis,
            channels_used,
            shadow_res: plan.config.params.resolution_px,
            splat: plan.config.params.splat,
            particle_res: plan.particle_res,
            resident_bytes,
            transient_bytes,
            smoke_texels: self.renderer.texels_covering_smoke(
                self.scene,
                &self.particles,
                plan.config.params.resolution_px,
            ),
            gpu_shadow_ms: Timing::of(&shadow_ms),
            gpu_render_ms: Timing::of(&render_ms),
            cpu_sort_ms: Timing::of(&sort_ms),
            frame_ms: Timing::of(&frame_ms),
            wall_ms: Timing::of(&wall_ms),
            particles_ms: Timing::of(&particles_ms),
            upsample_ms: Timing::of(&upsample_ms),
            particle_fragments: prepared.particle_fragments,
            frames_timed: frame_ms.len() as u32,
            overhead_ratio: None,
            shadow_ratio: None,
            vs_own_24: None,
            vs_exact: None,
            vs_full_res: None,
            rms_transmittance_error: prepared.probed.map(|t| rms_difference(&t, &self.exact_t)),
            image: image_path.clone(),
            diff_own_24: None,
            flip_own_24: None,
            diff_exact: None,
            flip_exact: None,
            hdr_image: hdr.as_ref().map(|(path, _)| path.clone()),
            settings_key: key,
            measured_against: Some(self.against.clone()),
            motion: None,
        };
        with_ratios(&mut cell, None);
        // The 24-channel cell is its own baseline: zero error by definition, no difference
        // images to look at. The others need it, from this process, disk or rendered now (the
        // last GPU work). Likewise a full-resolution cell is its own full-resolution image.
        let (own, full_res) = match is_frame_baseline {
            true => (None, None),
            false => {
                let own = match plan.config.params.channels == BASELINE_CHANNELS {
                    true => {
                        self.own_images.insert(plan.name.clone(), image.clone());
                        None
                    }
                    false => Some(self.own_baseline(plan)?),
                };
                let full_res = match plan.particle_res {
                    ParticleRes::Full => None,
                    _ => Some(self.full_res_baseline(plan)?),
                };
                (own, full_res)
            }
        };
        let exact = (!is_frame_baseline).then(|| std::sync::Arc::clone(&self.exact_image));
        let dir = self.dir.to_path_buf();
        let name = plan.name.clone();
        let comparisons = std::thread::spawn(move || -> anyhow::Result<CellResult> {
            let write_images = || -> anyhow::Result<()> {
                if !record {
                    return Ok(());
                }
                crate::output::write_png_rgb(&dir.join(&image_path), &image)?;
                if let Some((path, hdr)) = &hdr {
                    crate::output::write_exr(&dir.join(path), hdr)?;
                }
                Ok(())
            };
            let Some(exact) = exact else {
                write_images()?;
                return Ok(cell);
            };
            let ((written, vs_exact), (vs_own, vs_full_res)) = rayon::join(
                || {
                    rayon::join(write_images, || {
                        compare(&dir, &exact, &image, &format!("{name}_vs_exact"))
                    })
                },
                || {
                    rayon::join(
                        || {
                            own.as_ref()
                                .map(|own| compare(&dir, own, &image, &format!("{name}_vs_own_24")))
                        },
                        || {
                            full_res.as_ref().map(|full| {
                                compare(&dir, full, &image, &format!("{name}_vs_full_res"))
                            })
                        },
                    )
                },
            );
            if let Some((recorder, frames, exact_frames)) = animated {
                cell.motion = Some(super::animate::finish(recorder, &frames, &exact_frames)?);
            }
            cell.vs_full_res = Some(match vs_full_res.transpose()? {
                Some((error, _, _)) => error,
                None => ImageError {
                    flip_mean: 0.0,
                    rmse: 0.0,
                },
            });
            written?;
            let (vs_exact, x4, flip) = vs_exact?;
            cell.vs_exact = Some(vs_exact);
            cell.diff_exact = Some(x4);
            cell.flip_exact = Some(flip);
            match vs_own.transpose()? {
                None => {
                    cell.vs_own_24 = Some(ImageError {
                        flip_mean: 0.0,
                        rmse: 0.0,
                    })
                }
                Some((vs_own, x4, flip)) => {
                    cell.vs_own_24 = Some(vs_own);
                    cell.diff_own_24 = Some(x4);
                    cell.flip_own_24 = Some(flip);
                }
            }
            Ok(cell)
        });
        Ok(PendingCell {
            name: plan.name.clone(),
            comparisons,
        })
    }
}

/// What [`Sweeper::prepare`] measured before a cell's timed frames.
struct Prepared {
    /// T at the shaded points (not for `none`).
    probed: Option<Vec<f32>>,
    particle_fragments: Option<u64>,
}

/// A timed cell whose image writes and comparisons run on their own thread.
struct PendingCell {
    name: String,
    comparisons: std::thread::JoinHandle<anyhow::Result<CellResult>>,
}

impl PendingCell {
    /// Waits for the comparisons: the finished cell.
    fn finish(self) -> anyhow::Result<CellResult> {
        match self.comparisons.join() {
            Ok(cell) => cell,
            Err(_) => anyhow::bail!("the comparisons of cell {} stopped (a panic)", self.name),
        }
    }
}

/// Writes the x4 difference and FLIP map of `test` against `reference` under `dir/diffs/`
/// ([`crate::compare::write_pair`]); returns the error and both paths.
fn compare(
    dir: &Path,
    reference: &image::RgbImage,
    test: &image::RgbImage,
    stem: &str,
) -> anyhow::Result<(ImageError, String, String)> {
    // The sweep reports FLIP and RMSE only.
    let pair = crate::compare::write_pair(dir, reference, test, stem, crate::diff::Ssim::Skip)?;
    Ok((
        ImageError {
            flip_mean: pair.metrics.flip_mean,
            rmse: pair.metrics.rmse_srgb,
        },
        pair.difference,
        pair.flip_map,
    ))
}

/// What one sweep process produced.
#[derive(Debug)]
pub enum SweepOutcome {
    /// The whole sweep: every scene's results (in the order given) and, with `--scenes`, the
    /// gallery over them.
    Whole {
        scenes: Vec<SweepResults>,
        gallery: Option<super::gallery::Gallery>,
    },
    /// One shard's part of it (no tables or report: `--merge` writes them).
    Shard(ShardManifest),
}

/// One scene's planned cells; their stable indices start at `first_index`.
struct ScenePlan<'a> {
    scene: &'a Scene,
    /// The scene's folder relative to the sweep folder: "" for one scene, its name in a gallery.
    folder: String,
    first_index: usize,
    plans: Vec<Plan>,
    skipped: Vec<SkippedCell>,
    /// Settings key by cell name.
    keys: BTreeMap<String, String>,
    /// [`Scene::content_hash`], computed once.
    scene_sha256: String,
    /// The map resolutions `tune` chose ([`SweepOptions::shapes`]).
    shapes: crate::tune::Shapes,
}

impl ScenePlan<'_> {
    /// What the manifest records of it.
    fn planned(&self) -> PlannedScene {
        let s = self.scene;
        PlannedScene {
            name: s.name.clone(),
            description: s.summary(),
            folder: self.folder.clone(),
            scene_sha256: self.scene_sha256.clone(),
            seed: s.emitters.first().map_or(0, |e| e.seed),
            particles: crate::particles::count(s) as u32,
            width_px: s.output.width_px,
            height_px: s.output.height_px,
            framing: s.shadow.framing,
            shapes: self.shapes.clone(),
            cells: self
                .plans
                .iter()
                .enumerate()
                .map(|(i, p)| PlannedCell {
                    index: self.first_index + i,
                    name: p.name.clone(),
                    settings_key: self.keys[&p.name].clone(),
                })
                .collect(),
            skipped: self.skipped.clone(),
        }
    }
}

/// Plans every scene's cells, one after the other: a cell's stable index is its position in
/// this list, so it depends only on the options and the scenes, never on what ran before.
fn plan_scenes<'a>(
    scenes: &'a [Scene],
    options: &SweepOptions,
) -> anyhow::Result<Vec<ScenePlan<'a>>> {
    if scenes.is_empty() {
        anyhow::bail!("--scenes is empty: give at least one scene");
    }
    if !options.gallery && scenes.len() > 1 {
        anyhow::bail!("several scenes need the gallery layout (--scenes)");
    }
    let mut out: Vec<ScenePlan> = Vec::new();
    let mut first_index = 0;
    for scene in scenes {
        if options.gallery {
            check_folder_name(&scene.name)?;
            if out.iter().any(|p| p.scene.name == scene.name) {
                anyhow::bail!(
                    "--scenes: two scenes are named \"{}\"; each scene's sweep goes to a folder of its name",
                    scene.name
                );
            }
        }
        let (plans, skipped) = plan(scene, options)?;
        let scene_sha256 = scene.content_hash();
        let keys = plans
            .iter()
            .map(|p| {
                (
                    p.name.clone(),
                    settings_key(scene, &scene_sha256, options, p),
                )
            })
            .collect();
        let n = plans.len();
        out.push(ScenePlan {
            scene,
            folder: if options.gallery {
                scene.name.clone()
            } else {
                String::new()
            },
            first_index,
            plans,
            skipped,
            keys,
            scene_sha256,
            shapes: options.shapes.clone(),
        });
        first_index += n;
    }
    Ok(out)
}

/// A scene name is a folder name in a gallery sweep: letters, digits, `_`, `-` and `.` only.
fn check_folder_name(name: &str) -> anyhow::Result<()> {
    let ok = !name.is_empty()
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'));
    if !ok {
        anyhow::bail!(
            "--scenes: scene name \"{name}\" cannot be a folder name (letters, digits, _ - . only)"
        );
    }
    Ok(())
}

/// Removes the plain files directly inside `dir` (not folders).
fn remove_files(dir: &Path) -> anyhow::Result<()> {
    if !dir.is_dir() {
        return Ok(());
    }
    for entry in std::fs::read_dir(dir)? {
        let path = entry?.path();
        if path.is_file() {
            std::fs::remove_file(&path)
                .with_context(|| format!("cannot remove {}", path.display()))?;
        }
    }
    Ok(())
}

/// Removes `path` when it exists.
fn remove_if_present(path: &Path) -> anyhow::Result<()> {
    match std::fs::remove_file(path) {
        Err(err) if err.kind() != std::io::ErrorKind::NotFound => {
            Err(err).with_context(|| format!("cannot remove {}", path.display()))
        }
        _ => Ok(()),
    }
}

/// Runs the sweep (or, with `options.shard`, one shard of it) of `scenes` into `dir` and writes
/// every output.
///
/// Every process that has cells of a scene to measure first renders `exact` and measures
/// `none` itself: the `none` cell (stable index 0 of each scene) is recorded only by the
/// process it belongs to (shard 0 of a scene whose cells start at a multiple of N, ...); the
/// others measure it unrecorded, and each cell records the `none` frame time and the `exact` it
/// was measured against ([`MeasuredAgainst`]). A process that measures nothing (`--resume`
/// with every cell done) renders nothing.
pub fn run(
    gpu: &Gpu,
    scenes: &[Scene],
    options: &SweepOptions,
    dir: &Path,
) -> anyhow::Result<SweepOutcome> {
    let started = std::time::SystemTime::now();
    let wall = Instant::now();
    let scene_plans = plan_scenes(scenes, options)?;
    if dir.is_file() {
        anyhow::bail!("output {} is a file; give a folder", dir.display());
    }
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let shards_dir = dir.join(shard::SHARDS_DIR);
    let machine = Machine::of(gpu);
    let manifest = |finished: bool, measured: usize, reused: usize| {
        options.shard.map(|shard| ShardManifest {
            shard,
            tool_version: env!("CARGO_PKG_VERSION").to_owned(),
            frames: options.frames,
            warmup: options.warmup,
            gallery: options.gallery,
            scenes: scene_plans.iter().map(ScenePlan::planned).collect(),
            machine: machine.clone(),
            started: humantime::format_rfc3339_seconds(started).to_string(),
            wall_s: wall.elapsed().as_secs_f64(),
            measured: measured as u32,
            reused: reused as u32,
            finished,
        })
    };
    match manifest(false, 0, 0) {
        Some(m) => shard::write_manifest(dir, &m)?,
        // A fresh unsharded sweep forgets the shards of earlier runs, as it forgets their cells.
        None if !options.resume => remove_files(&shards_dir)?,
        None => {}
    }

    // What this process runs of each scene, and which of those cells it reuses.
    struct Own<'p> {
        plan: &'p Plan,
        key: String,
        reused: Option<CellResult>,
    }
    let mut work: Vec<(PathBuf, Vec<Own>)> = Vec::new();
    for sp in &scene_plans {
        let scene_dir = dir.join(&sp.folder);
        let mine: Vec<&Plan> = sp
            .plans
            .iter()
            .enumerate()
            .filter(|(i, _)| options.shard.is_none_or(|s| s.owns(sp.first_index + i)))
            .map(|(_, p)| p)
            .collect();
        if mine.is_empty() {
            work.push((scene_dir, Vec::new()));
            continue;
        }
        for sub in ["cells", "images", "diffs"] {
            std::fs::create_dir_all(scene_dir.join(sub))
                .with_context(|| format!("cannot create {}", scene_dir.join(sub).display()))?;
        }
        if !options.resume {
            match options.shard {
                // A fresh shard forgets only its own cells: other shards may share the folder.
                Some(_) => {
                    for p in &mine {
                        remove_if_present(&scene_dir.join(format!("cells/{}.json", p.name)))?;
                        remove_if_present(&scene_dir.join(p.image()))?;
                        remove_if_present(&scene_dir.join(format!("images/{}.exr", p.name)))?;
                    }
                }
                // A fresh sweep: forget finished cells and reference images of earlier runs.
                None => {
                    remove_files(&scene_dir.join("cells"))?;
                    remove_files(&scene_dir.join("images"))?;
                }
            }
        }
        let own = mine
            .into_iter()
            .map(|plan| {
                let key = sp.keys[&plan.name].clone();
                let record = scene_dir.join(format!("cells/{}.json", plan.name));
                let reused = options
                    .resume
                    .then(|| read_cell(&record))
                    .flatten()
                    .filter(|cell| {
                        cell.settings_key == key && scene_dir.join(&cell.image).is_file()
                    })
                    .filter(|cell| {
                        // A cell measured without its EXR is measured again when one is asked for.
                        !options.exr
                            || cell
                                .hdr_image
                                .as_ref()
                                .is_some_and(|p| scene_dir.join(p).is_file())
                    });
                Own { plan, key, reused }
            })
            .collect();
        work.push((scene_dir, own));
    }
    // Progress: every own cell, plus `exact` (and `none` when unrecorded) where a scene needs
    // measuring.
    let needs_gpu = |scene_dir: &Path, own: &[Own]| {
        own.iter().any(|o| o.reused.is_none())
            || (!own.is_empty() && !scene_dir.join(EXACT_IMAGE).is_file())
    };
    let records_none = |own: &[Own]| {
        own.first().is_some_and(|o| {
            o.plan.config.name == shadow::frame_baseline().name && o.reused.is_none()
        })
    };
    let total: usize = work
        .iter()
        .map(|(d, own)| {
            own.len()
                + match needs_gpu(d, own) {
                    // `exact`, its frames over the span, this process's `none` (and with
                    // `--animate`, unsharded, the side-by-side over the span).
                    true => {
                        1 + usize::from(options.animate.is_some())
                            * (1 + usize::from(options.shard.is_none()))
                            + usize::from(!records_none(own))
                    }
                    false => 0,
                }
        })
        .sum();
    let mut progress = Progress::new(total, "cells");

    let (mut measured, mut reused) = (0usize, 0usize);
    let mut results: Vec<SweepResults> = Vec::new();
    for (sp, (scene_dir, own)) in scene_plans.iter().zip(&work) {
        let planned = sp.planned();
        let mut sweeper: Option<Sweeper> = None;
        let mut exact_info: Option<(u64, u32)> = None;
        if needs_gpu(scene_dir, own) {
            let mut sw =
                Sweeper::start(gpu, sp.scene, options, scene_dir, &sp.keys, &mut progress)?;
            exact_info = Some((sw.against.exact_bytes, sw.against.exact_tiles));
            if !records_none(own) {
                // This process's frame baseline: its ratios are against it, but the `none` cell
                // is another process's (or was measured earlier).
                progress.start(&format!(
                    "{}: none (this process's baseline)",
                    sp.scene.name
                ));
                let none = sw.measure(&sp.plans[0], String::new(), false)?;
                progress.finish(format!(
                    "{}: none, this process's frame baseline: frame {:.1} ms (not recorded: {})",
                    sp.scene.name,
                    none.frame_ms.median,
                    match options.shard {
                        Some(s) => format!(
                            "cell {} belongs to shard {}",
                            sp.first_index,
                            Shard {
                                k: (sp.first_index % s.n as usize) as u32,
                                ..s
                            }
                        ),
                        None => "the none cell was measured earlier".to_owned(),
                    }
                ));
            }
            sweeper = Some(sw);
        }
        let mut cells: Vec<CellResult> = Vec::new();
        let metadata_now = |cells: &[CellResult]| {
            assemble(
                &planned,
                env!("CARGO_PKG_VERSION"),
                options.frames,
                options.warmup,
                cells,
                Some(&machine),
                exact_info,
                humantime::format_rfc3339_seconds(started).to_string(),
                wall.elapsed().as_secs_f64(),
                Vec::new(),
                scene_dir,
            )
        };
        // A finished cell joins the tables, rewritten at once (unsharded) so that a sweep stopped
        // here leaves consistent results.
        let keep = |cell: CellResult, cells: &mut Vec<CellResult>| -> anyhow::Result<()> {
            cells.push(cell);
            if options.shard.is_none() {
                write_results(&metadata_now(cells), scene_dir)?;
            }
            Ok(())
        };
        let finish = |pending: PendingCell,
                      progress: &mut Progress,
                      cells: &mut Vec<CellResult>|
         -> anyhow::Result<()> {
            let record = scene_dir.join(format!("cells/{}.json", pending.name));
            let cell = pending.finish()?;
            crate::output::write_atomic(&record, serde_json::to_string_pretty(&cell)?.as_bytes())?;
            progress.finish(summary(&cell));
            keep(cell, cells)
        };
        // The cell whose comparisons are running: finished once the next cell is prepared
        // (they overlap only its untimed work), or before a reused cell takes its place.
        let mut pending: Option<PendingCell> = None;
        for o in own {
            match &o.reused {
                Some(cell) => {
                    if let Some(p) = pending.take() {
                        finish(p, &mut progress, &mut cells)?;
                    }
                    progress.start(&o.plan.name);
                    progress.finish(format!("{}: done earlier, reused", o.plan.name));
                    reused += 1;
                    // The budgets it answers are this run's (they do not change what it measured).
                    let cell = CellResult {
                        byte_budgets: o.plan.byte_budgets.clone(),
                        memory_budgets: o.plan.memory_budgets.clone(),
                        channel_axis: o.plan.channel_axis,
                        ..cell.clone()
                    };
                    keep(cell, &mut cells)?;
                }
                None => {
                    let sw = sweeper
                        .as_mut()
                        .expect("a scene with cells to measure has a sweeper");
                    let prepared = sw.prepare(o.plan);
                    if let Some(p) = pending.take() {
                        finish(p, &mut progress, &mut cells)?;
                    }
                    progress.start(&o.plan.name);
                    pending = Some(sw.time(o.plan, prepared?, o.key.clone(), true)?);
                    measured += 1;
                }
            }
        }
        if let Some(p) = pending.take() {
            finish(p, &mut progress, &mut cells)?;
        }
        // An animated sweep's side-by-side, from the cells the results choose.
        let mut animation = None;
        if let (Some(sw), None) = (sweeper.as_mut(), options.shard)
            && sw.motion.is_some()
        {
            progress.start(&format!("{}: the span side by side", sp.scene.name));
            animation = sw.write_animation(&sp.plans, &metadata_now(&cells))?;
            if let Some(a) = &animation {
                progress.finish(format!(
                    "{}: {} over the span side by side: {}",
                    sp.scene.name,
                    a.tiles.join(", "),
                    scene_dir.join(&a.file).display()
                ));
            }
        }
        drop(sweeper);
        if options.shard.is_none() {
            let mut r = metadata_now(&cells);
            r.animation = animation;
            super::report::write_scene(&r, scene_dir)?;
            results.push(r);
        }
    }
    progress.end();
    if let Some(m) = manifest(true, measured, reused) {
        shard::write_manifest(dir, &m)?;
        return Ok(SweepOutcome::Shard(m));
    }
    let gallery = match options.gallery {
        true => Some(super::gallery::write(dir, &results)?),
        false => None,
    };
    Ok(SweepOutcome::Whole {
        scenes: results,
        gallery,
    })
}

/// SHA-256 of `bytes`, hex-encoded.
fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// One line about a finished cell.
fn summary(cell: &CellResult) -> String {
    let mut line = format!(
        "{} {} ch ({} used) {}² {}{}: {} bytes, frame {:.1} ms (shadow {:.1})",
        cell.technique,
        cell.channels,
        cell.channels_used,
        cell.shadow_res,
        cell.splat.name(),
        match cell.particle_res {
            ParticleRes::Full => String::new(),
            res => format!(", particles at {res}"),
        },
        cell.resident_bytes,
        cell.frame_ms.median,
        cell.gpu_shadow_ms.median
    );
    if let Some(e) = &cell.vs_exact {
        line.push_str(&format!(", FLIP vs exact {:.4}", e.flip_mean));
    }
    if cell.particle_res != ParticleRes::Full
        && let Some(e) = &cell.vs_full_res
    {
        line.push_str(&format!(", FLIP vs full res {:.4}", e.flip_mean));
    }
    if let Some(m) = &cell.motion {
        line.push_str(&format!(
            "; over {} frames: temporal error {:.3e} (p99.9 {:.3e}), {:.0} pops a frame, T {:.3e}",
            m.frames, m.temporal_error, m.temporal_p999, m.pops_per_frame, m.t_temporal_error
        ));
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_time_three_frames_or_two_slow_ones_within_their_seconds() {
        // Timing goes on while one more frame of the average so far fits in the seconds, up to
        // `frames`.
        assert!(!timed_enough(&[0.1; 4], 0.4, 20, 0.5));
        assert!(timed_enough(&[0.1; 5], 0.5, 20, 0.5));
        assert!(!timed_enough(&[0.02; 19], 0.38, 20, 0.5));
        assert!(timed_enough(&[0.02; 20], 0.4, 20, 0.5));
        // Four frames of 0.12 s: a fifth would end at 0.6 s.
        assert!(timed_enough(&[0.12; 4], 0.48, 20, 0.5));
        // At least three frames, whatever the seconds ...
        assert!(!timed_enough(&[0.3, 0.3], 0.6, 20, 0.5));
        assert!(timed_enough(&[0.3, 0.3, 0.3], 0.9, 20, 0.5));
        // ... or two when each of them took longer than the seconds on its own.
        assert!(!timed_enough(&[2.3], 2.3, 20, 0.5));
        assert!(timed_enough(&[2.3, 2.2], 4.5, 20, 0.5));
        assert!(!timed_enough(&[2.3, 0.4], 2.7, 20, 0.5));
        // `frames` below the minimum wins.
        assert!(timed_enough(&[2.3], 2.3, 1, 0.5));
    }
}
