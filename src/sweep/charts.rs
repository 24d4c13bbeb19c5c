//! The sweep's SVG charts ([`smokeshadow_core::sweep::charts`]), written into its folder.

use std::path::Path;

use anyhow::Context;

pub use smokeshadow_core::sweep::charts::*;

use super::SweepResults;

/// Draws every chart of `results` into `dir/charts/` (created if missing), each written
/// atomically, and returns them in the order the report shows them.
pub fn write_charts(results: &SweepResults, dir: &Path) -> anyhow::Result<Vec<Chart>> {
    let charts_dir = dir.join(CHARTS_DIR);
    std::fs::create_dir_all(&charts_dir)
        .with_context(|| format!("cannot create folder {}", charts_dir.display()))?;
    let mut charts = Vec::new();
    for (chart, svg) in draw_charts(results)? {
        crate::output::write_atomic(&dir.join(&chart.file), svg.as_bytes())?;
        charts.push(chart);
    }
    Ok(charts)
}
