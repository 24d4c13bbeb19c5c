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
//!   `index.html` ([`report`]) are rewritten from the finished cells.

pub mod charts;
pub mod report;
mod run;

use serde::{Deserialize, Serialize};

use crate::shadow::SplatMode;

pub use run::{CSV_COLUMNS, SweepOptions, run, write_results};

/// Median, minimum and maximum of a measurement over the timed frames, milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    pub median: f64,
    pub min: f64,
    pub max: f64,
}

impl Timing {
    /// Median, minimum and maximum of `samples` (all zero when there are none).
    pub fn of(samples: &[f64]) -> Self {
        run::timing(samples)
    }
}

/// Image error of a cell against a reference image.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImageError {
    /// FLIP mean (0 = identical).
    pub flip_mean: f64,
    /// RMSE of the sRGB values in [0, 1].
    pub rmse: f64,
}

/// One finished cell of the sweep.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellResult {
    /// Registry name; `none` is the frame-time baseline the overhead ratios divide by.
    pub technique: String,
    /// The channel budget asked for.
    pub channels: u32,
    /// The channels the technique uses under it (e.g. fom: 2n + 1).
    pub channels_used: u32,
    /// Shadow-map resolution (texels per side).
    pub shadow_res: u32,
    pub splat: SplatMode,
    /// Bytes the technique allocated (its memory ledger).
    pub bytes: u64,
    /// The part of `bytes` that is build scratch the lookup never reads (a deep capture's
    /// uncompressed lists); 0 for most techniques, and in cells written before it existed.
    #[serde(default)]
    pub transient_bytes: u64,
    /// GPU time of the technique's shadow build passes.
    pub gpu_shadow_ms: Timing,
    /// GPU time of everything else in the frame: opaque, particles (with their lighting), tone
    /// map.
    pub gpu_render_ms: Timing,
    /// CPU time of the particle sort(s).
    pub cpu_sort_ms: Timing,
    /// Per frame: all GPU passes plus the CPU sort (the thesis' "build + render, sorting
    /// included").
    pub frame_ms: Timing,
    /// Per frame: wall-clock time of the render call until its GPU work finished.
    pub wall_ms: Timing,
    /// Frames the medians are over (fewer than asked when the cell ran out of its seconds).
    #[serde(default)]
    pub frames_timed: u32,
    /// `frame_ms.median` / the `none` cell's `frame_ms.median` from the same run.
    pub overhead_ratio: Option<f64>,
    /// `gpu_shadow_ms.median` / the `none` cell's `frame_ms.median` from the same run: the
    /// build's share of an unshadowed frame.
    #[serde(default)]
    pub shadow_ratio: Option<f64>,
    /// Against the same technique at 24 channels (same resolution and splat); `None` for `none`.
    pub vs_own_24: Option<ImageError>,
    /// Against the `exact` reference image; `None` for `none`.
    pub vs_exact: Option<ImageError>,
    /// RMS difference of T from `exact` over the points the camera view shades (particle
    /// lighting points and lit opaque points); `None` for `none`.
    pub rms_transmittance_error: Option<f64>,
    /// Files, relative to the sweep folder.
    pub image: String,
    pub diff_own_24: Option<String>,
    pub flip_own_24: Option<String>,
    pub diff_exact: Option<String>,
    pub flip_exact: Option<String>,
    /// The linear HDR frame as OpenEXR (`--exr`).
    #[serde(default)]
    pub hdr_image: Option<String>,
    /// Identifies the settings this cell was measured with (scene, size, frames, warm-up, the
    /// technique's parameters, tool version): `--resume` reuses a cell only when it matches.
    pub settings_key: String,
}

/// A requested cell that was not run, and why (a budget below the technique's minimum).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SkippedCell {
    pub technique: String,
    pub channels: u32,
    pub reason: String,
}

/// What a sweep ran on and with.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SweepMetadata {
    pub tool_version: String,
    pub scene: String,
    /// SHA-256 of the scene's canonical TOML.
    pub scene_sha256: String,
    pub seed: u64,
    pub particles: u32,
    pub width_px: u32,
    pub height_px: u32,
    pub adapter: String,
    pub backend: String,
    pub driver: String,
    /// Whether the GPU times come from timestamp queries (if not, they are absent: 0).
    pub timestamp_queries: bool,
    pub frames: u32,
    pub warmup: u32,
    /// Light-space tiles per side of the `exact` reference every cell is compared with.
    pub exact_tiles: u32,
    /// Bytes `exact` allocated.
    pub exact_bytes: u64,
    /// RFC 3339 (UTC) start of this run, and its wall time in seconds.
    pub started: String,
    pub wall_s: f64,
}

/// Everything a sweep produced: written as `results.json` (and, a row per cell, `results.csv`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SweepResults {
    pub metadata: SweepMetadata,
    /// In run order: the `none` baseline first, then technique by technique.
    pub cells: Vec<CellResult>,
    pub skipped: Vec<SkippedCell>,
    /// Relative path of the `exact` reference image.
    pub exact_image: String,
    /// And of its HDR frame as OpenEXR (`--exr`).
    #[serde(default)]
    pub exact_hdr_image: Option<String>,
}
