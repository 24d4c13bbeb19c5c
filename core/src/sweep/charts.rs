//! The sweep's SVG charts: accuracy and frame time against memory, accuracy against shadow
//! resolution, and the thesis' own measure (error against the technique's 24-channel image,
//! chapter 4.2.2.2) against the channel budget.
//!
//! Drawn with `plotters`' SVG backend alone: no system fonts (text is `<text>` laid out by
//! plotters' built-in estimate, the browser draws it), no bitmaps, so the charts are small,
//! deterministic for the same results and readable in any browser beside `index.html`.
//!
//! Every chart is a `Plot` (series of points plus an optional reference line) built by one
//! small function from the [`SweepResults`], and drawn by `render_svg`, which drops points that
//! cannot be drawn (missing or NaN values, 0 on a log axis) and pads degenerate axis ranges. To
//! add a chart, write one more such function and list it in [`draw_charts`]; `index.html`
//! shows whatever [`Chart`]s come back.

use std::ops::Range;

use anyhow::Context;
use plotters::coord::ranged1d::{
    AsRangedCoord, DefaultFormatting, KeyPointHint, Ranged, ValueFormatter,
};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use super::{CellResult, SweepResults};
use crate::shadow::SplatMode;

/// Folder of the charts inside the sweep folder.
pub const CHARTS_DIR: &str = "charts";

const WIDTH_PX: u32 = 900;
const HEIGHT_PX: u32 = 560;
/// Tick labels per axis. Kept small so a log axis labels only its powers of the base.
const X_LABELS: usize = 6;
const Y_LABELS: usize = 8;
const FONT: &str = "sans-serif";

/// A pixel offset in the SVG (plotters' backend coordinate; x right, y down).
type BackendCoord = (i32, i32);

/// The Tableau 10 palette (matplotlib's default): ten well-separated colours. Markers tell
/// series apart where colours repeat or cannot be told apart.
const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// The `i`-th series colour as RGB (the gallery colours its techniques as the charts do: by
/// order of first appearance).
pub fn palette_rgb(i: usize) -> (u8, u8, u8) {
    let RGBColor(r, g, b) = PALETTE[i % PALETTE.len()];
    (r, g, b)
}

/// One chart written into the sweep folder, as `index.html` shows it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Chart {
    /// Path relative to the sweep folder, e.g. `charts/error_vs_bytes.svg`.
    pub file: String,
    /// Short title (also drawn in the SVG).
    pub title: String,
    /// One or two sentences: what is plotted and how to read it.
    pub caption: String,
}

/// Draws every chart of `results`, in the order the report shows them: each [`Chart`] with
/// its SVG text (the app writes it to the chart's `file`, the web page shows it inline). Empty
/// or partial results still give every chart (one with no points says "no data").
pub fn draw_charts(results: &SweepResults) -> anyhow::Result<Vec<(Chart, String)>> {
    // The charts compare shadow techniques: cells whose particles were drawn below full
    // resolution (`--particle-res`) are a cost option of the frame, in the tables only.
    let full_res;
    let results = match results
        .cells
        .iter()
        .any(|c| c.particle_res != crate::render::ParticleRes::Full)
    {
        false => results,
        true => {
            let mut r = results.clone();
            r.cells
                .retain(|c| c.particle_res == crate::render::ParticleRes::Full);
            full_res = r;
            &full_res
        }
    };
    let mut plots = vec![
        error_vs_bytes(results),
        transmittance_error_vs_bytes(results),
        time_vs_bytes(results),
        error_vs_frame_time(results),
        error_vs_resolution(results),
        error_vs_own_baseline(results),
    ];
    if let Some(motion) = &results.metadata.motion {
        plots.push(temporal_error_vs_bytes(results, motion));
        plots.push(flip_over_time(results, motion));
        plots.push(temporal_error_over_time(results, motion));
    }
    let mut charts = Vec::with_capacity(plots.len());
    for plot in plots {
        let svg =
            render_svg(&plot).with_context(|| format!("cannot draw chart {}", plot.file_name))?;
        charts.push((
            Chart {
                file: format!("{CHARTS_DIR}/{}", plot.file_name),
                title: plot.title,
                caption: plot.caption,
            },
            svg,
        ));
    }
    Ok(charts)
}

/// How the x axis maps values.
#[derive(Clone, Copy, Debug, PartialEq)]
enum XScale {
    /// Bytes on a base-2 log axis, ticks labelled in binary units.
    LogBytes,
    /// Shadow-map resolution (texels per side) on a base-2 log axis.
    LogResolution,
    /// A frame-time ratio (to `none`'s) on a base-2 log axis.
    LogRatio,
    /// Channel budget on a linear axis.
    Channels,
    /// Scene time, seconds, on a linear axis.
    Seconds,
    /// A count (particles) on a base-10 log axis against a log y axis: cost curves whose
    /// slopes read as powers ([`log_log_svg`], the bench's charts).
    LogLog,
}

/// Point shapes, cycled so that series of one colour still differ.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Marker {
    Circle,
    Triangle,
    Square,
    Diamond,
    Plus,
    Ring,
    HollowSquare,
}

const MARKERS: [Marker; 7] = [
    Marker::Circle,
    Marker::Triangle,
    Marker::Square,
    Marker::Diamond,
    Marker::Plus,
    Marker::Ring,
    Marker::HollowSquare,
];

/// One series: a legend label and its points (x, y), drawn joined in order of x.
struct Series {
    label: String,
    color: RGBColor,
    marker: Marker,
    points: Vec<(f64, f64)>,
}

/// A horizontal dashed reference line across the whole chart.
struct Reference {
    y: f64,
    label: String,
}

/// Everything needed to draw one chart.
struct Plot {
    file_name: &'static str,
    title: String,
    caption: String,
    x_scale: XScale,
    x_label: String,
    y_label: String,
    series: Vec<Series>,
    reference: Option<Reference>,
    legend_at: SeriesLabelPosition,
}

// ---------------------------------------------------------------------------------------------
// The charts.

/// FLIP mean against `exact` over bytes: accuracy per memory, the Pareto picture.
fn error_vs_bytes(results: &SweepResults) -> Plot {
    let (series, zero_bytes) = series_over_bytes(results, |c| c.vs_exact.map(|e| e.flip_mean));
    Plot {
        file_name: "error_vs_bytes.svg",
        title: "Accuracy per memory: FLIP vs exact".into(),
        caption: format!(
            "FLIP mean of each image against the exact reference (lower is better) over the bytes \
             the technique allocated (log scale). The lower-left envelope is the Pareto front: \
             nothing to its left is more accurate.{}",
            zero_bytes_note(zero_bytes)
        ),
        x_scale: XScale::LogBytes,
        x_label: "bytes allocated (log scale)".into(),
        y_label: "FLIP mean vs exact (0 = identical)".into(),
        series,
        reference: None,
        legend_at: SeriesLabelPosition::UpperRight,
    }
}

/// RMS transmittance error against `exact` over bytes.
fn transmittance_error_vs_bytes(results: &SweepResults) -> Plot {
    let (series, zero_bytes) = series_over_bytes(results, |c| c.rms_transmittance_error);
    Plot {
        file_name: "transmittance_error_vs_bytes.svg",
        title: "Transmittance error per memory".into(),
        caption: format!(
            "RMS difference of the transmittance T from exact over the points the view shades \
             (particle lighting points and lit opaque points), over the bytes allocated (log \
             scale). Unlike FLIP it measures the shadow itself, not its effect on the image.{}",
            zero_bytes_note(zero_bytes)
        ),
        x_scale: XScale::LogBytes,
        x_label: "bytes allocated (log scale)".into(),
        y_label: "RMS transmittance error vs exact".into(),
        series,
        reference: None,
        legend_at: SeriesLabelPosition::UpperRight,
    }
}

/// Median frame time over bytes, with the `none` cell's frame time as a reference line.
fn time_vs_bytes(results: &SweepResults) -> Plot {
    let (series, zero_bytes) = series_over_bytes(results, |c| Some(c.frame_ms.median));
    let reference = results
        .cells
        .iter()
        .find(|c| c.technique == crate::shadow::frame_baseline().name)
        .map(|c| c.frame_ms.median)
        .filter(|ms| ms.is_finite())
        .map(|ms| Reference {
            y: ms,
            label: format!("no shadows ({ms:.2} ms)"),
        });
    let timing = if results.metadata.timestamp_queries {
        "GPU passes from timestamp queries plus the CPU sort"
    } else {
        "this adapter has no timestamp queries, so only the CPU sort is counted"
    };
    Plot {
        file_name: "time_vs_bytes.svg",
        title: "Frame time per memory".into(),
        caption: format!(
            "Median frame time over {} frames ({timing}) over the bytes allocated (log scale). \
             The dashed line is the frame without self-shadowing (technique none).{}",
            results.metadata.frames,
            zero_bytes_note(zero_bytes)
        ),
        x_scale: XScale::LogBytes,
        x_label: "bytes allocated (log scale)".into(),
        y_label: "median frame time (ms)".into(),
        series,
        reference,
        legend_at: SeriesLabelPosition::UpperLeft,
    }
}

/// FLIP mean against `exact` over the shadow-map resolution, a series per technique x budget.
fn error_vs_resolution(results: &SweepResults) -> Plot {
    let cells = shadowed(results);
    let several_splats = distinct(&cells, |c| c.splat).len() > 1;
    let techniques = techniques(&cells);
    let mut series = Vec::new();
    for (t, technique) in techniques.iter().enumerate() {
        let of_technique: Vec<&CellResult> = cells
            .iter()
            .copied()
            .filter(|c| &c.technique == technique)
            .collect();
        let mut keys: Vec<(u32, SplatMode)> = Vec::new();
        for c in &of_technique {
            if !keys.contains(&(c.channels, c.splat)) {
                keys.push((c.channels, c.splat));
            }
        }
        // Largest budget first, as the thesis orders them.
        keys.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.name().cmp(b.1.name())));
        for (k, &(channels, splat)) in keys.iter().enumerate() {
            let mut label = format!("{technique} {channels} ch");
            if several_splats {
                label.push_str(&format!(" {}", splat.name()));
            }
            let points = of_technique
                .iter()
                .filter(|c| c.channels == channels && c.splat == splat)
                .filter_map(|c| Some((f64::from(c.shadow_res), c.vs_exact?.flip_mean)))
                .collect();
            series.push(Series {
                label,
                color: PALETTE[t % PALETTE.len()],
                marker: MARKERS[(t + k) % MARKERS.len()],
                points,
            });
        }
    }
    let resolutions = distinct(&cells, |c| c.shadow_res);
    let single = match resolutions.as_slice() {
        [res] => format!(" Only one resolution ({res}²) was swept, so each series is one point."),
        _ => String::new(),
    };
    Plot {
        file_name: "error_vs_resolution.svg",
        title: "Accuracy per shadow-map resolution".into(),
        caption: format!(
            "FLIP mean against exact over the shadow-map resolution (texels per side, log \
             scale), one series per technique and channel budget.{single}"
        ),
        x_scale: XScale::LogResolution,
        x_label: "shadow-map resolution (texels per side, log scale)".into(),
        y_label: "FLIP mean vs exact (0 = identical)".into(),
        series,
        reference: None,
        legend_at: SeriesLabelPosition::UpperRight,
    }
}

/// The thesis' measure: FLIP against the technique's own 24-channel image over the budget.
fn error_vs_own_baseline(results: &SweepResults) -> Plot {
    let series = series_per_variant(results, |c| {
        Some((f64::from(c.channels), c.vs_own_24?.flip_mean))
    });
    Plot {
        file_name: "error_vs_own_baseline.svg",
        title: "Error against the technique's own 24-channel image".into(),
        caption: "The thesis' measure (chapter 4.2.2.2): FLIP mean of each image against the same \
                  technique at 24 channels (same resolution and splat) over the channel budget. \
                  It shows how fast a technique degrades as its budget shrinks, not how close it \
                  is to the truth: compare with FLIP against exact."
            .into(),
        x_scale: XScale::Channels,
        x_label: "channel budget B (render-target components)".into(),
        y_label: "FLIP mean vs own 24-channel image".into(),
        series,
        reference: None,
        legend_at: SeriesLabelPosition::UpperRight,
    }
}

/// The temporal error over the animated span over bytes: stability per memory.
fn temporal_error_vs_bytes(results: &SweepResults, motion: &super::MotionReference) -> Plot {
    let (series, zero_bytes) =
        series_over_bytes(results, |c| c.motion.as_ref().map(|m| m.temporal_error));
    Plot {
        file_name: "temporal_error_vs_bytes.svg",
        title: "Stability per memory: temporal error vs exact".into(),
        caption: format!(
            "Mean over the {} of the per-pixel |ΔI − ΔI_exact| between consecutive frames, \
             linear luminance (lower is steadier; 0 changes exactly as exact does), over the \
             bytes allocated (log scale). The dashed line is exact's own mean change a frame: a \
             technique near it changes about as wrongly as the image changes at all.{}",
            motion.change.span.describe(),
            zero_bytes_note(zero_bytes)
        ),
        x_scale: XScale::LogBytes,
        x_label: "bytes allocated (log scale)".into(),
        y_label: "temporal error (linear luminance)".into(),
        series,
        reference: Some(Reference {
            y: motion.change.luminance,
            label: "exact's change a frame".into(),
        }),
        legend_at: SeriesLabelPosition::UpperRight,
    }
}

/// The cells the charts over time follow: each technique's at the smallest byte budget (where
/// flicker shows most), else at the smallest channel budget.
fn over_time_cells(results: &SweepResults) -> (String, Vec<&CellResult>) {
    if let Some(&b) = super::answer::byte_budgets(results).iter().min() {
        return (
            format!("at {b} bytes a texel"),
            super::answer::at_byte_budget(results, b),
        );
    }
    let cells = shadowed(results);
    let mut out: Vec<&CellResult> = Vec::new();
    for t in techniques(&cells) {
        if let Some(c) = cells
            .iter()
            .copied()
            .filter(|c| c.technique == t && c.motion.is_some())
            .min_by_key(|c| c.channels)
        {
            out.push(c);
        }
    }
    ("at each technique's smallest channel budget".into(), out)
}

/// One series a cell over the span's times, `values` per frame (or pair: each at its later
/// frame).
fn series_over_time(
    cells: &[&CellResult],
    times: &[f32],
    values: impl Fn(&crate::motion::Motion) -> &[f64],
) -> Vec<Series> {
    cells
        .iter()
        .enumerate()
        .filter_map(|(i, c)| {
            let m = c.motion.as_ref()?;
            let v = values(m);
            let skip = times.len().saturating_sub(v.len());
            Some(Series {
                label: format!("{} {}", c.technique, c.channels),
                color: PALETTE[i % PALETTE.len()],
                marker: MARKERS[i % MARKERS.len()],
                points: times[skip..]
                    .iter()
                    .zip(v)
                    .map(|(&t, &y)| (f64::from(t), y))
                    .collect(),
            })
        })
        .collect()
}

/// FLIP against `exact` of every frame of the span.
fn flip_over_time(results: &SweepResults, motion: &super::MotionReference) -> Plot {
    let (which, cells) = over_time_cells(results);
    let times = motion.change.span.times();
    Plot {
        file_name: "flip_over_time.svg",
        title: format!("FLIP vs exact over time, {which}"),
        caption: format!(
            "FLIP mean of each frame against exact's at the same time over the {}: a flat line \
             errs the same way in every frame, a jagged one is wrong differently from frame to \
             frame.",
            motion.change.span.describe()
        ),
        x_scale: XScale::Seconds,
        x_label: "scene time".into(),
        y_label: "FLIP mean vs exact".into(),
        series: series_over_time(&cells, &times, |m| &m.flip_per_frame),
        reference: None,
        legend_at: SeriesLabelPosition::UpperRight,
    }
}

/// The temporal error of every frame pair of the span.
fn temporal_error_over_time(results: &SweepResults, motion: &super::MotionReference) -> Plot {
    let (which, cells) = over_time_cells(results);
    let times = motion.change.span.times();
    Plot {
        file_name: "temporal_error_over_time.svg",
        title: format!("Temporal error over time, {which}"),
        caption: format!(
            "Mean per-pixel |ΔI − ΔI_exact| of each pair of consecutive frames, at the later \
             frame's time, over the {}; the dashed line is exact's own mean change a frame.",
            motion.change.span.describe()
        ),
        x_scale: XScale::Seconds,
        x_label: "scene time".into(),
        y_label: "temporal error (linear luminance)".into(),
        series: series_over_time(&cells, &times, |m| &m.temporal_per_pair),
        reference: Some(Reference {
            y: motion.change.luminance,
            label: "exact's change a frame".into(),
        }),
        legend_at: SeriesLabelPosition::UpperRight,
    }
}

// ---------------------------------------------------------------------------------------------
// Grouping cells into series.

/// The cells with a shadow technique (not the `none` frame-time baseline), in run order.
fn shadowed(results: &SweepResults) -> Vec<&CellResult> {
    results
        .cells
        .iter()
        .filter(|c| c.technique != crate::shadow::frame_baseline().name)
        .collect()
}

/// Technique names in order of first appearance.
fn techniques(cells: &[&CellResult]) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for c in cells {
        if !names.contains(&c.technique) {
            names.push(c.technique.clone());
        }
    }
    names
}

/// The distinct values of `key` over `cells`, in order of first appearance.
fn distinct<K: PartialEq>(cells: &[&CellResult], key: impl Fn(&CellResult) -> K) -> Vec<K> {
    let mut values = Vec::new();
    for c in cells {
        let k = key(c);
        if !values.contains(&k) {
            values.push(k);
        }
    }
    values
}

/// One series per technique x resolution x splat mode (the label names resolution and splat
/// only when the sweep has several), points from `point` (`None` skips the cell). Colours
/// follow the technique, so a technique looks the same in every chart.
fn series_per_variant(
    results: &SweepResults,
    point: impl Fn(&CellResult) -> Option<(f64, f64)>,
) -> Vec<Series> {
    let cells = shadowed(results);
    let mut resolutions = distinct(&cells, |c| c.shadow_res);
    resolutions.sort_unstable();
    let splats = distinct(&cells, |c| c.splat);
    let mut series = Vec::new();
    for (t, technique) in techniques(&cells).iter().enumerate() {
        let mut v = 0;
        for &res in &resolutions {
            for &splat in &splats {
                let members: Vec<&CellResult> = cells
                    .iter()
                    .copied()
                    .filter(|c| {
                        &c.technique == technique && c.shadow_res == res && c.splat == splat
                    })
                    .collect();
                if members.is_empty() {
                    continue;
                }
                let mut label = technique.clone();
                if resolutions.len() > 1 {
                    label.push_str(&format!(" {res}²"));
                }
                if splats.len() > 1 {
                    label.push_str(&format!(" {}", splat.name()));
                }
                series.push(Series {
                    label,
                    color: PALETTE[t % PALETTE.len()],
                    marker: MARKERS[(t + v) % MARKERS.len()],
                    points: members.into_iter().filter_map(&point).collect(),
                });
                v += 1;
            }
        }
    }
    series
}

/// FLIP mean against `exact` over the frame time relative to `none`'s: accuracy per time, the
/// time Pareto picture, on the adapter the sweep ran on.
fn error_vs_frame_time(results: &SweepResults) -> Plot {
    let series = series_per_variant(results, |c| {
        Some((c.overhead_ratio?, c.vs_exact.map(|e| e.flip_mean)?))
    });
    Plot {
        file_name: "error_vs_frame_time.svg",
        title: format!(
            "Accuracy per frame time: FLIP vs exact ({})",
            results.metadata.adapter
        ),
        caption: format!(
            "FLIP mean of each image against the exact reference (lower is better) over its median \
             frame time relative to the frame without self-shadowing (none's, 1x; log scale), \
             timed on {} ({}). The lower-left envelope is the Pareto front of time: nothing to \
             its left is more accurate. Times are this adapter's: a software rasterizer's \
             ratios are not a desktop GPU's (docs/gpu holds GPU runs).",
            results.metadata.adapter, results.metadata.backend
        ),
        x_scale: XScale::LogRatio,
        x_label: "frame time / none's (log scale)".into(),
        y_label: "FLIP mean vs exact (0 = identical)".into(),
        series,
        reference: None,
        legend_at: SeriesLabelPosition::UpperRight,
    }
}

/// [`series_per_variant`] over bytes, with `value` as y. Cells with 0 bytes cannot sit on a log
/// axis: they are left out and counted.
fn series_over_bytes(
    results: &SweepResults,
    value: impl Fn(&CellResult) -> Option<f64>,
) -> (Vec<Series>, usize) {
    let zero_bytes = shadowed(results)
        .iter()
        .filter(|c| c.resident_bytes == 0 && value(c).is_some_and(f64::is_finite))
        .count();
    let series = series_per_variant(results, |c| {
        // u64 -> f64 is exact up to 2^53 bytes, far beyond any GPU.
        if c.resident_bytes == 0 {
            return None;
        }
        Some((c.resident_bytes as f64, value(c)?))
    });
    (series, zero_bytes)
}

fn zero_bytes_note(count: usize) -> String {
    match count {
        0 => String::new(),
        1 => " One cell allocated 0 bytes and is not shown on the log axis.".into(),
        n => format!(" {n} cells allocated 0 bytes and are not shown on the log axis."),
    }
}

// ---------------------------------------------------------------------------------------------
// Drawing.

/// One line of a [`log_log_svg`] chart: a legend label and its (x, y) points.
pub struct LogLogSeries {
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

impl LogLogSeries {
    /// Adds `point` to the series labelled `label` in `series`, a new one at the end if none is.
    pub fn push_point(series: &mut Vec<LogLogSeries>, label: String, point: (f64, f64)) {
        match series.iter_mut().find(|s| s.label == label) {
            Some(s) => s.points.push(point),
            None => series.push(LogLogSeries {
                label,
                points: vec![point],
            }),
        }
    }
}

/// A line chart on log-log axes as an SVG document, drawn like the sweep's charts: series `i`
/// gets colour `i` of the palette and marker `i` of the markers (so colours that repeat differ
/// in shape). Points that are not positive and finite are left out.
pub fn log_log_svg(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[LogLogSeries],
) -> anyhow::Result<String> {
    let plot = Plot {
        file_name: "",
        title: title.to_owned(),
        caption: String::new(),
        x_scale: XScale::LogLog,
        x_label: x_label.to_owned(),
        y_label: y_label.to_owned(),
        series: series
            .iter()
            .enumerate()
            .map(|(i, s)| Series {
                label: s.label.clone(),
                color: PALETTE[i % PALETTE.len()],
                marker: MARKERS[i % MARKERS.len()],
                points: s.points.clone(),
            })
            .collect(),
        reference: None,
        legend_at: SeriesLabelPosition::UpperLeft,
    };
    render_svg(&plot)
}

/// Draws `plot` as an SVG document.
fn render_svg(plot: &Plot) -> anyhow::Result<String> {
    let series: Vec<Series> = plot
        .series
        .iter()
        .map(|s| {
            let mut points: Vec<(f64, f64)> = s
                .points
                .iter()
                .copied()
                .filter(|&(x, y)| {
                    x.is_finite()
                        && y.is_finite()
                        && (matches!(plot.x_scale, XScale::Channels | XScale::Seconds) || x > 0.0)
                        && (plot.x_scale != XScale::LogLog || y > 0.0)
                })
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
            Series {
                label: s.label.clone(),
                color: s.color,
                marker: s.marker,
                points,
            }
        })
        .filter(|s| !s.points.is_empty())
        .collect();
    let xs: Vec<f64> = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.0))
        .collect();
    let mut ys: Vec<f64> = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1))
        .collect();
    ys.extend(plot.reference.as_ref().map(|r| r.y));
    if plot.x_scale == XScale::LogLog {
        return draw(
            plot,
            &series,
            log_range(&xs, 1.5, 1000.0..1e6).log_scale(),
            log_range(&ys, 1.5, 0.01..1000.0).log_scale(),
            &|x| number_label(*x),
        );
    }
    let y_range = linear_range(&ys, true);
    match plot.x_scale {
        XScale::LogBytes => draw(
            plot,
            &series,
            log_range(&xs, 1.5, 1024.0..(64.0 * 1024.0 * 1024.0))
                .log_scale()
                .base(2.0),
            y_range,
            &|x| bytes_label(*x),
        ),
        XScale::LogResolution => draw(
            plot,
            &series,
            log_range(&xs, std::f64::consts::SQRT_2, 128.0..2048.0)
                .log_scale()
                .base(2.0),
            y_range,
            &|x| number_label(*x),
        ),
        XScale::LogRatio => draw(
            plot,
            &series,
            log_range(&xs, std::f64::consts::SQRT_2, 1.0..4.0)
                .log_scale()
                .base(2.0),
            y_range,
            &|x| format!("{}x", number_label(*x)),
        ),
        XScale::Channels => draw(
            plot,
            &series,
            TickedAxis::new(linear_range(&xs, false), &xs),
            y_range,
            &|x| number_label(*x),
        ),
        XScale::Seconds => draw(
            plot,
            &series,
            TickedAxis::new(linear_range(&xs, false), &[]),
            y_range,
            &|x| format!("{} s", number_label(*x)),
        ),
        XScale::LogLog => unreachable!("drawn above"),
    }
}

/// Draws `series` (finite points only, each non-empty) on the axes given by `x_spec` and
/// `y_spec`.
fn draw<X, Y>(
    plot: &Plot,
    series: &[Series],
    x_spec: X,
    y_spec: Y,
    x_label_text: &dyn Fn(&f64) -> String,
) -> anyhow::Result<String>
where
    X: AsRangedCoord<Value = f64>,
    X::CoordDescType: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: AsRangedCoord<Value = f64>,
    Y::CoordDescType: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH_PX, HEIGHT_PX)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(&plot.title, (FONT, 22))
            .margin(16)
            .x_label_area_size(48)
            .y_label_area_size(72)
            .build_cartesian_2d(x_spec, y_spec)?;
        chart
            .configure_mesh()
            .x_labels(X_LABELS)
            .y_labels(Y_LABELS)
            .x_desc(plot.x_label.as_str())
            .y_desc(plot.y_label.as_str())
            .x_label_formatter(x_label_text)
            .y_label_formatter(&|y| number_label(*y))
            .label_style((FONT, 13))
            .axis_desc_style((FONT, 15))
            .max_light_lines(4)
            .light_line_style(RGBColor(238, 238, 238))
            .bold_line_style(RGBColor(215, 215, 215))
            .draw()?;

        let (x_lo, x_hi) = {
            let r = chart.x_range();
            (r.start, r.end)
        };
        if let Some(reference) = &plot.reference {
            let style = BLACK.mix(0.7).stroke_width(2);
            chart
                .draw_series(DashedLineSeries::new(
                    [(x_lo, reference.y), (x_hi, reference.y)],
                    8,
                    5,
                    style,
                ))?
                .label(reference.label.as_str())
                .legend(move |(x, y)| {
                    EmptyElement::at((x, y))
                        + PathElement::new([(-10, 0), (-3, 0)], style)
                        + PathElement::new([(3, 0), (10, 0)], style)
                });
        }
        for s in series {
            let color = s.color;
            if s.points.len() > 1 {
                chart.draw_series(LineSeries::new(
                    s.points.iter().copied(),
                    color.mix(0.8).stroke_width(2),
                ))?;
            }
            let (outline, filled) = marker_shape(s.marker);
            let (fill, stroke) = marker_styles(filled, color);
            let path = closed(&outline);
            let legend_outline = outline.clone();
            let legend_path = path.clone();
            chart
                .draw_series(s.points.iter().map(|&p| {
                    EmptyElement::at(p)
                        + Polygon::new(outline.clone(), fill)
                        + PathElement::new(path.clone(), stroke)
                }))?
                .label(s.label.as_str())
                .legend(move |(x, y)| {
                    EmptyElement::at((x, y))
                        + PathElement::new([(-10, 0), (10, 0)], stroke)
                        + Polygon::new(legend_outline.clone(), fill)
                        + PathElement::new(legend_path.clone(), stroke)
                });
        }
        if series.is_empty() {
            let style = TextStyle::from((FONT, 24).into_font())
                .color(&RGBColor(120, 120, 120))
                .pos(plotters::style::text_anchor::Pos::new(
                    plotters::style::text_anchor::HPos::Center,
                    plotters::style::text_anchor::VPos::Center,
                ));
            root.draw(&Text::new(
                "no data",
                (WIDTH_PX as i32 / 2, HEIGHT_PX as i32 / 2),
                style,
            ))?;
        } else {
            chart
                .configure_series_labels()
                .position(plot.legend_at.clone())
                .background_style(WHITE.mix(0.85))
                .border_style(RGBColor(190, 190, 190))
                .label_font((FONT, 13))
                .draw()?;
        }
        root.present()?;
    }
    Ok(svg)
}

/// A linear axis labelled exactly at the values swept (the channel budgets 6, 8, 16, 24 rather
/// than plotters' round 5, 10, 15), unless there are too many to read.
struct TickedAxis {
    linear: RangedCoordf64,
    ticks: Vec<f64>,
}

impl TickedAxis {
    /// Above this many distinct values the axis falls back to round ticks.
    const MAX_TICKS: usize = 12;

    fn new(range: Range<f64>, values: &[f64]) -> Self {
        let mut ticks: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
        ticks.sort_by(f64::total_cmp);
        ticks.dedup();
        Self {
            linear: range.into(),
            ticks,
        }
    }
}

impl Ranged for TickedAxis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        self.linear.map(value, limit)
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if self.ticks.is_empty() || self.ticks.len() > Self::MAX_TICKS {
            self.linear.key_points(hint)
        } else if hint.weight().allow_light_points() {
            // No minor grid between budgets.
            Vec::new()
        } else {
            self.ticks.clone()
        }
    }

    fn range(&self) -> Range<f64> {
        self.linear.range()
    }
}

/// A marker's outline around its centre (pixels, y down) and whether it is filled with the
/// series colour (else white). Every shape is a polygon, so one element type draws them all.
fn marker_shape(marker: Marker) -> (Vec<BackendCoord>, bool) {
    let square = vec![(-4, -4), (4, -4), (4, 4), (-4, 4)];
    let circle = || -> Vec<BackendCoord> {
        (0..16)
            .map(|i| {
                let angle = f64::from(i) * std::f64::consts::TAU / 16.0;
                (
                    (5.0 * angle.cos()).round() as i32,
                    (5.0 * angle.sin()).round() as i32,
                )
            })
            .collect()
    };
    match marker {
        Marker::Circle => (circle(), true),
        Marker::Triangle => (vec![(0, -6), (6, 4), (-6, 4)], true),
        Marker::Square => (square, true),
        Marker::Diamond => (vec![(0, -6), (6, 0), (0, 6), (-6, 0)], true),
        Marker::Plus => (
            vec![
                (-2, -6),
                (2, -6),
                (2, -2),
                (6, -2),
                (6, 2),
                (2, 2),
                (2, 6),
                (-2, 6),
                (-2, 2),
                (-6, 2),
                (-6, -2),
                (-2, -2),
            ],
            true,
        ),
        Marker::Ring => (circle(), false),
        Marker::HollowSquare => (square, false),
    }
}

/// The fill and the outline of a marker shape.
fn marker_styles(filled: bool, color: RGBColor) -> (ShapeStyle, ShapeStyle) {
    let fill = if filled {
        color.filled()
    } else {
        WHITE.filled()
    };
    (fill, color.stroke_width(2))
}

/// The outline closed into a path (for the stroke).
fn closed(outline: &[BackendCoord]) -> Vec<BackendCoord> {
    let mut path = outline.to_vec();
    path.extend(outline.first().copied());
    path
}

/// A linear axis range covering `values` (the finite ones) with a little room; from 0 when
/// `from_zero` and every value is positive. Empty gives 0..1; equal values are padded.
fn linear_range(values: &[f64], from_zero: bool) -> Range<f64> {
    let Some((lo, hi)) = finite_bounds(values) else {
        return 0.0..1.0;
    };
    let lo = if from_zero { lo.min(0.0) } else { lo };
    let span = hi - lo;
    if span <= f64::EPSILON * hi.abs().max(1.0) {
        // All equal: pad by a tenth of the value, or by 1 around 0.
        let pad = if hi.abs() > 0.0 { hi.abs() * 0.1 } else { 1.0 };
        let lo = if from_zero && lo >= 0.0 {
            0.0
        } else {
            lo - pad
        };
        let hi = if from_zero && hi == 0.0 {
            1.0
        } else {
            hi + pad
        };
        return lo..hi;
    }
    let pad = span * 0.08;
    let lo = if from_zero && lo >= 0.0 { lo } else { lo - pad };
    lo..hi + pad
}

/// A range for a log axis covering the positive finite `values`, widened by `factor` on both
/// sides (so a single point is still a range); `fallback` when there are none.
fn log_range(values: &[f64], factor: f64, fallback: Range<f64>) -> Range<f64> {
    let positive: Vec<f64> = values.iter().copied().filter(|v| *v > 0.0).collect();
    match finite_bounds(&positive) {
        Some((lo, hi)) => lo / factor..hi * factor,
        None => fallback,
    }
}

fn finite_bounds(values: &[f64]) -> Option<(f64, f64)> {
    values
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
}

/// Bytes in binary units for a tick: `512 KiB`, `1 MiB`, `1.5 GiB`.
fn bytes_label(bytes: f64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut value = bytes;
    let mut unit = 0;
    while value.abs() >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    format!("{} {}", number_label(value), UNITS[unit])
}

/// A tick value with at most three significant decimals and no trailing zeros.
fn number_label(value: f64) -> String {
    if value == 0.0 || !value.is_finite() {
        return format!("{value}");
    }
    let magnitude = value.abs().log10().floor();
    let decimals = (2.0 - magnitude).clamp(0.0, 8.0) as usize;
    let text = format!("{value:.decimals$}");
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::{ImageError, SkippedCell, SweepMetadata, Timing};
    use std::path::Path;

    fn timing(ms: f64) -> Timing {
        Timing {
            median: ms,
            min: ms * 0.9,
            max: ms * 1.2,
        }
    }

    fn cell(technique: &str, channels: u32, res: u32, bytes: u64, flip: Option<f64>) -> CellResult {
        let error = flip.map(|f| ImageError {
            flip_mean: f,
            rmse: f / 2.0,
        });
        CellResult {
            technique: technique.into(),
            channels,
            byte_budgets: Vec::new(),
            memory_budgets: Vec::new(),
            channel_axis: true,
            channels_used: channels,
            shadow_res: res,
            splat: SplatMode::Point,
            particle_res: Default::default(),
            resident_bytes: bytes,
            transient_bytes: 0,
            smoke_texels: 0,
            gpu_shadow_ms: timing(1.0),
            gpu_render_ms: timing(4.0),
            cpu_sort_ms: timing(0.5),
            frame_ms: timing(5.5 + channels as f64 * 0.1),
            wall_ms: timing(7.0),
            particles_ms: Default::default(),
            upsample_ms: Default::default(),
            particle_fragments: None,
            frames_timed: 20,
            overhead_ratio: Some(1.2),
            shadow_ratio: None,
            vs_own_24: error,
            vs_exact: error,
            vs_full_res: None,
            rms_transmittance_error: flip.map(|f| f * 3.0),
            image: format!("images/{technique}_{channels}_{res}.png"),
            diff_own_24: None,
            flip_own_24: None,
            diff_exact: None,
            flip_exact: None,
            hdr_image: None,
            settings_key: "k".into(),
            measured_against: None,
            motion: None,
        }
    }

    fn metadata() -> SweepMetadata {
        SweepMetadata {
            framing: crate::scene::Framing::Fit,
            shapes: Default::default(),
            tool_version: "0.1.0".into(),
            scene: "thesis_plume".into(),
            description: String::new(),
            scene_sha256: "00".into(),
            seed: 1,
            particles: 2500,
            width_px: 1024,
            height_px: 768,
            adapter: "llvmpipe".into(),
            backend: "vulkan".into(),
            driver: "mesa".into(),
            timestamp_queries: true,
            clock_floor_ms: 0.0,
            frames: 30,
            warmup: 5,
            exact_tiles: 64,
            exact_bytes: 63 << 20,
            exact_check_points: 400,
            exact_check_worst: Some(2e-6),
            started: "2026-01-01T00:00:00Z".into(),
            wall_s: 12.5,
            shards: Vec::new(),
            motion: None,
        }
    }

    fn results(cells: Vec<CellResult>) -> SweepResults {
        SweepResults {
            metadata: metadata(),
            cells,
            skipped: vec![SkippedCell {
                technique: "fom".into(),
                channels: 2,
                bytes_per_texel: None,
                memory: None,
                reason: "below minimum".into(),
            }],
            exact_image: "images/exact.png".into(),
            exact_hdr_image: None,
            animation: None,
        }
    }

    /// The charts written as the CLI writes them, each under `dir/charts/`.
    fn write_charts(results: &SweepResults, dir: &Path) -> anyhow::Result<Vec<Chart>> {
        std::fs::create_dir_all(dir.join(CHARTS_DIR))?;
        let mut charts = Vec::new();
        for (chart, svg) in draw_charts(results)? {
            std::fs::write(dir.join(&chart.file), svg)?;
            charts.push(chart);
        }
        Ok(charts)
    }

    fn temp_dir(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("sweep-charts-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// Reads a chart back, checks it parses as XML with an `<svg>` root, and returns the text
    /// of every `<text>` element.
    fn chart_texts(path: &Path) -> Vec<String> {
        let svg = std::fs::read_to_string(path).unwrap();
        assert!(svg.contains("<svg"), "{} has no <svg>", path.display());
        let doc = roxmltree::Document::parse(&svg)
            .unwrap_or_else(|e| panic!("{} is not well-formed XML: {e}", path.display()));
        assert_eq!(doc.root_element().tag_name().name(), "svg");
        doc.descendants()
            .filter(|n| n.has_tag_name("text"))
            .filter_map(|n| n.text().map(|t| t.trim().to_string()))
            .collect()
    }

    #[test]
    fn writes_every_chart_with_the_techniques_in_the_legend() {
        let mut cells = vec![cell("none", 24, 512, 0, None)];
        for (technique, scale) in [("osm", 1.0), ("fom", 0.5)] {
            for channels in [24u32, 16, 8, 6] {
                cells.push(cell(
                    technique,
                    channels,
                    512,
                    u64::from(channels) * 512 * 512 * 2,
                    Some(scale * 0.2 / f64::from(channels)),
                ));
            }
        }
        let dir = temp_dir("full");
        let charts = write_charts(&results(cells), &dir).unwrap();
        assert_eq!(charts.len(), 6);
        for chart in &charts {
            assert!(chart.file.starts_with("charts/") && chart.file.ends_with(".svg"));
            let texts = chart_texts(&dir.join(&chart.file));
            let all = texts.join("\n");
            assert!(all.contains(&chart.title), "{}: no title", chart.file);
            for technique in ["osm", "fom"] {
                assert!(
                    texts.iter().any(|t| t.starts_with(technique)),
                    "{}: no legend entry for {technique} in {texts:?}",
                    chart.file
                );
            }
            assert!(!all.contains("no data"), "{}", chart.file);
            assert!(
                !texts.iter().any(|t| t.starts_with("none")),
                "{}",
                chart.file
            );
        }
        let time = chart_texts(&dir.join("charts/time_vs_bytes.svg")).join("\n");
        assert!(time.contains("no shadows"), "{time}");
        let bytes = chart_texts(&dir.join("charts/error_vs_bytes.svg")).join("\n");
        assert!(bytes.contains("MiB"), "byte ticks in binary units: {bytes}");
        let res = charts
            .iter()
            .find(|c| c.file.ends_with("error_vs_resolution.svg"))
            .unwrap();
        assert!(res.caption.contains("one resolution"), "{}", res.caption);
        // No temporary files left behind.
        let names: Vec<_> = std::fs::read_dir(dir.join("charts"))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert!(names.iter().all(|n| n.ends_with(".svg")), "{names:?}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn several_resolutions_and_splats_name_them_in_the_labels() {
        let mut cells = Vec::new();
        for res in [256u32, 512, 1024] {
            for splat in [SplatMode::Point, SplatMode::Segment] {
                for channels in [24u32, 8] {
                    let mut c = cell(
                        "dom",
                        channels,
                        res,
                        u64::from(res * res * channels * 2),
                        Some(0.01),
                    );
                    c.splat = splat;
                    cells.push(c);
                }
            }
        }
        let dir = temp_dir("variants");
        let charts = write_charts(&results(cells), &dir).unwrap();
        let bytes = chart_texts(&dir.join(&charts[0].file));
        assert!(bytes.iter().any(|t| t == "dom 256² segment"), "{bytes:?}");
        let res = chart_texts(&dir.join("charts/error_vs_resolution.svg"));
        assert!(res.iter().any(|t| t == "dom 24 ch point"), "{res:?}");
        assert!(
            res.iter().any(|t| t == "1024"),
            "log-2 ticks at the resolutions: {res:?}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn edge_cases_do_not_panic() {
        // Nothing at all.
        let dir = temp_dir("empty");
        let charts = write_charts(&results(Vec::new()), &dir).unwrap();
        for chart in &charts {
            let texts = chart_texts(&dir.join(&chart.file));
            assert!(
                texts.iter().any(|t| t == "no data"),
                "{}: {texts:?}",
                chart.file
            );
        }
        let _ = std::fs::remove_dir_all(&dir);
        // One point; zero bytes; NaN and missing errors; all-equal values.
        let mut nan = cell("osm", 16, 512, 4096, Some(f64::NAN));
        nan.frame_ms.median = f64::NAN;
        let cases = [
            vec![cell("osm", 24, 512, 1 << 20, Some(0.05))],
            vec![
                cell("osm", 24, 512, 0, Some(0.05)),
                cell("has", 8, 512, 0, Some(0.0)),
            ],
            vec![nan, cell("fom", 8, 512, 8192, None)],
            vec![
                cell("osm", 24, 512, 1 << 20, Some(0.0)),
                cell("osm", 8, 512, 1 << 20, Some(0.0)),
            ],
        ];
        for (i, cells) in cases.into_iter().enumerate() {
            let dir = temp_dir(&format!("edge{i}"));
            let charts = write_charts(&results(cells), &dir).unwrap();
            for chart in &charts {
                chart_texts(&dir.join(&chart.file));
                let svg = std::fs::read_to_string(dir.join(&chart.file)).unwrap();
                assert!(
                    !svg.contains("NaN") && !svg.contains("inf"),
                    "case {i}: {}",
                    chart.file
                );
            }
            let _ = std::fs::remove_dir_all(&dir);
        }
    }

    #[test]
    fn ranges_and_labels() {
        assert_eq!(linear_range(&[], true), 0.0..1.0);
        assert_eq!(linear_range(&[0.0, 0.0], true), 0.0..1.0);
        let r = linear_range(&[2.0, 2.0], false);
        assert!(r.start < 2.0 && r.end > 2.0);
        let r = linear_range(&[0.1, f64::NAN, 0.3], true);
        assert!(r.start == 0.0 && r.end > 0.3);
        let r = log_range(&[0.0, 4096.0], 2.0, 1.0..2.0);
        assert_eq!(r, 2048.0..8192.0);
        assert_eq!(log_range(&[0.0], 2.0, 1.0..2.0), 1.0..2.0);
        assert_eq!(bytes_label(1024.0 * 1024.0), "1 MiB");
        assert_eq!(bytes_label(512.0 * 1024.0), "512 KiB");
        assert_eq!(bytes_label(1.5 * 1024.0 * 1024.0), "1.5 MiB");
        assert_eq!(number_label(0.0125), "0.0125");
        assert_eq!(number_label(0.1), "0.1");
        assert_eq!(number_label(24.0), "24");
        assert_eq!(number_label(0.0), "0");
    }
}
