//! A sweep's measured cells as records: each cell's JSON under `cells/`, a scene's results
//! assembled from them (with the overhead ratios), and the tables `results.csv` and
//! `results.json` written from those results.

use std::path::Path;

use super::shard::PlannedScene;
use super::{CellResult, Machine, MeasuredAgainst, SweepMetadata, SweepResults};
use smokeshadow_core::shadow;
use smokeshadow_core::sweep::table;

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
            c.set_ratios(baseline);
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

/// Writes `results.csv` (a row per cell) and `results.json` (everything) atomically.
pub fn write_results(results: &SweepResults, dir: &Path) -> anyhow::Result<()> {
    let csv = table::results_csv(results)?;
    crate::output::write_atomic(&dir.join("results.csv"), &csv)?;
    let json = table::results_json(results)?;
    crate::output::write_atomic(&dir.join("results.json"), json.as_bytes())
}
