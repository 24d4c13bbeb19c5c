//! Memory-budget sweeps: every technique x channel budget x shadow resolution x splat mode,
//! honestly timed (GPU timestamp queries, medians over many frames after a warm-up), with the
//! bytes each technique allocated and its error against its own 24-channel image (the thesis'
//! measure, chapter 4.2.2.2) and against `exact`. The thesis measured 3 techniques at 4 budgets
//! by hand (chapter 4.2.1); with no options this runs that experiment.
//!
//! - [`run`]: the engine: renders, times and compares each cell, persisting each finished cell
//!   atomically under `DIR/cells/` so a killed sweep loses at most the cell in flight and
//!   `--resume` skips cells already done with identical settings;
//! - `results.csv` / `results.json` ([`write_results`]), the SVG charts ([`charts`]) and
//!   `index.html` ([`report`]) are rewritten from the finished cells;
//! - several scenes (`--scenes`): each scene's sweep in its own folder, and a gallery report
//!   over them ([`gallery`]: the per-budget ranks, their median and worst across scenes, where
//!   each technique wins, and advice computed from those numbers);
//! - [`shard`]: `--shard K/N` runs the cells whose stable index is K mod N (a shard records in
//!   each cell what its ratios and errors were measured against, [`MeasuredAgainst`]), and
//!   `--merge` assembles the shards' cells into the tables and reports without a GPU.

mod animate;
mod cells;
pub mod charts;
pub mod gallery;
mod merge;
pub mod report;
mod run;
pub mod shard;

pub use cells::write_results;
pub use merge::merge;
pub use run::{SweepOptions, SweepOutcome, run};
pub use shard::ShardManifest;
pub use smokeshadow_core::sweep::plan::{CellTiming, DEFAULT_BYTES_PER_TEXEL, Grid, parse_memory};
pub use smokeshadow_core::sweep::table::CSV_COLUMNS;
pub use smokeshadow_core::sweep::{
    Animation, Budget, CellResult, ImageError, Machine, MeasuredAgainst, MotionReference,
    SHADED_STRIDE_PX, Shard, SkippedCell, SweepMetadata, SweepResults, Timing, answer,
    cone_framing, registry_index,
};
