//! The sweep engine: plans the cells, renders and times each one on one long-lived renderer
//! (pipelines are rebuilt only when the technique changes; the particles are simulated once),
//! compares it with its own 24-channel image and with `exact`, and persists it.

use crate::Wait;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;

use super::cells::{EXACT_HDR_IMAGE, EXACT_IMAGE, assemble, read_cell, write_results};
use super::shard::{self, PlannedCell, PlannedScene, Shard, ShardManifest};
use super::{CellResult, ImageError, Machine, MeasuredAgainst, SkippedCell, SweepResults};
use crate::diff;
use crate::progress::Progress;
use smokeshadow_core::gpu::Gpu;
use smokeshadow_core::render::{
    OffscreenTarget, ParticleRes, RenderOptions, Renderer, TechniqueConfig,
};
use smokeshadow_core::scene::Scene;
use smokeshadow_core::shadow::{self, SplatMode};
use smokeshadow_core::sim::Particle;
use smokeshadow_core::sweep::SceneHeader;
use smokeshadow_core::sweep::cell::{Bench, Prepared, Reference};
use smokeshadow_core::sweep::plan::{
    self, BASELINE_CHANNELS, CellTiming, DEFAULT_BYTES_PER_TEXEL, Grid, Plan, settings_key,
};

/// What to sweep. [`SweepOptions::default`] is the thesis experiment (chapter 4.2.1).
#[derive(Clone, Debug)]
pub struct SweepOptions {
    /// The axes the cells are laid out over.
    pub grid: Grid,
    /// How each cell is timed.
    pub timing: CellTiming,
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
}

impl Default for SweepOptions {
    fn default() -> Self {
        Self {
            grid: Grid {
                techniques: shadow::default_sweep(),
                channels: vec![24, 16, 8, 6],
                bytes_per_texel: DEFAULT_BYTES_PER_TEXEL.to_vec(),
                memory: Vec::new(),
                shadow_res: vec![512],
                splats: vec![SplatMode::Segment],
                particle_res: vec![ParticleRes::Full],
            },
            timing: CellTiming {
                frames: 20,
                warmup: 1,
                cell_seconds: 0.5,
                animate: None,
            },
            resume: false,
            exr: false,
            gallery: false,
            shard: None,
            shapes: crate::tune::shipped_shapes(),
        }
    }
}

/// Checks the options and lays out the cells ([`plan::plan`] over the options' grid).
fn plan(scene: &Scene, options: &SweepOptions) -> anyhow::Result<(Vec<Plan>, Vec<SkippedCell>)> {
    options.timing.check()?;
    if let Some(span) = options.timing.animate {
        check_sequence_frames(scene, &span)?;
    }
    plan::plan(scene, &options.grid)
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

/// What every cell of a sweeper is measured on and against ([`Bench`]), borrowing its fields
/// one by one so that its renderer stays free to lend mutably.
macro_rules! bench {
    ($sweeper:expr) => {
        Bench {
            gpu: $sweeper.gpu,
            scene: $sweeper.scene,
            particles: &$sweeper.particles,
            target: &$sweeper.target,
            points: &$sweeper.points,
            owners: &$sweeper.owners,
            exact_t: &$sweeper.exact_t,
        }
    };
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
        let mut reference = Reference::render(
            gpu,
            scene,
            &particles,
            options.grid.shadow_res[0],
            options.grid.splats[0],
        )
        .wait()?;
        crate::output::write_png_rgb(&dir.join(EXACT_IMAGE), &reference.image)?;
        if options.exr {
            let hdr =
                smokeshadow_core::gpu::read_texture_rgba16f(gpu, reference.renderer.hdr_texture())
                    .wait()?;
            crate::output::write_exr(&dir.join(EXACT_HDR_IMAGE), &hdr)?;
        }
        // No error is measured against a reference that disagrees with the closed form.
        let check = progress.suspend(|| {
            smokeshadow_core::render::reference_check::verify(
                &mut reference.renderer,
                gpu,
                scene,
                &particles,
            )
            .wait()
        })?;
        progress.finish(format!(
            "{}: exact reference ({}² light tiles): {} bytes, T at {} shaded points; {check}",
            scene.name,
            reference.tiles,
            reference.bytes,
            reference.points.len()
        ));
        let motion = match options.timing.animate {
            None => None,
            Some(span) => {
                progress.start(&format!("{}: exact over {}", scene.name, span.describe()));
                let frames = super::animate::ExactFrames::render(
                    gpu,
                    &mut reference.renderer,
                    &reference.target,
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
            shard: options.shard,
            motion: motion.as_ref().map(|m| super::MotionReference {
                change: m.change,
                check_points: m.check_points,
                check_worst: m.check_worst,
            }),
            ..reference.measured_against(&check, Machine::of(gpu).wait())
        };
        Ok(Self {
            gpu,
            scene,
            options,
            dir,
            particles,
            renderer: reference.renderer,
            target: reference.target,
            points: reference.points,
            owners: reference.owners,
            exact_t: reference.t,
            exact_image: std::sync::Arc::new(reference.image),
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

    /// The technique's own 24-channel image at the cell's resolution, splat and particle
    /// resolution ([`Sweeper::reference`]).
    fn own_baseline(&mut self, plan: &Plan) -> anyhow::Result<image::RgbImage> {
        self.reference(plan.own_baseline(self.scene))
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
            None => bench!(self)
                .render_image(&mut self.renderer, &baseline)
                .wait()?,
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

    /// Everything a cell does before its timed frames ([`Bench::prepare`]). None of it is
    /// timed, so the previous cell's comparisons may run beside it ([`Sweeper::time`]).
    fn prepare(&mut self, plan: &Plan) -> anyhow::Result<Prepared> {
        bench!(self)
            .prepare(&mut self.renderer, plan, self.options.timing.warmup)
            .wait()
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
        let (mut cell, image) = bench!(self)
            .time(
                &mut self.renderer,
                plan,
                prepared,
                &self.options.timing,
                key,
                &mut self.against,
            )
            .wait()?;
        let image_path = cell.image.clone();
        let mut hdr = None;
        if self.options.exr && record {
            let path = format!("images/{}.exr", plan.name);
            let frame =
                smokeshadow_core::gpu::read_texture_rgba16f(self.gpu, self.renderer.hdr_texture())
                    .wait()?;
            cell.hdr_image = Some(path.clone());
            hdr = Some((path, frame));
        }
        // The cell over the span (not `none`, which is compared with nothing).
        let animated = match (&self.motion, is_frame_baseline) {
            (Some(exact), false) => {
                let exact = std::sync::Arc::clone(exact);
                let (recorder, frames) =
                    exact.record(self.gpu, &mut self.renderer, &self.target, &plan.options())?;
                Some((recorder, frames, std::sync::Arc::clone(&exact.images)))
            }
            _ => None,
        };
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
                None => ImageError::NONE,
            });
            written?;
            let (vs_exact, x4, flip) = vs_exact?;
            cell.vs_exact = Some(vs_exact);
            cell.diff_exact = Some(x4);
            cell.flip_exact = Some(flip);
            match vs_own.transpose()? {
                None => cell.vs_own_24 = Some(ImageError::NONE),
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
        ImageError::of(&pair.metrics),
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
            header: SceneHeader::of(
                s,
                crate::particles::count(s) as u32,
                self.scene_sha256.clone(),
                self.shapes.clone(),
            ),
            folder: self.folder.clone(),
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
                    settings_key(scene, &scene_sha256, &options.timing, p),
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
    let machine = Machine::of(gpu).wait();
    let manifest = |finished: bool, measured: usize, reused: usize| {
        options.shard.map(|shard| ShardManifest {
            shard,
            tool_version: env!("CARGO_PKG_VERSION").to_owned(),
            frames: options.timing.frames,
            warmup: options.timing.warmup,
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
                        1 + usize::from(options.timing.animate.is_some())
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
                options.timing.frames,
                options.timing.warmup,
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
