//! `smokeshadow bench --volume cloud|FILE.vdb`: what a density volume's pieces cost on this
//! machine (issue 26, "Performance"), per grid size and step count: the cloud's noise textures
//! and its bake into a grid, the light march a map's texels or the reference take (T at a
//! 256² lattice of points beneath the volume), and the eye's march with secondary ray marching
//! (one ray a pixel). Times are wall-clock milliseconds from submission to the results' readback
//! (medians after warm-up runs: the first runs compile the shaders); these passes write no GPU
//! timestamps, so no GPU time is claimed for them.

use crate::Wait;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use glam::{DAffine3, UVec3, Vec3};

use smokeshadow_core::gpu::{Gpu, MemoryLedger};
use smokeshadow_core::medium::cloud::{CloudBaker, CloudNoiseGenerator};
use smokeshadow_core::medium::cloud_noise::CloudParams;
use smokeshadow_core::medium::eye::{EyeMarchProbe, EyeMarchSettings, EyeRay};
use smokeshadow_core::medium::gpu_grid::{GpuGrid, GridMarch};
use smokeshadow_core::medium::grid::DensityGrid;
use smokeshadow_core::medium::vdb;

/// The file the rows go to, in the bench's output folder.
pub const CSV_FILE: &str = "bench_volume.csv";
/// Points of the light march: a 256² lattice, a map's texels' worth of rays.
const LIGHT_LATTICE: u32 = 256;

/// What to bench.
#[derive(Clone, Debug, PartialEq)]
pub enum VolumeSource {
    /// The procedural cloud, baked at each grid size (a flat layer: size x size/4 x size).
    Cloud,
    /// An OpenVDB file's `density` grid, at its own size.
    File(PathBuf),
}

impl VolumeSource {
    pub fn parse(text: &str) -> Self {
        match text {
            "cloud" => Self::Cloud,
            path => Self::File(PathBuf::from(path)),
        }
    }
}

/// The bench's settings.
#[derive(Clone, Debug)]
pub struct VolumeBenchOptions {
    pub source: VolumeSource,
    /// Edge lengths of the cloud's bake (ignored for a file).
    pub grid_sizes: Vec<u32>,
    /// The cloud layer's coverages, 0..1 (ignored for a file): the dissertation's coverage
    /// axis (000 §4.1.5, 10-100%), along which SRM's cost grows with the cloud it crosses.
    pub coverages: Vec<f32>,
    /// Steps towards the light: the light march's, and SRM's per eye sample.
    pub light_steps: Vec<u32>,
    pub eye_steps: u32,
    pub frames: u32,
    pub warmup: u32,
    /// The eye march's rays: one a pixel of this frame.
    pub size_px: (u32, u32),
}

/// One measured stage.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeBenchRow {
    /// The grid's voxels along x, y, z, as `64x16x64`.
    pub grid: String,
    /// The cloud's coverage, for a baked cloud.
    pub coverage: Option<f32>,
    /// Bytes of the grid on the device.
    pub grid_bytes: u64,
    pub stage: &'static str,
    pub eye_steps: u32,
    pub light_steps: u32,
    /// Median wall time, submission to readback, ms.
    pub median_ms: f64,
    /// For the eye march: the RMS difference of its radiance from the run's march with the
    /// most light steps on the same grid (the 2018 thesis' sun-step experiment, 004 §4.1, whose
    /// reference took 100), over the pixels; `None` for the other stages.
    pub rmse_vs_most_steps: Option<f64>,
}

/// The cloud the bench bakes: a 6 km layer 1.5 km thick at `coverage`, its coverage map on.
fn bench_cloud(coverage: f32) -> CloudParams {
    CloudParams {
        origin_xz_m: [-3000.0, -3000.0],
        size_xz_m: [6000.0, 6000.0],
        altitude_m: 1500.0,
        thickness_m: 1500.0,
        coverage,
        density_per_m: 0.02,
        top_fraction: 1.0,
        shape_period_m: 4000.0,
        detail_period_m: 800.0,
        coverage_map: 1.0,
    }
}

/// Median of `frames` timed runs of `f` after `warmup` untimed ones.
fn median_ms(
    warmup: u32,
    frames: u32,
    mut f: impl FnMut() -> anyhow::Result<()>,
) -> anyhow::Result<f64> {
    for _ in 0..warmup {
        f()?;
    }
    let mut times = Vec::with_capacity(frames as usize);
    for _ in 0..frames.max(1) {
        let start = Instant::now();
        f()?;
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    Ok(times[times.len() / 2])
}

/// What a bench measured, and the grids it could not march (empty: no cloud at that coverage, or
/// a file's empty grid), one line each.
pub struct VolumeBench {
    pub rows: Vec<VolumeBenchRow>,
    pub skipped: Vec<String>,
}

/// Runs the bench: for each grid (each size and coverage of the cloud, or the file's), the light
/// march and the eye march at each light step count; for the cloud, the noise and the bake too.
pub fn run(gpu: &Gpu, options: &VolumeBenchOptions) -> anyhow::Result<VolumeBench> {
    let mut rows = Vec::new();
    let mut skipped = Vec::new();
    let mut ledger = MemoryLedger::for_device(&gpu.limits);
    let march = GridMarch::new(gpu);
    let eye = EyeMarchProbe::new(gpu);
    let grids: Vec<(Option<f32>, DensityGrid)> = match &options.source {
        VolumeSource::File(path) => {
            let bytes =
                std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
            let grid = vdb::read_float_grid(&bytes, "density", &vdb::Limits::default())
                .with_context(|| format!("{}", path.display()))?;
            vec![(
                None,
                DensityGrid::from_vdb(&grid, DAffine3::IDENTITY, 10.0)?,
            )]
        }
        VolumeSource::Cloud => {
            let generator = CloudNoiseGenerator::new(gpu);
            let baker = CloudBaker::new(gpu);
            let noise_ms = median_ms(options.warmup, options.frames, || {
                // The textures are made and dropped each run; `read_texels` would add a readback.
                let mut scratch = MemoryLedger::for_device(&gpu.limits);
                generator.generate(gpu, &mut scratch, 7)?;
                gpu.wait_idle()?;
                Ok(())
            })?;
            rows.push(VolumeBenchRow {
                grid: "noise 128+32".to_owned(),
                coverage: None,
                grid_bytes: (128u64.pow(3) + 32u64.pow(3)) * 16,
                stage: "cloud noise",
                eye_steps: 0,
                light_steps: 0,
                median_ms: noise_ms,
                rmse_vs_most_steps: None,
            });
            let noise = generator.generate(gpu, &mut ledger, 7)?;
            let mut grids = Vec::new();
            for &size in &options.grid_sizes {
                for &coverage in &options.coverages {
                    let params = bench_cloud(coverage);
                    let dims = UVec3::new(size, (size / 4).max(1), size);
                    let mut grid = None;
                    let bake_ms = median_ms(options.warmup, options.frames, || {
                        let mut scratch = MemoryLedger::for_device(&gpu.limits);
                        grid = Some(
                            baker
                                .bake(gpu, &mut scratch, &noise, &params, dims, glam::Vec3::ZERO)
                                .wait()?,
                        );
                        Ok(())
                    })?;
                    let grid = grid.expect("baked at least once");
                    rows.push(VolumeBenchRow {
                        grid: format!("{}x{}x{}", dims.x, dims.y, dims.z),
                        coverage: Some(coverage),
                        grid_bytes: 4 * u64::from(dims.x * dims.y * dims.z),
                        stage: "cloud bake (with readback)",
                        eye_steps: 0,
                        light_steps: 0,
                        median_ms: bake_ms,
                        rmse_vs_most_steps: None,
                    });
                    grids.push((Some(coverage), grid));
                }
            }
            grids
        }
    };
    for (coverage, grid) in &grids {
        let coverage = *coverage;
        let uploaded = GpuGrid::upload(gpu, &mut ledger, grid)?;
        let dims = grid.dims;
        let name = format!("{}x{}x{}", dims.x, dims.y, dims.z);
        let Some((lo, hi)) = grid
            .world_bounds()
            .filter(|_| grid.values.iter().any(|v| *v > 0.0))
        else {
            let at = coverage.map_or(String::new(), |c| format!(" at coverage {c}"));
            skipped.push(format!("{name}{at}: no density anywhere, nothing to march"));
            continue;
        };
        let (lo, hi) = (lo.as_vec3(), hi.as_vec3());
        let centre = 0.5 * (lo + hi);
        let extent = (hi - lo).length();
        // The volume's up: the cloud's y, a simulation's z (Houdini's and Blender's own).
        let up = match options.source {
            VolumeSource::Cloud => Vec3::Y,
            VolumeSource::File(_) => Vec3::Z,
        };
        let light = centre + up * extent;
        let (u_axis, v_axis) = up.any_orthonormal_pair();
        let points: Vec<Vec3> = (0..LIGHT_LATTICE * LIGHT_LATTICE)
            .map(|n| {
                let (i, j) = (n % LIGHT_LATTICE, n / LIGHT_LATTICE);
                let f = |k: u32| (k as f32 + 0.5) / LIGHT_LATTICE as f32 - 0.5;
                centre - up * (0.5 * extent) + (u_axis * f(i) + v_axis * f(j)) * extent
            })
            .collect();
        let (w, h) = options.size_px;
        let camera = centre + (v_axis - up * 0.3).normalize() * extent * 1.2;
        let forward = (centre - camera).normalize();
        let right = forward.cross(up).normalize();
        let cam_up = right.cross(forward);
        let rays: Vec<EyeRay> = (0..w * h)
            .map(|n| {
                let x = (n % w) as f32 / w as f32 - 0.5;
                let y = 0.5 - (n / w) as f32 / h as f32;
                let dir = (forward + right * x + cam_up * y * h as f32 / w as f32).normalize();
                EyeRay {
                    origin: camera,
                    dir,
                    t_near: 0.0,
                    t_far: 3.0 * extent,
                }
            })
            .collect();
        let most_steps = options.light_steps.iter().copied().max().unwrap_or(1);
        let mut images: Vec<(usize, Vec<f32>)> = Vec::new();
        let mut reference: Option<Vec<f32>> = None;
        for &light_steps in &options.light_steps {
            let light_ms = median_ms(options.warmup, options.frames, || {
                march
                    .transmittance(gpu, &uploaded, light, &points, light_steps)
                    .wait()?;
                Ok(())
            })?;
            rows.push(VolumeBenchRow {
                grid: name.clone(),
                coverage,
                grid_bytes: uploaded.bytes,
                stage: "light march at 256² points",
                eye_steps: 0,
                light_steps,
                median_ms: light_ms,
                rmse_vs_most_steps: None,
            });
            let settings = EyeMarchSettings {
                light,
                albedo: Vec3::ONE,
                eye_steps: options.eye_steps,
                light_steps,
                jitter: 0.5,
            };
            let mut radiance = Vec::new();
            let eye_ms = median_ms(options.warmup, options.frames, || {
                radiance = eye
                    .march(gpu, &uploaded, &settings, &rays)
                    .wait()?
                    .iter()
                    .map(|r| r.radiance.x)
                    .collect();
                Ok(())
            })?;
            images.push((rows.len(), radiance.clone()));
            if light_steps == most_steps {
                reference = Some(radiance);
            }
            rows.push(VolumeBenchRow {
                grid: name.clone(),
                coverage,
                grid_bytes: uploaded.bytes,
                stage: "eye march + SRM (ray a pixel)",
                eye_steps: options.eye_steps,
                light_steps,
                median_ms: eye_ms,
                rmse_vs_most_steps: None,
            });
        }
        if let Some(reference) = reference {
            for (row, image) in images {
                let sum: f64 = image
                    .iter()
                    .zip(&reference)
                    .map(|(a, b)| f64::from(a - b).powi(2))
                    .sum();
                rows[row].rmse_vs_most_steps = Some((sum / image.len().max(1) as f64).sqrt());
            }
        }
    }
    Ok(VolumeBench { rows, skipped })
}

/// The sun-step chart's file: for each grid, the eye march's time and its radiance's RMS
/// difference from the most light steps, against the light steps (the 2018 thesis' experiment).
pub const LIGHT_STEPS_CHART: &str = "bench_volume_light_steps.svg";

/// Writes [`LIGHT_STEPS_CHART`] into `folder` when the rows hold eye marches at more than one
/// light step count; returns its path.
pub fn write_chart(rows: &[VolumeBenchRow], folder: &Path) -> anyhow::Result<Option<PathBuf>> {
    use crate::sweep::charts::{LogLogSeries, log_log_svg};
    let mut series: Vec<LogLogSeries> = Vec::new();
    for r in rows.iter().filter(|r| r.rmse_vs_most_steps.is_some()) {
        let grid = match r.coverage {
            Some(c) => format!("{} at coverage {c}", r.grid),
            None => r.grid.clone(),
        };
        let x = f64::from(r.light_steps);
        for (label, y) in [
            (format!("{grid}: eye march ms"), r.median_ms),
            (
                format!("{grid}: RMSE against the most steps"),
                r.rmse_vs_most_steps.unwrap_or(f64::NAN),
            ),
        ] {
            LogLogSeries::push_point(&mut series, label, (x, y));
        }
    }
    if !series.iter().any(|s| s.points.len() > 1) {
        return Ok(None);
    }
    let svg = log_log_svg(
        "The eye march against the steps towards the light (the 2018 thesis' sun steps)",
        "light steps (log scale)",
        "ms, or RMSE of radiance (log scale)",
        &series,
    )?;
    std::fs::create_dir_all(folder)
        .with_context(|| format!("cannot create {}", folder.display()))?;
    let path = folder.join(LIGHT_STEPS_CHART);
    crate::output::write_atomic(&path, svg.as_bytes())?;
    Ok(Some(path))
}

/// Writes the rows as CSV into `folder` (created if missing), atomically.
pub fn write_csv(rows: &[VolumeBenchRow], folder: &Path) -> anyhow::Result<PathBuf> {
    std::fs::create_dir_all(folder)
        .with_context(|| format!("cannot create {}", folder.display()))?;
    let mut csv = csv::Writer::from_writer(Vec::new());
    csv.write_record([
        "grid",
        "coverage",
        "grid_bytes",
        "stage",
        "eye_steps",
        "light_steps",
        "median_wall_ms",
        "rmse_vs_most_light_steps",
    ])?;
    for r in rows {
        let rmse = r
            .rmse_vs_most_steps
            .map_or(String::new(), |e| format!("{e:.6}"));
        csv.write_record([
            r.grid.clone(),
            r.coverage.map_or(String::new(), |c| c.to_string()),
            r.grid_bytes.to_string(),
            r.stage.to_owned(),
            r.eye_steps.to_string(),
            r.light_steps.to_string(),
            format!("{:.3}", r.median_ms),
            rmse,
        ])?;
    }
    let text = csv.into_inner().map_err(|e| anyhow::anyhow!("{e}"))?;
    let path = folder.join(CSV_FILE);
    crate::output::write_atomic(&path, &text)?;
    Ok(path)
}
