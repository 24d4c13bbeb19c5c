//! A sweep's measured cells as records: each cell's JSON under `cells/`, a scene's results
//! assembled from them (with the overhead ratios), and the tables `results.csv` and
//! `results.json` written from those results.

use std::path::Path;

use super::shard::PlannedScene;
use super::{CellResult, Machine, SweepResults};
use smokeshadow_core::sweep::RunRecord;
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

/// A scene's results from its planned cells and the cells finished so far (in plan order)
/// ([`SweepResults::assemble`]); `fallback` and `exact` stand in for cells written before their
/// records held the machine and the `exact` figures. `exact`'s HDR frame is named where the
/// scene's folder has it.
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
    let run = RunRecord {
        tool_version,
        frames,
        warmup,
        fallback,
        exact,
        started,
        wall_s,
        shards,
        exact_image: EXACT_IMAGE.to_owned(),
        exact_hdr_image: scene_dir
            .join(EXACT_HDR_IMAGE)
            .is_file()
            .then(|| EXACT_HDR_IMAGE.to_owned()),
    };
    SweepResults::assemble(&planned.header, run, cells, planned.skipped.clone())
}

/// Writes `results.csv` (a row per cell) and `results.json` (everything) atomically.
pub fn write_results(results: &SweepResults, dir: &Path) -> anyhow::Result<()> {
    let csv = table::results_csv(results)?;
    crate::output::write_atomic(&dir.join("results.csv"), &csv)?;
    let json = table::results_json(results)?;
    crate::output::write_atomic(&dir.join("results.json"), json.as_bytes())
}
