//! A sweep's measured cells as records: each cell's JSON under `cells/`, a scene's results
//! assembled from them (with the overhead ratios), and the tables `results.csv` and
//! `results.json` written from those results.

use std::path::Path;

use anyhow::Context;

use super::shard::PlannedScene;
use super::{CellResult, Machine, MeasuredAgainst, SweepMetadata, SweepResults};
use smokeshadow_core::shadow;

/// Path of the `exact` reference image inside a scene's folder.
pub(super) const EXACT_IMAGE: &str = "images/exact.png";

/// Path of `exact`'s HDR frame inside a scene's folder.
pub(super) const EXACT_HDR_IMAGE: &str = "images/exact.exr";

/// Reads a cell record; `None` when missing or unreadable (a cell not finished).
pub(super) fn read_cell(path: &Path) -> Option<CellResult> {
    std::fs::read_to_string(path)
        .ok()
        .and_then(|text| serde_json::from_str(&text).ok())
}

/// A scene's results from its planned cells and the cells finished so far (in plan order),
/// with their overhead ratios ([`with_ratios`]). The machine and the `exact` figures come
/// from the cells' records, `fallback` and `exact` stand in for cells written before those
/// existed.
#[allow(clippy::too_many_arguments)]
pub(super) fn assemble(
    planned: &PlannedScene,
    tool_version: &str,
    frames: u32,
    warmup: u32,
    cells: &[CellResult],
    fallback: Option<&Machine>,
    exact: Option<(u64, u32)>,
    started: String,
    wall_s: f64,
    shards: Vec<String>,
    scene_dir: &Path,
) -> SweepResults {
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
        .or(exact)
        .unwrap_or((0, 0));
    let metadata = SweepMetadata {
        tool_version: tool_version.to_owned(),
        scene: planned.name.clone(),
        description: planned.description.clone(),
        scene_sha256: planned.scene_sha256.clone(),
        seed: planned.seed,
        particles: planned.particles,
        width_px: planned.width_px,
        height_px: planned.height_px,
        framing: planned.framing,
        shapes: planned.shapes.clone(),
        adapter: distinct(&|m| m.adapter.clone(), fallback.map(|m| m.adapter.clone())),
        backend: distinct(&|m| m.backend.clone(), fallback.map(|m| m.backend.clone())),
        driver: distinct(&|m| m.driver.clone(), fallback.map(|m| m.driver.clone())),
        timestamp_queries: match against.is_empty() {
            true => fallback.is_some_and(|m| m.timestamp_queries),
            false => against.iter().all(|a| a.machine.timestamp_queries),
        },
        clock_floor_ms: against
            .iter()
            .map(|a| a.machine.clock_floor_ms)
            .chain(fallback.map(|m| m.clock_floor_ms))
            .fold(0.0, f64::max),
        frames,
        warmup,
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
        started,
        wall_s,
        shards,
        motion: against.iter().find_map(|a| a.motion.clone()),
    };
    let baseline = cells
        .iter()
        .find(|c| c.technique == shadow::frame_baseline().name)
        .map(|c| c.frame_ms.median);
    let cells = cells
        .iter()
        .cloned()
        .map(|mut c| {
            with_ratios(&mut c, baseline);
            c
        })
        .collect();
    SweepResults {
        metadata,
        cells,
        skipped: planned.skipped.clone(),
        exact_image: EXACT_IMAGE.to_owned(),
        exact_hdr_image: scene_dir
            .join(EXACT_HDR_IMAGE)
            .is_file()
            .then(|| EXACT_HDR_IMAGE.to_owned()),
        animation: None,
    }
}

/// Sets a cell's overhead and shadow ratios: against the `none` frame time of the process that
/// measured it, or for a cell written before that was recorded, against `results_none` (the
/// `none` cell of the results).
pub(super) fn with_ratios(cell: &mut CellResult, results_none: Option<f64>) {
    let baseline = cell
        .measured_against
        .as_ref()
        .map(|a| a.none_frame_ms)
        .or(results_none)
        .filter(|b| b.is_finite() && *b > 0.0);
    cell.overhead_ratio = baseline.map(|b| cell.frame_ms.median / b);
    cell.shadow_ratio = baseline.map(|b| cell.gpu_shadow_ms.median / b);
}

/// The CSV columns, in order (documented in docs/sweeps.md).
pub const CSV_COLUMNS: &[&str] = &[
    "technique",
    "channels",
    "byte_budgets",
    "memory_budgets",
    "channels_used",
    "shadow_res",
    "splat",
    "particle_res",
    "resident_bytes",
    "persistent_bytes",
    "transient_bytes",
    "smoke_texels",
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
    "particles_ms_median",
    "upsample_ms_median",
    "particle_fragments",
    "flip_vs_full_res",
    "motion_frames",
    "temporal_error",
    "temporal_p999",
    "temporal_p999_worst",
    "pops_per_frame",
    "t_temporal_error",
    "t_temporal_p999",
    "frame_error",
    "flip_t_median",
    "flip_t_p95",
    "flip_t_std",
    "image",
];

/// Writes `results.csv` (a row per cell) and `results.json` (everything) atomically.
pub fn write_results(results: &SweepResults, dir: &Path) -> anyhow::Result<()> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    writer.write_record(CSV_COLUMNS)?;
    for c in &results.cells {
        writer.write_record(csv_row(c))?;
    }
    let csv = writer.into_inner().context("cannot encode results.csv")?;
    crate::output::write_atomic(&dir.join("results.csv"), &csv)?;
    let json = serde_json::to_string_pretty(results)?;
    crate::output::write_atomic(&dir.join("results.json"), json.as_bytes())
}

/// A cell's `results.csv` row, in [`CSV_COLUMNS`] order.
pub(super) fn csv_row(c: &CellResult) -> Vec<String> {
    let opt = |v: Option<f64>, digits: usize| v.map_or(String::new(), |v| format!("{v:.digits$}"));
    // The temporal measures are a few 1e-4 of luminance: three significant digits.
    let motion = |f: fn(&smokeshadow_core::motion::Motion) -> f64| {
        c.motion
            .as_ref()
            .map_or(String::new(), |m| format!("{:.3e}", f(m)))
    };
    vec![
        c.technique.clone(),
        c.channels.to_string(),
        c.byte_budgets
            .iter()
            .map(u32::to_string)
            .collect::<Vec<_>>()
            .join(";"),
        c.memory_budgets
            .iter()
            .map(u64::to_string)
            .collect::<Vec<_>>()
            .join(";"),
        c.channels_used.to_string(),
        c.shadow_res.to_string(),
        c.splat.name().to_owned(),
        c.particle_res.name().to_owned(),
        c.resident_bytes.to_string(),
        c.persistent_bytes().to_string(),
        c.transient_bytes.to_string(),
        c.smoke_texels.to_string(),
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
        format!("{:.3}", c.particles_ms.median),
        format!("{:.3}", c.upsample_ms.median),
        c.particle_fragments
            .map_or(String::new(), |n| n.to_string()),
        opt(c.vs_full_res.map(|e| e.flip_mean), 6),
        c.motion
            .as_ref()
            .map_or(String::new(), |m| m.frames.to_string()),
        motion(|m| m.temporal_error),
        motion(|m| m.temporal_p999),
        motion(|m| m.temporal_p999_worst),
        c.motion
            .as_ref()
            .map_or(String::new(), |m| format!("{:.2}", m.pops_per_frame)),
        motion(|m| m.t_temporal_error),
        motion(|m| m.t_temporal_p999),
        motion(|m| m.frame_error),
        motion(|m| m.flip_median),
        motion(|m| m.flip_p95),
        motion(|m| m.flip_std),
        c.image.clone(),
    ]
}
