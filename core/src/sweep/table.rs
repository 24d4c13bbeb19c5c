//! The tables a sweep writes, as bytes: `results.csv`, a row per cell in [`CSV_COLUMNS`]
//! order, and `results.json`, everything. The CLI writes them to its folder, the web page offers
//! them for download: one format.

use anyhow::Context;

use super::{CellResult, SweepResults};

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

/// `results.csv`: the header and a row per cell.
pub fn results_csv(results: &SweepResults) -> anyhow::Result<Vec<u8>> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    writer.write_record(CSV_COLUMNS)?;
    for c in &results.cells {
        writer.write_record(csv_row(c))?;
    }
    writer.into_inner().context("cannot encode results.csv")
}

/// `results.json`: everything, pretty-printed.
pub fn results_json(results: &SweepResults) -> anyhow::Result<String> {
    serde_json::to_string_pretty(results).context("cannot encode results.json")
}

/// A cell's `results.csv` row, in [`CSV_COLUMNS`] order.
pub fn csv_row(c: &CellResult) -> Vec<String> {
    let opt = |v: Option<f64>, digits: usize| v.map_or(String::new(), |v| format!("{v:.digits$}"));
    // The temporal measures are a few 1e-4 of luminance: three significant digits.
    let motion = |f: fn(&crate::motion::Motion) -> f64| {
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
