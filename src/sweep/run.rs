//! The sweep engine: plans the cells, renders and times each one on one long-lived renderer
//! (pipelines are rebuilt only when the technique changes; the particles are simulated once),
//! compares it with its own 24-channel image and with `exact`, and persists it.

use std::path::Path;
use std::time::Instant;

use anyhow::Context;

use super::{CellResult, ImageError, SkippedCell, SweepMetadata, SweepResults, Timing};
use crate::diff;
use crate::gpu::Gpu;
use crate::progress::Progress;
use crate::render::shaded::{rms_difference, shaded_points};
use crate::render::{OUTPUT_FORMAT, OffscreenTarget, RenderOptions, Renderer, TechniqueConfig};
use crate::scene::Scene;
use crate::shadow::{self, SplatMode};
use crate::sim::Particle;

/// What to sweep. [`SweepOptions::default`] is the thesis experiment (chapter 4.2.1).
#[derive(Clone, Debug)]
pub struct SweepOptions {
    pub techniques: Vec<String>,
    pub channels: Vec<u32>,
    pub shadow_res: Vec<u32>,
    pub splats: Vec<SplatMode>,
    /// Timed frames per cell (medians over these) and untimed warm-up frames before them.
    pub frames: u32,
    pub warmup: u32,
    /// Seconds of timed frames after which a cell stops early (after at least
    /// [`MIN_TIMED_FRAMES`], or [`MIN_SLOW_FRAMES`] of frames each longer than this), so a slow
    /// technique does not hold the sweep: its medians are over fewer frames, and the cell says
    /// how many (`frames_timed`).
    pub cell_seconds: f64,
    /// Reuse cells already finished with identical settings.
    pub resume: bool,
    /// Also write every cell's linear HDR frame as OpenEXR beside its PNG.
    pub exr: bool,
}

impl Default for SweepOptions {
    fn default() -> Self {
        Self {
            techniques: shadow::default_sweep(),
            channels: vec![24, 16, 8, 6],
            shadow_res: vec![512],
            splats: vec![SplatMode::Point],
            frames: 20,
            warmup: 1,
            cell_seconds: 0.5,
            resume: false,
            exr: false,
        }
    }
}

/// Timed frames a cell takes at least, whatever `cell_seconds` says (fewer only when
/// `frames` asks for fewer, or [`MIN_SLOW_FRAMES`] when each frame outlasts `cell_seconds`).
pub const MIN_TIMED_FRAMES: u32 = 3;
/// Timed frames a cell takes at least when every frame took longer than `cell_seconds` on its
/// own: a deep capture's frames of seconds on lavapipe vary by a few percent, and a third one
/// would cost `dsm` 2.3 s a cell.
pub const MIN_SLOW_FRAMES: u32 = 2;

/// Whether a cell has timed enough frames (`frame_s`, wall seconds each) after `elapsed_s` of
/// timing: `frames` of them, or `cell_seconds` of timing over at least [`MIN_TIMED_FRAMES`]
/// frames, or over [`MIN_SLOW_FRAMES`] when each of them alone took longer than `cell_seconds`.
pub fn timed_enough(frame_s: &[f64], elapsed_s: f64, frames: u32, cell_seconds: f64) -> bool {
    let n = frame_s.len() as u32;
    if n >= frames {
        return true;
    }
    if elapsed_s < cell_seconds {
        return false;
    }
    let slow = frame_s.iter().all(|&s| s > cell_seconds);
    n >= MIN_TIMED_FRAMES || (slow && n >= MIN_SLOW_FRAMES)
}

/// The budget every cell's "own baseline" uses (the thesis' baselines).
const BASELINE_CHANNELS: u32 = 24;
/// Pixel stride of the opaque points the transmittance error is measured at.
const SHADED_STRIDE_PX: u32 = 4;

/// One planned cell.
#[derive(Clone, Debug)]
struct Plan {
    name: String,
    config: TechniqueConfig,
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
    non_empty("shadow-res", options.shadow_res.is_empty())?;
    non_empty("splat", options.splats.is_empty())?;
    if options.frames == 0 {
        anyhow::bail!("--frames 0: time at least one frame");
    }
    for &res in &options.shadow_res {
        if !(1..=8192).contains(&res) {
            anyhow::bail!("--shadow-res {res} is out of range: allowed 1..=8192");
        }
    }
    let mut cells = vec![Plan::new(
        scene,
        shadow::frame_baseline().name,
        1,
        options.shadow_res[0],
        options.splats[0],
    )];
    let mut skipped = Vec::new();
    for name in &options.techniques {
        let entry = shadow::find(name)?;
        if entry.role != shadow::Role::Contender {
            anyhow::bail!(
                "--techniques {name}: `{}` and `{}` are the sweep's baseline and reference, always measured; list the techniques to compare",
                shadow::frame_baseline().name,
                shadow::reference().name
            );
        }
        for &b in &options.channels {
            if !(1..=shadow::MAX_CHANNELS).contains(&b) {
                anyhow::bail!(
                    "--channels {b} is out of range: allowed 1..={}",
                    shadow::MAX_CHANNELS
                );
            }
            if let Err(err) = shadow::check_channels(entry, b) {
                skipped.push(SkippedCell {
                    technique: entry.name.to_owned(),
                    channels: b,
                    reason: err.to_string(),
                });
            } else if !entry.uses_budget && Some(b) != first_budget(entry, &options.channels) {
                skipped.push(SkippedCell {
                    technique: entry.name.to_owned(),
                    channels: b,
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
    for &res in &options.shadow_res {
        for (s, &splat) in options.splats.iter().enumerate() {
            for name in &options.techniques {
                let entry = shadow::find(name)?;
                if s > 0 && !entry.uses_splat {
                    continue;
                }
                for &b in &options.channels {
                    let once =
                        entry.uses_budget || Some(b) == first_budget(entry, &options.channels);
                    if shadow::check_channels(entry, b).is_ok() && once {
                        cells.push(Plan::new(scene, entry.name, b, res, splat));
                    }
                }
            }
        }
    }
    Ok((cells, skipped))
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
fn settings_key(scene: &Scene, options: &SweepOptions, plan: &Plan) -> String {
    format!(
        "tool={} scene={} size={}x{} frames={} warmup={} cell_seconds={} exact=closed-form technique={} params={}",
        env!("CARGO_PKG_VERSION"),
        scene.content_hash(),
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

/// Median, minimum and maximum of samples.
pub(super) fn timing(samples: &[f64]) -> Timing {
    let mut v = samples.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return Timing::default();
    }
    let median = if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    };
    Timing {
        median,
        min: v[0],
        max: v[n - 1],
    }
}

/// The long-lived state of one sweep.
struct Sweeper<'a> {
    gpu: &'a Gpu,
    scene: &'a Scene,
    options: &'a SweepOptions,
    dir: &'a Path,
    particles: Vec<Particle>,
    renderer: Renderer,
    target: OffscreenTarget,
    /// Points the transmittance error is measured at, and `exact`'s T there.
    points: Vec<glam::Vec3>,
    exact_t: Vec<f32>,
    exact_image: image::RgbImage,
}

impl Sweeper<'_> {
    /// Renders `config` once and returns the frame.
    fn render_image(&mut self, config: &TechniqueConfig) -> anyhow::Result<image::RgbImage> {
        self.renderer.set_technique(self.gpu, config)?;
        self.renderer.render(
            self.gpu,
            self.scene,
            &self.particles,
            &RenderOptions::default(),
            &self.target.view,
        )?;
        let rgba = crate::gpu::read_texture_rgba8(self.gpu, &self.target.texture)?;
        Ok(image::DynamicImage::ImageRgba8(rgba).into_rgb8())
    }

    /// The technique's own 24-channel image at the cell's resolution and splat: from disk when
    /// an earlier cell (or run) wrote it, else rendered now.
    fn own_baseline(&mut self, plan: &Plan) -> anyhow::Result<image::RgbImage> {
        let p = &plan.config.params;
        let baseline = Plan::new(
            self.scene,
            &plan.config.name,
            BASELINE_CHANNELS,
            p.resolution_px,
            p.splat,
        );
        let path = self.dir.join(format!("images/{}.png", baseline.name));
        if path.is_file() {
            return Ok(diff::load_png(&path)?);
        }
        let image = self.render_image(&baseline.config)?;
        crate::output::write_png_rgb(&path, &image)?;
        Ok(image)
    }

    /// Times, images and compares one cell.
    ///
    /// The transmittance probe comes first: it builds the maps once (compiling the build's
    /// shaders), and the warm-up frames reuse them, so that a technique whose build takes
    /// seconds pays for it once before the timed frames rather than once per warm-up frame. The
    /// timed frames build their maps every frame. The image comparisons run on every core after
    /// the timing, when nothing else runs.
    fn measure(&mut self, plan: &Plan, key: String) -> anyhow::Result<CellResult> {
        self.renderer.set_technique(self.gpu, &plan.config)?;
        let is_frame_baseline = plan.config.name == shadow::frame_baseline().name;
        let probed = if is_frame_baseline {
            None
        } else {
            Some(
                self.renderer
                    .probe(self.gpu, self.scene, &self.particles, &self.points)?,
            )
        };
        let warm = RenderOptions {
            reuse_shadow_maps: true,
            ..RenderOptions::default()
        };
        for _ in 0..self.options.warmup {
            self.renderer.render(
                self.gpu,
                self.scene,
                &self.particles,
                &warm,
                &self.target.view,
            )?;
            self.gpu.wait_idle()?;
        }
        let options = RenderOptions::default();
        let (mut shadow_ms, mut render_ms, mut sort_ms, mut frame_ms, mut wall_ms) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let cell_start = Instant::now();
        while !timed_enough(
            &wall_ms.iter().map(|ms| ms / 1e3).collect::<Vec<f64>>(),
            cell_start.elapsed().as_secs_f64(),
            self.options.frames,
            self.options.cell_seconds,
        ) {
            let start = Instant::now();
            let stats = self.renderer.render(
                self.gpu,
                self.scene,
                &self.particles,
                &options,
                &self.target.view,
            )?;
            let times = self.renderer.gpu_times(self.gpu)?;
            wall_ms.push(start.elapsed().as_secs_f64() * 1e3);
            let shadow = times.get("shadow").unwrap_or(0.0);
            shadow_ms.push(shadow);
            render_ms.push(times.total_ms() - shadow);
            sort_ms.push(stats.sort_ms);
            frame_ms.push(times.total_ms() + stats.sort_ms);
        }
        let technique = self.renderer.technique();
        let (channels_used, bytes, transient_bytes) = (
            technique.channels_used(),
            technique.memory().total_bytes(),
            technique.memory().transient_bytes(),
        );
        let rgba = crate::gpu::read_texture_rgba8(self.gpu, &self.target.texture)?;
        let image = image::DynamicImage::ImageRgba8(rgba).into_rgb8();
        let image_path = format!("images/{}.png", plan.name);
        let hdr = match self.options.exr {
            true => Some((
                format!("images/{}.exr", plan.name),
                crate::gpu::read_texture_rgba16f(self.gpu, self.renderer.hdr_texture())?,
            )),
            false => None,
        };
        let dir = self.dir;
        let write_images = || -> anyhow::Result<()> {
            crate::output::write_png_rgb(&dir.join(&image_path), &image)?;
            if let Some((path, hdr)) = &hdr {
                crate::output::write_exr(&dir.join(path), hdr)?;
            }
            Ok(())
        };

        let mut cell = CellResult {
            technique: plan.config.name.clone(),
            channels: plan.config.params.channels,
            channels_used,
            shadow_res: plan.config.params.resolution_px,
            splat: plan.config.params.splat,
            bytes,
            transient_bytes,
            gpu_shadow_ms: timing(&shadow_ms),
            gpu_render_ms: timing(&render_ms),
            cpu_sort_ms: timing(&sort_ms),
            frame_ms: timing(&frame_ms),
            wall_ms: timing(&wall_ms),
            frames_timed: frame_ms.len() as u32,
            overhead_ratio: None,
            shadow_ratio: None,
            vs_own_24: None,
            vs_exact: None,
            rms_transmittance_error: probed.map(|t| rms_difference(&t, &self.exact_t)),
            image: image_path.clone(),
            diff_own_24: None,
            flip_own_24: None,
            diff_exact: None,
            flip_exact: None,
            hdr_image: hdr.as_ref().map(|(path, _)| path.clone()),
            settings_key: key,
        };
        if is_frame_baseline {
            write_images()?;
            return Ok(cell);
        }
        // The 24-channel cell is its own baseline: zero error by definition, no difference
        // images to look at. The others need it, from disk or rendered now (the last GPU work).
        let own = if plan.config.params.channels == BASELINE_CHANNELS {
            None
        } else {
            Some(self.own_baseline(plan)?)
        };
        let ((written, vs_exact), vs_own) = rayon::join(
            || {
                rayon::join(write_images, || {
                    compare(
                        dir,
                        &self.exact_image,
                        &image,
                        &format!("{}_vs_exact", plan.name),
                    )
                })
            },
            || {
                own.as_ref()
                    .map(|own| compare(dir, own, &image, &format!("{}_vs_own_24", plan.name)))
            },
        );
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
    let pair = crate::compare::write_pair(dir, reference, test, stem)?;
    Ok((
        ImageError {
            flip_mean: pair.metrics.flip_mean,
            rmse: pair.metrics.rmse_srgb,
        },
        pair.difference,
        pair.flip_map,
    ))
}

/// Runs the sweep into `dir` and writes every output; returns the results.
pub fn run(
    gpu: &Gpu,
    scene: &Scene,
    options: &SweepOptions,
    dir: &Path,
) -> anyhow::Result<SweepResults> {
    let started = std::time::SystemTime::now();
    let wall = Instant::now();
    let (plans, skipped) = plan(scene, options)?;
    if dir.is_file() {
        anyhow::bail!("output {} is a file; give a folder", dir.display());
    }
    let cells_dir = dir.join("cells");
    for sub in ["cells", "images", "diffs"] {
        std::fs::create_dir_all(dir.join(sub))
            .with_context(|| format!("cannot create {}", dir.join(sub).display()))?;
    }
    if !options.resume {
        // A fresh sweep: forget finished cells and reference images of earlier runs.
        for sub in ["cells", "images"] {
            for entry in std::fs::read_dir(dir.join(sub))? {
                let path = entry?.path();
                if path.is_file() {
                    std::fs::remove_file(&path)?;
                }
            }
        }
    }

    let particles = crate::particles::scene_particles(scene)?;
    let (w, h) = (scene.output.width_px, scene.output.height_px);
    let mut exact_config = plans[0].config.clone();
    exact_config.name = shadow::reference().name.to_owned();
    let mut progress = Progress::new(plans.len() + 1, "cells");
    progress.start("exact reference");
    let mut renderer = Renderer::new(gpu, w, h, OUTPUT_FORMAT, &exact_config)?;
    let target = OffscreenTarget::new(gpu, w, h);
    renderer.render(
        gpu,
        scene,
        &particles,
        &RenderOptions::default(),
        &target.view,
    )?;
    let exact_bytes = renderer.technique().memory().total_bytes();
    let exact_tiles = counter(&renderer.technique().counters(), "tiles_per_side") as u32;
    let exact_image =
        image::DynamicImage::ImageRgba8(crate::gpu::read_texture_rgba8(gpu, &target.texture)?)
            .into_rgb8();
    let exact_image_path = "images/exact.png".to_owned();
    crate::output::write_png_rgb(&dir.join(&exact_image_path), &exact_image)?;
    let exact_hdr_path = match options.exr {
        true => {
            let path = "images/exact.exr".to_owned();
            let hdr = crate::gpu::read_texture_rgba16f(gpu, renderer.hdr_texture())?;
            crate::output::write_exr(&dir.join(&path), &hdr)?;
            Some(path)
        }
        false => None,
    };
    let points = shaded_points(scene, &particles, w, h, SHADED_STRIDE_PX);
    let exact_t = renderer.probe(gpu, scene, &particles, &points)?;
    progress.finish(format!(
        "exact reference ({}² light tiles): {} bytes, T at {} shaded points",
        exact_tiles,
        exact_bytes,
        points.len()
    ));

    let mut sweeper = Sweeper {
        gpu,
        scene,
        options,
        dir,
        particles,
        renderer,
        target,
        points,
        exact_t,
        exact_image,
    };
    let metadata = |wall_s: f64| SweepMetadata {
        tool_version: env!("CARGO_PKG_VERSION").to_owned(),
        scene: scene.name.clone(),
        scene_sha256: scene.content_hash(),
        seed: scene.emitters[0].seed,
        particles: scene.particle_count() as u32,
        width_px: w,
        height_px: h,
        adapter: gpu.info.name.clone(),
        backend: format!("{:?}", gpu.info.backend),
        driver: format!("{} {}", gpu.info.driver, gpu.info.driver_info),
        timestamp_queries: gpu.has_timestamps(),
        frames: options.frames,
        warmup: options.warmup,
        exact_tiles,
        exact_bytes,
        started: humantime::format_rfc3339_seconds(started).to_string(),
        wall_s,
    };
    let mut cells: Vec<CellResult> = Vec::new();
    for plan in &plans {
        let key = settings_key(scene, options, plan);
        let record = cells_dir.join(format!("{}.json", plan.name));
        progress.start(&plan.name);
        let reused = options
            .resume
            .then(|| std::fs::read_to_string(&record).ok())
            .flatten()
            .and_then(|text| serde_json::from_str::<CellResult>(&text).ok())
            .filter(|cell| cell.settings_key == key && dir.join(&cell.image).is_file())
            .filter(|cell| {
                // A cell measured without its EXR is measured again when one is asked for.
                !options.exr
                    || cell
                        .hdr_image
                        .as_ref()
                        .is_some_and(|p| dir.join(p).is_file())
            });
        let cell = match reused {
            Some(cell) => {
                progress.finish(format!("{}: done earlier, reused", plan.name));
                cell
            }
            None => {
                let cell = sweeper.measure(plan, key)?;
                crate::output::write_atomic(
                    &record,
                    serde_json::to_string_pretty(&cell)?.as_bytes(),
                )?;
                progress.finish(summary(&cell));
                cell
            }
        };
        cells.push(cell);
        // Keep the tables current, so a sweep stopped here leaves consistent results.
        let partial = results(
            metadata(wall.elapsed().as_secs_f64()),
            &cells,
            &skipped,
            &exact_image_path,
            exact_hdr_path.as_deref(),
        );
        write_results(&partial, dir)?;
    }
    progress.end();
    let results = results(
        metadata(wall.elapsed().as_secs_f64()),
        &cells,
        &skipped,
        &exact_image_path,
        exact_hdr_path.as_deref(),
    );
    write_results(&results, dir)?;
    let charts = super::charts::write_charts(&results, dir)?;
    super::report::write_html(&results, &charts, dir)?;
    Ok(results)
}

/// The results so far, with overhead ratios against the `none` cell.
fn results(
    metadata: SweepMetadata,
    cells: &[CellResult],
    skipped: &[SkippedCell],
    exact_image: &str,
    exact_hdr_image: Option<&str>,
) -> SweepResults {
    let baseline = cells
        .iter()
        .find(|c| c.technique == shadow::frame_baseline().name)
        .map(|c| c.frame_ms.median);
    let cells = cells
        .iter()
        .cloned()
        .map(|mut c| {
            let baseline = baseline.filter(|b| *b > 0.0);
            c.overhead_ratio = baseline.map(|b| c.frame_ms.median / b);
            c.shadow_ratio = baseline.map(|b| c.gpu_shadow_ms.median / b);
            c
        })
        .collect();
    SweepResults {
        metadata,
        cells,
        skipped: skipped.to_vec(),
        exact_image: exact_image.to_owned(),
        exact_hdr_image: exact_hdr_image.map(str::to_owned),
    }
}

/// One line about a finished cell.
fn summary(cell: &CellResult) -> String {
    let mut line = format!(
        "{} {} ch ({} used) {}² {}: {} bytes, frame {:.1} ms (shadow {:.1})",
        cell.technique,
        cell.channels,
        cell.channels_used,
        cell.shadow_res,
        cell.splat.name(),
        cell.bytes,
        cell.frame_ms.median,
        cell.gpu_shadow_ms.median
    );
    if let Some(e) = &cell.vs_exact {
        line.push_str(&format!(", FLIP vs exact {:.4}", e.flip_mean));
    }
    line
}

/// The CSV columns, in order (documented in the README).
pub const CSV_COLUMNS: &[&str] = &[
    "technique",
    "channels",
    "channels_used",
    "shadow_res",
    "splat",
    "bytes",
    "transient_bytes",
    "shadow_ms_median",
    "shadow_ms_min",
    "shadow_ms_max",
    "render_ms_median",
    "render_ms_min",
    "render_ms_max",
    "sort_ms_median",
    "frame_ms_median",
    "frame_ms_min",
    "frame_ms_max",
    "wall_ms_median",
    "frames_timed",
    "overhead_ratio",
    "shadow_ratio",
    "flip_vs_own_24",
    "rmse_vs_own_24",
    "flip_vs_exact",
    "rmse_vs_exact",
    "rms_transmittance_error",
    "image",
];

/// Writes `results.csv` (a row per cell) and `results.json` (everything) atomically.
pub fn write_results(results: &SweepResults, dir: &Path) -> anyhow::Result<()> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    writer.write_record(CSV_COLUMNS)?;
    let opt = |v: Option<f64>, digits: usize| v.map_or(String::new(), |v| format!("{v:.digits$}"));
    for c in &results.cells {
        writer.write_record([
            c.technique.clone(),
            c.channels.to_string(),
            c.channels_used.to_string(),
            c.shadow_res.to_string(),
            c.splat.name().to_owned(),
            c.bytes.to_string(),
            c.transient_bytes.to_string(),
            format!("{:.3}", c.gpu_shadow_ms.median),
            format!("{:.3}", c.gpu_shadow_ms.min),
            format!("{:.3}", c.gpu_shadow_ms.max),
            format!("{:.3}", c.gpu_render_ms.median),
            format!("{:.3}", c.gpu_render_ms.min),
            format!("{:.3}", c.gpu_render_ms.max),
            format!("{:.3}", c.cpu_sort_ms.median),
            format!("{:.3}", c.frame_ms.median),
            format!("{:.3}", c.frame_ms.min),
            format!("{:.3}", c.frame_ms.max),
            format!("{:.3}", c.wall_ms.median),
            c.frames_timed.to_string(),
            opt(c.overhead_ratio, 3),
            opt(c.shadow_ratio, 3),
            opt(c.vs_own_24.map(|e| e.flip_mean), 6),
            opt(c.vs_own_24.map(|e| e.rmse), 6),
            opt(c.vs_exact.map(|e| e.flip_mean), 6),
            opt(c.vs_exact.map(|e| e.rmse), 6),
            opt(c.rms_transmittance_error, 6),
            c.image.clone(),
        ])?;
    }
    let csv = writer.into_inner().context("cannot encode results.csv")?;
    crate::output::write_atomic(&dir.join("results.csv"), &csv)?;
    let json = serde_json::to_string_pretty(results)?;
    crate::output::write_atomic(&dir.join("results.json"), json.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_time_three_frames_or_two_slow_ones_once_their_seconds_are_spent() {
        // Before the seconds are spent: keep timing, up to `frames`.
        assert!(!timed_enough(&[0.1; 5], 0.45, 20, 0.5));
        assert!(timed_enough(&[0.1; 20], 1.9, 20, 0.5));
        // After: at least three frames ...
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
