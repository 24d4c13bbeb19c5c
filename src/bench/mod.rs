//! Scaling benchmarks: what each term of a frame costs as the particle count grows, on the
//! scaling family (`plume_scaled`, rescaled by [`crate::scene::Scene::with_particles`] so that
//! every count is the same plume, more finely sampled).
//!
//! For each count the smoke is simulated once (CPU wall time, on rayon's global pool), then
//! every technique renders `warmup` untimed frames and `frames` timed ones on one long-lived
//! renderer. A timed frame records the renderer's CPU sort (its own timer around the keys and
//! the sort), every GPU pass from timestamp queries ([`crate::gpu::GpuTimer`]: opaque,
//! particles, tone map, and the technique's shadow passes), the frame time as the sweep defines
//! it (GPU passes + CPU sort) and the wall time of `render` + reading the timestamps. After the
//! timed frames the technique's memory ledger (`total_bytes`) and counters are recorded. A
//! technique that refuses a configuration (its create, its budget check or its build fails) is
//! a refused cell with the one-line reason; the rest of the run goes on.
//!
//! Before the techniques, each count measures the cheapest possible build over the same
//! billboards, and after each technique's timed frames one more frame counts its build's
//! fragments (pipeline-statistics queries, where the adapter has them): [`bound`] sets each
//! build against that floor (ns per fragment, per channel written, and the ratio).
//!
//! [`write()`] puts `bench.csv` (a row per count x technique), `bench.json` (everything) and three
//! log-log SVG charts (time, GPU passes and bytes against the particle count) into a folder.

use crate::Wait;
pub mod bound;
pub mod volume;
pub mod volume_frames;

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use serde::Serialize;

use crate::progress::Progress;
use crate::sweep::Timing;
use crate::sweep::charts::{LogLogSeries, log_log_svg};
use bound::{Bound, BuildWork, CheapestBuild, CheapestMeasured};
use smokeshadow_core::gpu::Gpu;
use smokeshadow_core::render::{
    OUTPUT_FORMAT, OffscreenTarget, ParticleRes, RenderOptions, Renderer, SortOrder,
    TechniqueConfig,
};
use smokeshadow_core::scene::Scene;
use smokeshadow_core::shadow;

/// The particle counts a bench runs by default: the thesis' 2,500 up to a million, about a
/// factor of four apart.
pub const DEFAULT_COUNTS: [u32; 5] = [2_500, 16_384, 65_536, 262_144, 1_000_000];

/// Output size of a bench frame unless asked otherwise: small enough that lavapipe renders a
/// million particles in a usable time, large enough that the per-pixel passes still show.
pub const DEFAULT_SIZE_PX: (u32, u32) = (512, 384);

/// What to measure.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Particle counts, in the order they are run.
    pub counts: Vec<u32>,
    /// Registry names.
    pub techniques: Vec<String>,
    /// The channel budget every technique gets (one below a technique's minimum is refused).
    pub channels: u32,
    pub frames: u32,
    pub warmup: u32,
    /// The particle pass's resolution (`--particle-res`).
    pub particle_res: ParticleRes,
    /// The orders of the frame's one sort to measure each technique with (`--sort`); every
    /// order but the view's also measures its image against the view-sorted one.
    pub sorts: Vec<SortOrder>,
}

/// Everything one bench measured.
#[derive(Clone, Debug, Serialize)]
pub struct BenchResults {
    pub scene: String,
    /// The scene's own particle count, N0 of the scaling rule.
    pub scene_particles: u32,
    pub width_px: u32,
    pub height_px: u32,
    pub shadow_res: u32,
    pub channels: u32,
    pub frames: u32,
    pub warmup: u32,
    /// The particle pass's resolution, `1`, `1/2` or `1/4` of the frame's per axis.
    pub particle_res: ParticleRes,
    /// The sort orders measured (`--sort`).
    pub sorts: Vec<SortOrder>,
    pub adapter: String,
    /// Whether GPU pass times were measured (the adapter has timestamp queries).
    pub gpu_timestamps: bool,
    /// The round trip of an empty submission ([`crate::gpu::Gpu::clock_floor_ms`]), which every
    /// frame's wall time pays beyond its passes.
    pub clock_floor_ms: f64,
    /// Threads of rayon's pool (the simulation and the sort); `RAYON_NUM_THREADS` sets it.
    pub cpu_threads: usize,
    pub counts: Vec<CountResult>,
}

/// One particle count.
#[derive(Clone, Debug, Serialize)]
pub struct CountResult {
    pub particles: u32,
    /// Fixed steps simulated and their CPU wall time.
    pub sim_steps: u64,
    pub sim_ms: f64,
    /// The cheapest possible build over these particles' billboards ([`bound`]), measured
    /// before the techniques; `None` when it failed (its reason is printed).
    pub cheapest: Option<CheapestMeasured>,
    pub cells: Vec<Cell>,
}

/// One technique at one count and sort order: measured, or refused with the reason.
#[derive(Clone, Debug, Serialize)]
pub struct Cell {
    pub technique: String,
    pub sort: SortOrder,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refused: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub measured: Option<Measured>,
}

/// A measured cell (times in milliseconds over the timed frames).
#[derive(Clone, Debug, Serialize)]
pub struct Measured {
    pub channels_used: u32,
    /// The technique's memory ledger after the frames.
    pub bytes: u64,
    /// The technique's counters after the frames (e.g. `exact`'s segments).
    pub counters: BTreeMap<String, u64>,
    /// The CPU sort(s) of the frame (the renderer's, plus a technique's own).
    pub sort_ms: Timing,
    /// GPU time per pass, in the order the frame records them.
    pub gpu_passes: Vec<PassTiming>,
    pub gpu_total_ms: Timing,
    /// GPU passes + CPU sort, as the sweep counts a frame.
    pub frame_ms: Timing,
    /// CPU wall time of `render` and reading its timestamps back.
    pub wall_ms: Timing,
    /// For the reference: the worst |ΔT| of its self-check against the f64 closed form
    /// (core/src/render/reference_check.rs; a larger one refuses the cell).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_check_worst: Option<f64>,
    /// The build passes' fragment work, counted in one more frame after the timed ones (absent
    /// without pipeline-statistics queries, or for a technique without build passes).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub build_work: Option<BuildWork>,
    /// The build against the cheapest build at the same count ([`bound`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bound: Option<Bound>,
    /// Fragment shader invocations of the last frame's particle pass (pipeline-statistics
    /// query; absent without one, or when the technique draws its own particle pass).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub particle_fragments: Option<u64>,
    /// For a sort order other than the view's: its frame against the same technique's
    /// view-sorted frame (what sharing the sort costs in accuracy).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vs_view_sort: Option<crate::sweep::ImageError>,
}

#[derive(Clone, Debug, Serialize)]
pub struct PassTiming {
    pub pass: String,
    pub ms: Timing,
}

impl Cell {
    /// The technique's name, with the sort order when it is not the view's: a row's and a
    /// series' name.
    pub fn label(&self) -> String {
        match self.sort {
            SortOrder::View => self.technique.clone(),
            sort => format!("{} ({sort} sort)", self.technique),
        }
    }

    /// The GPU time of `pass`, if measured.
    pub fn pass_ms(&self, pass: &str) -> Option<Timing> {
        let m = self.measured.as_ref()?;
        m.gpu_passes.iter().find(|p| p.pass == pass).map(|p| p.ms)
    }
}

impl BenchResults {
    /// Every GPU pass name any cell recorded, in first-recorded order.
    pub fn pass_names(&self) -> Vec<String> {
        let mut names: Vec<String> = Vec::new();
        for m in self.measured() {
            for p in &m.1.gpu_passes {
                if !names.contains(&p.pass) {
                    names.push(p.pass.clone());
                }
            }
        }
        names
    }

    /// Every counter name any cell recorded, sorted.
    pub fn counter_names(&self) -> Vec<String> {
        let mut names: Vec<String> = self
            .measured()
            .flat_map(|(_, m)| m.counters.keys().cloned())
            .collect();
        names.sort();
        names.dedup();
        names
    }

    /// The cells' labels ([`Cell::label`]) in the order they ran.
    pub fn labels(&self) -> Vec<String> {
        let mut names: Vec<String> = Vec::new();
        for c in self.counts.iter().flat_map(|c| &c.cells) {
            let label = c.label();
            if !names.contains(&label) {
                names.push(label);
            }
        }
        names
    }

    fn measured(&self) -> impl Iterator<Item = (&Cell, &Measured)> {
        self.counts
            .iter()
            .flat_map(|c| &c.cells)
            .filter_map(|c| c.measured.as_ref().map(|m| (c, m)))
    }
}

/// Checks the options before any work.
fn check(options: &BenchOptions) -> anyhow::Result<()> {
    if options.counts.is_empty() {
        anyhow::bail!("--particles-list is empty: give at least one count");
    }
    if options.techniques.is_empty() {
        anyhow::bail!("no technique to measure: give at least one --technique");
    }
    if options.frames == 0 {
        anyhow::bail!("--frames 0: time at least one frame");
    }
    if options.sorts.is_empty() {
        anyhow::bail!("--sort is empty: give view, half-angle or both");
    }
    for name in &options.techniques {
        shadow::find(name)?;
    }
    Ok(())
}

/// Runs the bench of `scene` (its output size is the frame size) on `gpu`.
pub fn run(gpu: &Gpu, scene: &Scene, options: &BenchOptions) -> anyhow::Result<BenchResults> {
    check(options)?;
    let (w, h) = (scene.output.width_px, scene.output.height_px);
    let baseline = TechniqueConfig {
        name: shadow::frame_baseline().name.to_owned(),
        params: scene.shadow.params(1),
    };
    // One renderer for every cell: pipelines are rebuilt only when the technique changes.
    let mut renderer = Renderer::new(gpu, w, h, OUTPUT_FORMAT, &baseline).wait()?;
    let target = OffscreenTarget::new(gpu, w, h);
    let mut results = BenchResults {
        scene: scene.name.clone(),
        scene_particles: crate::particles::count(scene) as u32,
        width_px: w,
        height_px: h,
        shadow_res: scene.shadow.resolution_px,
        channels: options.channels,
        frames: options.frames,
        warmup: options.warmup,
        particle_res: options.particle_res,
        sorts: options.sorts.clone(),
        adapter: gpu.describe(),
        gpu_timestamps: gpu.has_timestamps(),
        clock_floor_ms: gpu.clock_floor_ms().wait(),
        cpu_threads: rayon::current_num_threads(),
        counts: Vec::new(),
    };
    let mut progress = Progress::new(
        options.counts.len() * options.techniques.len() * options.sorts.len(),
        "cells",
    );
    for &count in &options.counts {
        let scaled = scene.clone().with_particles(count)?;
        progress.start(&format!("simulating {count} particles"));
        let sim_start = Instant::now();
        let particles = progress.suspend(|| crate::particles::scene_particles(&scaled))?;
        let sim_ms = sim_start.elapsed().as_secs_f64() * 1e3;
        progress.start(&format!("cheapest build at {count} particles"));
        let mut bench = CellBench {
            gpu,
            renderer: &mut renderer,
            scene: &scaled,
            particles: &particles,
            target: &target,
            options,
        };
        let cheapest = match bench.measure_cheapest() {
            Ok(measured) => Some(measured),
            Err(err) => {
                progress
                    .suspend(|| eprintln!("warning: cheapest build at {count} particles: {err:#}"));
                None
            }
        };
        let mut counted = CountResult {
            particles: count,
            sim_steps: smokeshadow_core::sim::step_index(scaled.sim.step_s, scaled.sim.duration_s),
            sim_ms,
            cheapest,
            cells: Vec::new(),
        };
        for name in &options.techniques {
            for &sort in &options.sorts {
                progress.start(&format!("{name} at {count} particles, {sort} sort"));
                let config = TechniqueConfig {
                    name: name.clone(),
                    params: scaled.shadow.params(options.channels),
                };
                let measured = bench.measure(&config, sort, counted.cheapest.as_ref());
                let cell = Cell {
                    technique: name.clone(),
                    sort,
                    refused: measured
                        .as_ref()
                        .err()
                        .map(|err| format!("{err:#}").replace('\n', " ")),
                    measured: measured.ok(),
                };
                progress.finish(summary(count, &cell));
                counted.cells.push(cell);
            }
        }
        results.counts.push(counted);
    }
    progress.end();
    Ok(results)
}

/// One line per finished cell, for the progress output.
fn summary(count: u32, cell: &Cell) -> String {
    match (&cell.measured, &cell.refused) {
        (Some(m), _) => format!(
            "{} at {count} particles: frame {:.2} ms (sort {:.2} ms), {} bytes",
            cell.label(),
            m.frame_ms.median,
            m.sort_ms.median,
            m.bytes
        ),
        (None, reason) => format!(
            "{} at {count} particles: refused: {}",
            cell.label(),
            reason.as_deref().unwrap_or("?")
        ),
    }
}

/// What measuring one cell needs.
struct CellBench<'a> {
    gpu: &'a Gpu,
    renderer: &'a mut Renderer,
    scene: &'a Scene,
    particles: &'a [smokeshadow_core::sim::Particle],
    target: &'a OffscreenTarget,
    options: &'a BenchOptions,
}

impl CellBench<'_> {
    /// The cheapest build ([`bound::CheapestBuild`]): `warmup` and `frames` frames of it alone,
    /// then one counted frame.
    fn measure_cheapest(&mut self) -> anyhow::Result<CheapestMeasured> {
        let cheapest = CheapestBuild::new(
            self.gpu,
            self.renderer.frame_layout(),
            self.scene.shadow.resolution_px,
        )?;
        let mut pass = |_: &Gpu, inputs: shadow::BuildInputs<'_>| {
            cheapest.record(inputs);
            Ok(())
        };
        for _ in 0..self.options.warmup {
            self.renderer
                .light_pass_frame(self.gpu, self.scene, self.particles, &mut pass)
                .wait()?;
            self.gpu.wait_idle()?;
        }
        let mut build = Vec::new();
        for _ in 0..self.options.frames {
            self.renderer
                .light_pass_frame(self.gpu, self.scene, self.particles, &mut pass)
                .wait()?;
            let times = self.renderer.gpu_times(self.gpu).wait()?;
            if let Some(ms) = times.get(bound::BUILD_PASS) {
                build.push(ms);
            }
        }
        if build.is_empty() {
            anyhow::bail!("no GPU timestamps to time it with");
        }
        let mut work = None;
        if self.renderer.set_count_fragments(self.gpu, true) {
            self.renderer
                .light_pass_frame(self.gpu, self.scene, self.particles, &mut pass)
                .wait()?;
            work = BuildWork::of(&self.renderer.fragment_counts(self.gpu).wait()?);
            self.renderer.set_count_fragments(self.gpu, false);
        }
        Ok(CheapestMeasured {
            build_ms: Timing::of(&build),
            work,
        })
    }

    /// The fragment tallies of one more frame (the build's passes and the particle pass), if
    /// the adapter counts fragments.
    fn count_frame(
        &mut self,
        options: &RenderOptions,
    ) -> anyhow::Result<Vec<smokeshadow_core::gpu::FragmentTally>> {
        if !self.renderer.set_count_fragments(self.gpu, true) {
            return Ok(Vec::new());
        }
        self.render(options)?;
        let tallies = self.renderer.fragment_counts(self.gpu).wait()?;
        self.renderer.set_count_fragments(self.gpu, false);
        Ok(tallies)
    }

    /// One frame of the cell's particles with `options` into the target.
    fn render(
        &mut self,
        options: &RenderOptions,
    ) -> Result<smokeshadow_core::render::FrameStats, shadow::ShadowError> {
        self.renderer
            .render(
                self.gpu,
                self.scene,
                self.particles,
                options,
                &self.target.view,
            )
            .wait()
    }

    /// The tone-mapped frame the target holds, read back.
    fn read_image(&self) -> anyhow::Result<image::RgbImage> {
        Ok(self.target.read_rgb(self.gpu).wait()?)
    }

    fn measure(
        &mut self,
        config: &TechniqueConfig,
        sort: SortOrder,
        cheapest: Option<&CheapestMeasured>,
    ) -> anyhow::Result<Measured> {
        // `shadow::create` (through `set_technique`) checks the budget and the parameters.
        self.renderer.set_technique(self.gpu, config).wait()?;
        let options = RenderOptions {
            particle_res: self.options.particle_res,
            sort,
            ..RenderOptions::default()
        };
        for _ in 0..self.options.warmup {
            self.render(&options)?;
            self.gpu.wait_idle()?;
        }
        let mut passes: Vec<(&'static str, Vec<f64>)> = Vec::new();
        let (mut sort_times, mut gpu_total, mut frame, mut wall) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for _ in 0..self.options.frames {
            let start = Instant::now();
            let stats = self.render(&options)?;
            let times = self.renderer.gpu_times(self.gpu).wait()?;
            wall.push(start.elapsed().as_secs_f64() * 1e3);
            sort_times.push(stats.sort_ms);
            gpu_total.push(times.total_ms());
            frame.push(stats.frame_ms(&times));
            for (name, ms) in times.passes {
                match passes.iter_mut().find(|(n, _)| *n == name) {
                    Some((_, v)) => v.push(ms),
                    None => passes.push((name, vec![ms])),
                }
            }
        }
        let tallies = self.count_frame(&options)?;
        // The reference checks itself on the cell's own particles (nothing else measured here).
        let reference_check = smokeshadow_core::render::reference_check::verify_if_reference(
            self.renderer,
            self.gpu,
            self.scene,
            self.particles,
        )
        .wait()?;
        let vs_view_sort = match sort {
            SortOrder::View => None,
            _ => {
                // The target holds this order's frame: the counted one, or the last timed one.
                let shared = self.read_image()?;
                self.render(&RenderOptions {
                    sort: SortOrder::View,
                    ..options
                })?;
                let view = self.read_image()?;
                let metrics = crate::diff::compare(&view, &shared)?.metrics;
                Some(crate::sweep::ImageError::of(&metrics))
            }
        };
        let build_work = BuildWork::of(&tallies);
        let build_ms = passes
            .iter()
            .find(|(n, _)| *n == bound::BUILD_PASS)
            .map(|(_, v)| Timing::of(v).median);
        let bound = build_ms
            .zip(cheapest)
            .and_then(|(ms, floor)| Bound::new(ms, build_work, floor));
        let technique = self.renderer.technique();
        Ok(Measured {
            channels_used: technique.channels_used(),
            bytes: self.renderer.shadow_bytes().0,
            counters: self.renderer.counters().into_iter().collect(),
            sort_ms: Timing::of(&sort_times),
            gpu_passes: passes
                .into_iter()
                .map(|(pass, v)| PassTiming {
                    pass: pass.to_owned(),
                    ms: Timing::of(&v),
                })
                .collect(),
            gpu_total_ms: Timing::of(&gpu_total),
            frame_ms: Timing::of(&frame),
            wall_ms: Timing::of(&wall),
            build_work,
            bound,
            particle_fragments: smokeshadow_core::render::particle_fragments(&tallies),
            vs_view_sort,
            reference_check_worst: reference_check.map(|c| c.worst_difference),
        })
    }
}

/// The CSV's fixed leading columns; then `gpu_<pass>_ms` per pass, `counter_<name>` per
/// counter, and `refused`.
pub const CSV_COLUMNS: &[&str] = &[
    "particles",
    "technique",
    "sort",
    "sim_ms",
    "sort_ms_median",
    "gpu_total_ms_median",
    "frame_ms_median",
    "frame_ms_min",
    "frame_ms_max",
    "wall_ms_median",
    "channels_used",
    "bytes",
    // The bound of the build ([`bound::Bound`]); empty where there is none.
    "build_ms_median",
    "fragments",
    "channel_writes",
    "bytes_written",
    "ns_per_fragment",
    "ns_per_channel_write",
    "cheapest_build_ms",
    "cheapest_fragments",
    "build_over_cheapest",
    // The frame against the view-sorted one, for another sort order; empty for the view's.
    "vs_view_sort_flip_mean",
    "vs_view_sort_rmse",
];

/// The files [`write()`] puts in its folder.
pub const CSV_FILE: &str = "bench.csv";
pub const JSON_FILE: &str = "bench.json";
pub const CHART_FILES: [&str; 3] = [
    "time_vs_particles.svg",
    "gpu_passes_vs_particles.svg",
    "bytes_vs_particles.svg",
];

/// Writes `bench.csv`, `bench.json` and the charts into `dir` (created if missing), each
/// atomically; returns the paths written.
pub fn write(results: &BenchResults, dir: &Path) -> anyhow::Result<Vec<std::path::PathBuf>> {
    use anyhow::Context;
    if dir.is_file() {
        anyhow::bail!("output {} is a file; give a folder", dir.display());
    }
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut written = Vec::new();
    let mut put = |name: &str, bytes: &[u8]| -> anyhow::Result<()> {
        let path = dir.join(name);
        crate::output::write_atomic(&path, bytes)?;
        written.push(path);
        Ok(())
    };
    put(CSV_FILE, &csv(results)?)?;
    put(JSON_FILE, serde_json::to_string_pretty(results)?.as_bytes())?;
    for (name, svg) in CHART_FILES.iter().zip(charts(results)?) {
        put(name, svg.as_bytes())?;
    }
    Ok(written)
}

fn csv(results: &BenchResults) -> anyhow::Result<Vec<u8>> {
    let passes = results.pass_names();
    let counters = results.counter_names();
    let mut writer = csv::Writer::from_writer(Vec::new());
    let mut header: Vec<String> = CSV_COLUMNS.iter().map(|c| (*c).to_owned()).collect();
    header.extend(passes.iter().map(|p| format!("gpu_{p}_ms_median")));
    header.extend(counters.iter().map(|c| format!("counter_{c}")));
    header.push("refused".into());
    writer.write_record(&header)?;
    let ms = |v: f64| format!("{v:.4}");
    for count in &results.counts {
        for cell in &count.cells {
            let mut row = vec![
                count.particles.to_string(),
                cell.technique.clone(),
                cell.sort.name().to_owned(),
                ms(count.sim_ms),
            ];
            match &cell.measured {
                Some(m) => {
                    row.extend([
                        ms(m.sort_ms.median),
                        ms(m.gpu_total_ms.median),
                        ms(m.frame_ms.median),
                        ms(m.frame_ms.min),
                        ms(m.frame_ms.max),
                        ms(m.wall_ms.median),
                        m.channels_used.to_string(),
                        m.bytes.to_string(),
                    ]);
                    row.extend(bound_fields(m.bound.as_ref()));
                    row.extend(match &m.vs_view_sort {
                        Some(e) => [format!("{:.5}", e.flip_mean), format!("{:.5}", e.rmse)],
                        None => [String::new(), String::new()],
                    });
                    row.extend(
                        passes
                            .iter()
                            .map(|p| cell.pass_ms(p).map_or(String::new(), |t| ms(t.median))),
                    );
                    row.extend(
                        counters
                            .iter()
                            .map(|c| m.counters.get(c).map_or(String::new(), u64::to_string)),
                    );
                }
                None => row.extend(std::iter::repeat_n(
                    String::new(),
                    CSV_COLUMNS.len() - 4 + passes.len() + counters.len(),
                )),
            }
            row.push(cell.refused.clone().unwrap_or_default());
            writer.write_record(&row)?;
        }
    }
    writer
        .into_inner()
        .map_err(|e| anyhow::anyhow!("cannot encode {CSV_FILE}: {e}"))
}

/// The bound columns of a row ([`CSV_COLUMNS`] from `build_ms_median`), empty without one.
fn bound_fields(bound: Option<&Bound>) -> Vec<String> {
    let Some(b) = bound else {
        return vec![String::new(); 9];
    };
    vec![
        format!("{:.4}", b.build_ms),
        b.fragments.to_string(),
        b.channel_writes.to_string(),
        b.bytes_written.to_string(),
        format!("{:.4}", b.ns_per_fragment),
        format!("{:.4}", b.ns_per_channel_write),
        format!("{:.4}", b.cheapest_build_ms),
        b.cheapest_fragments.to_string(),
        format!("{:.4}", b.over_cheapest),
    ]
}

/// The three charts' SVG documents, in [`CHART_FILES`] order.
fn charts(results: &BenchResults) -> anyhow::Result<Vec<String>> {
    let x_label = "particles (log scale)";
    let ms_label = "milliseconds (log scale)";
    let techniques = results.labels();
    // A line over the counts where `value` gives a point.
    let line = |label: String, value: &dyn Fn(&CountResult) -> Option<f64>| LogLogSeries {
        label,
        points: results
            .counts
            .iter()
            .filter_map(|c| Some((f64::from(c.particles), value(c)?)))
            .collect(),
    };
    let cell = |c: &'_ CountResult, t: &str| -> Option<Measured> {
        c.cells
            .iter()
            .find(|cell| cell.label() == t)
            .and_then(|cell| cell.measured.clone())
    };

    let mut time = vec![line("simulation (CPU)".into(), &|c| Some(c.sim_ms))];
    // The renderer's sort is the same for every technique (a technique's own sort adds to it):
    // the least over the cells is the renderer's.
    time.push(line("back-to-front sort (CPU)".into(), &|c| {
        c.cells
            .iter()
            .filter_map(|cell| cell.measured.as_ref().map(|m| m.sort_ms.median))
            .min_by(f64::total_cmp)
    }));
    for t in &techniques {
        time.push(line(format!("{t}: frame (GPU + sort)"), &|c| {
            cell(c, t).map(|m| m.frame_ms.median)
        }));
    }

    let mut passes = Vec::new();
    for t in &techniques {
        for p in results.pass_names() {
            let series = line(format!("{t}: {p}"), &|c| {
                c.cells
                    .iter()
                    .find(|cell| cell.label() == *t)
                    .and_then(|cell| cell.pass_ms(&p))
                    .map(|ms| ms.median)
            });
            if !series.points.is_empty() {
                passes.push(series);
            }
        }
    }

    let bytes: Vec<LogLogSeries> = techniques
        .iter()
        .map(|t| {
            line(t.clone(), &|c| {
                cell(c, t).map(|m| m.bytes as f64).filter(|b| *b > 0.0)
            })
        })
        .filter(|s| !s.points.is_empty())
        .collect();

    let size = format!("{}x{}", results.width_px, results.height_px);
    Ok(vec![
        log_log_svg(
            &format!(
                "Time per term against particle count ({}, {size})",
                results.scene
            ),
            x_label,
            ms_label,
            &time,
        )?,
        log_log_svg(
            &format!("GPU time per pass against particle count ({size})"),
            x_label,
            ms_label,
            &passes,
        )?,
        log_log_svg(
            "Technique memory against particle count",
            x_label,
            "bytes (log scale)",
            &bytes,
        )?,
    ])
}
