//! The sweep's `index.html`: a self-contained page (no network, relative links only) that
//! answers "which technique gives the most accuracy for a given memory", then shows the charts,
//! every measured cell, the cells that were skipped, and every image with its differences.
//!
//! The page is built from [`SweepResults`] alone, so it can be rewritten from `results.json`
//! at any time; the page skeleton and formatting come from [`crate::report`], shared with the
//! `compare` page. A new section is one more function that appends to the body in
//! [`write_html`].

use std::fmt::Write;
use std::path::Path;

use super::answer::{
    TEMPORAL_SPREAD, TIME_BUDGETS, at_byte_budget, at_memory_budget, at_time_budget, byte_budgets,
    flip_exact, memory_budgets, most_stable, pareto_front, shape_tuned, temporal_error,
    time_pareto,
};
use super::charts::Chart;
use super::{CellResult, SweepResults, Timing};
use crate::report::{self, escape as e};
use smokeshadow_core::render::ParticleRes;

/// Every path the page references (`src` and `href` attributes, and the `compare` page's
/// `data-*` image attributes), for checking that a report's links resolve.
pub use crate::compare::referenced_paths;

/// Name of the page inside the sweep folder.
pub const INDEX_HTML: &str = "index.html";

/// A scene's whole output from its results: the tables (`results.csv`, `results.json`), the
/// charts and the page, as a run and a merge both write them.
pub fn write_scene(results: &SweepResults, dir: &Path) -> anyhow::Result<()> {
    super::cells::write_results(results, dir)?;
    let charts = super::charts::write_charts(results, dir)?;
    write_html(results, &charts, dir)
}

/// Writes `dir/index.html` atomically from `results` and the `charts` already written into
/// `dir` (see [`super::charts::write_charts`]). Every link is relative to `dir`.
pub fn write_html(results: &SweepResults, charts: &[Chart], dir: &Path) -> anyhow::Result<()> {
    let html = page(results, charts);
    report::write_studies(dir)?;
    crate::output::write_atomic(&dir.join(INDEX_HTML), html.as_bytes())
}

/// Page-specific style: Pareto rows and the image grid's small links.
const STYLE: &str = "<style>
tr.pareto td { background: #d9f2dc; }
tr.baseline td { color: #6b7280; }
.charts { display: grid; grid-template-columns: repeat(auto-fill, minmax(440px, 1fr)); gap: 16px; }
.charts figure { margin: 0; }
.charts img { width: 100%; height: auto; border: 1px solid #ddd; }
.charts figcaption { font-size: 13px; color: #374151; }
.links a { margin-right: 4px; }
.grid .empty { color: #9ca3af; font-size: 12px; }
.range { font-size: 11px; }
.wide { overflow-x: auto; }
</style>
";

fn page(results: &SweepResults, charts: &[Chart]) -> String {
    let m = &results.metadata;
    let title = format!("smokeshadow sweep: {}", m.scene);
    let variants = Variants::of(&results.cells);
    let pareto = pareto_front(&results.cells);

    let mut body = String::from(STYLE);
    let _ = writeln!(body, "<h1>{}</h1>", e(&title));
    metadata_line(&mut body, results);
    answer(&mut body, results, &variants, &pareto);
    motion_section(&mut body, results, &variants);
    charts_section(&mut body, charts);
    table(&mut body, results, &variants, &pareto);
    skipped(&mut body, results);
    image_grid(&mut body, results, &variants);
    body.push_str(
        "<h2>Data</h2>\n<p>Every cell as <a href=\"results.csv\">results.csv</a> (a row per \
         cell) and <a href=\"results.json\">results.json</a> (with the metadata above).</p>\n",
    );
    report::page(&title, &body, "")
}

/// What the sweep ran on and with.
fn metadata_line(body: &mut String, results: &SweepResults) {
    let m = &results.metadata;
    let wall = if m.wall_s.is_finite() && m.wall_s >= 0.0 {
        humantime::format_duration(std::time::Duration::from_secs(m.wall_s.round() as u64))
            .to_string()
    } else {
        "unknown".into()
    };
    let _ = writeln!(
        body,
        "<p class=\"muted\">Scene <code>{scene}</code> at {w}x{h}, {particles} particles, seed {seed}; \
         adapter {adapter} ({backend}, driver {driver}); timestamp queries: {ts}; \
         {frames} timed frames after {warmup} warm-up; reference <code>exact</code>: the closed form per point \
         through {exact_tiles}² light-space tiles ({exact_bytes}), {check}; smokeshadow {version}; ran {wall}, started {started}.</p>",
        scene = e(&m.scene),
        w = m.width_px,
        h = m.height_px,
        particles = m.particles,
        seed = m.seed,
        adapter = e(&m.adapter),
        backend = e(&m.backend),
        driver = e(&m.driver),
        ts = if m.timestamp_queries {
            "yes"
        } else {
            "no (GPU times are absent)"
        },
        frames = m.frames,
        warmup = m.warmup,
        exact_tiles = m.exact_tiles,
        exact_bytes = report::bytes(m.exact_bytes),
        check = match m.exact_check_worst {
            Some(worst) => format!(
                "checked against the f64 closed form at {} shaded points (worst |ΔT| {worst:.1e}, allowed {:.0e})",
                m.exact_check_points,
                smokeshadow_core::render::reference_check::TOLERANCE
            ),
            None => "not checked against the closed form (cells measured before the check)".into(),
        },
        version = e(&m.tool_version),
        started = e(&m.started),
    );
}

/// The answer: at each byte budget per texel, the techniques ranked (a best named only beyond
/// the run-to-run spread of FLIP); what a budget cannot buy a technique; then the Pareto front
/// and the most accurate cell over every budget.
fn answer(body: &mut String, results: &SweepResults, variants: &Variants, pareto: &[bool]) {
    body.push_str("<h2>Answer</h2>\n");
    let _ = writeln!(body, "<p>{}</p>", same_footing(results, true));
    equal_bytes(body, results, variants);
    equal_memory(body, results, variants);
    equal_time(body, results, variants);
    body.push_str(&report::studies_paragraph());
    let mut front: Vec<&CellResult> = results
        .cells
        .iter()
        .zip(pareto)
        .filter_map(|(c, &p)| p.then_some(c))
        .collect();
    if front.is_empty() {
        body.push_str(
            "<p>No cell has an error against <code>exact</code> yet, so there is no answer.</p>\n",
        );
        return;
    }
    front.sort_by(|a, b| {
        a.resident_bytes
            .cmp(&b.resident_bytes)
            .then(flip_exact(a).total_cmp(&flip_exact(b)))
    });
    let listed: Vec<String> = front
        .iter()
        .map(|c| {
            format!(
                "<b>{}</b>: {}, FLIP {:.4}",
                e(&variants.cell_label(c)),
                report::bytes(c.resident_bytes),
                flip_exact(c)
            )
        })
        .collect();
    let best = results
        .cells
        .iter()
        .filter(|c| flip_exact(c).is_finite())
        .min_by(|a, b| {
            flip_exact(a)
                .total_cmp(&flip_exact(b))
                .then(a.resident_bytes.cmp(&b.resident_bytes))
        });
    let _ = write!(
        body,
        "<p>Over every cell: most accuracy for the memory (the Pareto front: no other cell is both no larger and \
         closer to <code>exact</code> by FLIP mean): {}.",
        listed.join("; ")
    );
    if let Some(best) = best {
        let _ = write!(
            body,
            " Closest to <code>exact</code> overall: <b>{}</b> (FLIP {:.4}, {}).",
            e(&variants.cell_label(best)),
            flip_exact(best),
            report::bytes(best.resident_bytes)
        );
    }
    body.push_str("</p>\n");
}

/// With `--animate`: what the span is, `exact`'s own change over it, and every cell's
/// temporal measures beside its still error (docs/sweeps.md, "Smoke in motion", defines each).
fn motion_section(body: &mut String, results: &SweepResults, variants: &Variants) {
    let Some(motion) = &results.metadata.motion else {
        return;
    };
    let c = &motion.change;
    let _ = writeln!(
        body,
        "<h2>In motion</h2>\n<p>Every cell and <code>exact</code> rendered over the {span} \
         (the still figures above are at the scene's own time). <code>exact</code> changes by \
         {lum:.2e} a frame (mean |ΔL| per pixel, linear luminance) and its T at the shaded \
         points by {t:.2e}; it was checked against the f64 closed form at every frame (at least \
         {points} points each, worst |ΔT| {worst:.1e}). <i>Temporal error</i>: the mean \
         per-pixel |ΔI − ΔI<sub>exact</sub>| between consecutive frames (0: it changes exactly \
         as <code>exact</code> does, whatever its still error); <i>p99.9</i>: its 99.9th \
         percentile per frame pair (mean, worst pair); <i>pops</i>: pixels a frame whose change \
         is visible (more than 3/255 of sRGB-encoded luminance) where <code>exact</code>'s is \
         not; <i>T temporal</i>: the same as the temporal error on the shadow's T at the \
         particles' lighting points and the lit ground; <i>frame error</i>: the still measure \
         on the same frames, mean |I − I<sub>exact</sub>|; FLIP over the frames: median, 95th \
         percentile, standard deviation.</p>",
        span = c.span.describe(),
        lum = c.luminance,
        t = c.transmittance,
        points = motion.check_points,
        worst = motion.check_worst,
    );
    body.push_str(
        "<div class=\"wide\"><table><tr><th>cell</th><th>FLIP vs exact (still)</th>\
         <th>frame error</th><th>temporal error</th><th>p99.9 (mean / worst)</th>\
         <th>pops a frame</th><th>T temporal (p99.9)</th><th>FLIP over the frames \
         (median / p95 / std)</th></tr>\n",
    );
    let mut cells: Vec<&CellResult> = results
        .cells
        .iter()
        .filter(|c| c.motion.is_some())
        .collect();
    cells.sort_by(|a, b| temporal_error(a).total_cmp(&temporal_error(b)));
    for cell in cells {
        let m = cell.motion.as_ref().expect("filtered");
        let _ = writeln!(
            body,
            "<tr><td style=\"text-align: left\">{}</td><td>{}</td><td>{:.2e}</td><td>{:.2e}</td>\
             <td>{:.2e} / {:.2e}</td><td>{:.0}</td><td>{:.2e} ({:.2e})</td>\
             <td>{:.4} / {:.4} / {:.4}</td></tr>",
            e(&variants.cell_label(cell)),
            metric(cell.vs_exact.map(|x| x.flip_mean)),
            m.frame_error,
            m.temporal_error,
            m.temporal_p999,
            m.temporal_p999_worst,
            m.pops_per_frame,
            m.t_temporal_error,
            m.t_temporal_p999,
            m.flip_median,
            m.flip_p95,
            m.flip_std,
        );
    }
    body.push_str("</table></div>\n");
    if let Some(a) = &results.animation {
        let _ = writeln!(
            body,
            "<figure><a href=\"{x}\"><img src=\"{x}\" alt=\"the span side by side\" \
             style=\"max-width: 100%\"></a><figcaption>Left to right: {} over the {}, each at \
             half size (an animated PNG; chosen: at each budget from the smallest, the most \
             accurate still and the most stable in motion, and at the smallest the least \
             stable).</figcaption></figure>",
            a.tiles
                .iter()
                .map(|t| format!("<b>{}</b>", e(t)))
                .collect::<Vec<_>>()
                .join(", "),
            c.span.describe(),
            x = e(&a.file),
        );
    }
}

/// The framing and the filtering every technique of the sweep shares, in one sentence (names in
/// `<code>` for the report when `html`, in backticks otherwise).
pub fn same_footing(results: &SweepResults, html: bool) -> String {
    let exact = match html {
        true => "<code>exact</code>",
        false => "`exact`",
    };
    let m = &results.metadata;
    let framing = match m.framing {
        smokeshadow_core::scene::Framing::Fit => {
            "fitted to the smoke's light-space bounds within the cone"
        }
        smokeshadow_core::scene::Framing::Cone => {
            "over the whole spotlight cone (the thesis' framing)"
        }
        smokeshadow_core::scene::Framing::Stable => {
            "fitted to the smoke's light-space bounds within the cone and held steady in steps \
             (`framing = \"stable\"`: size and depth range in quarter octaves, aim in 1/256 of the \
             width, depth start in eighths of the range)"
        }
    };
    let coverage = results
        .cells
        .iter()
        .filter(|c| c.smoke_texels > 0)
        .map(|c| (c.shadow_res, c.smoke_texels))
        .min()
        .map_or(String::new(), |(res, texels)| {
            let all = u64::from(res).pow(2);
            format!(
                ": {texels} of a {res}² map's {all} texels hold smoke ({:.0}%)",
                100.0 * texels as f64 / all as f64
            )
        });
    format!(
        "The same footing for every technique: every light-space map (and {exact}'s tiles) is \
         framed {framing}{coverage}; the volume's grid spans the smoke's world box. \
         No technique prefilters: a map's texel holds the chord through its centre, a volume \
         voxel the extinction at its centre; lookups interpolate bilinearly (the volume \
         trilinearly)."
    )
}

/// The techniques ranked at each memory budget (total bytes), each at its tuned resolution
/// ([`at_memory_budget`]).
fn equal_memory(body: &mut String, results: &SweepResults, variants: &Variants) {
    let budgets = memory_budgets(results);
    if budgets.is_empty() {
        return;
    }
    let _ = writeln!(
        body,
        "<p>At equal total memory: at each swept shadow-map resolution, each technique at the \
         largest configuration whose resident bytes fit the budget; then each technique at the \
         resolution <code>smokeshadow tune</code> chose for it at this budget on the training \
         scenes (as its parameters were), or, marked <i>best here</i>, where tune chose none of \
         the swept resolutions, at its most accurate of them on this scene; ranked by FLIP mean \
         against <code>exact</code>.</p>\n<table><tr>\
         <th>memory</th><th>answer</th><th>ranked (FLIP vs exact, resolution)</th>{}</tr>",
        motion_header(results)
    );
    for &total in &budgets {
        let at = at_memory_budget(results, total);
        answer_row(
            body,
            &report::bytes(total),
            "no technique fits",
            &at,
            variants,
            |c| match shape_tuned(results, total, c) {
                true => format!("{}²", c.shadow_res),
                false => format!("{}², <i>best here</i>", c.shadow_res),
            },
        );
    }
    body.push_str("</table>\n");
}

/// The techniques ranked at each byte budget, and what a budget cannot buy each.
fn equal_bytes(body: &mut String, results: &SweepResults, variants: &Variants) {
    let budgets = byte_budgets(results);
    if budgets.is_empty() {
        return;
    }
    let spread = super::answer::FLIP_SPREAD;
    let _ = writeln!(
        body,
        "<p>At equal memory: each technique at the largest configuration whose resident bytes \
         (maps, build scratch, lists and uniforms: all it holds at its peak) fit the byte \
         budget per shadow-map texel, at its own precision (half floats are 2 bytes a \
         channel, single floats 4), ranked by FLIP mean against <code>exact</code>. A best is \
         named only when it leads by more than {spread} FLIP, the spread another CPU's rounding \
         gives; within it the leaders are tied.</p>\n<table><tr><th>budget</th><th>answer</th>\
         <th>ranked (FLIP vs exact, RMS T error)</th>{}</tr>",
        motion_header(results)
    );
    for &b in &budgets {
        let at = at_byte_budget(results, b);
        answer_row(
            body,
            &format!("{b} bytes"),
            "no technique fits",
            &at,
            variants,
            |c| {
                c.rms_transmittance_error
                    .map_or("—".into(), |t| format!("{t:.4}"))
            },
        );
    }
    body.push_str("</table>\n");
    let notes = budget_limits(results, budgets[0]);
    if !notes.is_empty() {
        let _ = writeln!(
            body,
            "<p>What a byte budget cannot buy: {}.</p>",
            notes.join("; ")
        );
    }
}

/// The techniques ranked within each frame-time budget ([`TIME_BUDGETS`]), with the adapter
/// the times are from.
fn equal_time(body: &mut String, results: &SweepResults, variants: &Variants) {
    if !results.cells.iter().any(|c| c.overhead_ratio.is_some()) {
        return;
    }
    let m = &results.metadata;
    let _ = writeln!(
        body,
        "<p>At equal time: each technique's most accurate configuration (of every cell, channel \
         and byte budgets alike) whose median frame takes at most the budget's multiple of the \
         frame without self-shadowing (<code>none</code>'s, timed in the same run), ranked by \
         FLIP mean against <code>exact</code>. Timed on <b>{}</b> ({}, {}): on another adapter \
         the times, and so this answer, differ (a software rasterizer's are not a GPU's).</p>\n\
         <table><tr><th>frame time</th><th>answer</th><th>ranked (FLIP vs exact, frame time / \
         none's, resident bytes)</th>{}</tr>",
        e(&m.adapter),
        e(&m.backend),
        e(&m.driver),
        motion_header(results)
    );
    for &ratio in TIME_BUDGETS {
        let at = at_time_budget(results, ratio);
        let budget = format!("≤ {ratio:.1}x none");
        answer_row(
            body,
            &budget,
            "no technique is that fast",
            &at,
            variants,
            |c| {
                format!(
                    "{:.2}x, {}",
                    c.overhead_ratio.unwrap_or(f64::NAN),
                    report::bytes(c.resident_bytes)
                )
            },
        );
    }
    body.push_str("</table>\n");
    let front = time_pareto(results);
    if !front.is_empty() {
        let listed: Vec<String> = front
            .iter()
            .map(|c| {
                format!(
                    "<b>{}</b>: {:.2}x, FLIP {:.4}",
                    e(&variants.cell_label(c)),
                    c.overhead_ratio.unwrap_or(f64::NAN),
                    flip_exact(c)
                )
            })
            .collect();
        let _ = writeln!(
            body,
            "<p>Most accuracy for the time on {} (the Pareto front of time: no other cell is both \
             no slower and closer to <code>exact</code>): {}.</p>",
            e(&m.adapter),
            listed.join("; ")
        );
    }
}

/// One row of an answer table: the budget, its verdict (the best, or the leaders tied within
/// the spread another CPU's rounding gives) and the cells `at` ranked, each with its FLIP vs
/// `exact` and `detail`; `none` where no cell answers it.
fn answer_row(
    body: &mut String,
    budget: &str,
    none: &str,
    at: &[&CellResult],
    variants: &Variants,
    detail: impl Fn(&CellResult) -> String,
) {
    let Some(first) = at.first() else {
        let _ = writeln!(body, "<tr><td>{budget}</td><td>{none}</td><td></td></tr>");
        return;
    };
    let spread = super::answer::FLIP_SPREAD;
    let label = |c: &CellResult| e(&variants.cell_label(c));
    let tied: Vec<&&CellResult> = at
        .iter()
        .filter(|c| flip_exact(c) - flip_exact(first) < spread)
        .collect();
    let verdict = match tied.len() {
        1 => format!("<b>{}</b>", label(first)),
        _ => format!(
            "tied: {}",
            tied.iter()
                .map(|c| format!("<b>{}</b>", label(c)))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let ranked = at
        .iter()
        .enumerate()
        .map(|(i, c)| {
            format!(
                "{}. {} ({:.4}, {})",
                i + 1,
                label(c),
                flip_exact(c),
                detail(c)
            )
        })
        .collect::<Vec<_>>()
        .join("; ");
    let _ = writeln!(
        body,
        "<tr><td>{budget}</td><td style=\"text-align: left\">{verdict}</td>\
         <td style=\"text-align: left; white-space: normal\">{ranked}</td>{}</tr>",
        motion_cell(at, variants)
    );
}

/// The answer tables' column of the most stable, when the sweep was animated.
fn motion_header(results: &SweepResults) -> &'static str {
    match results.metadata.motion.is_some() {
        true => "<th>most stable over the span (temporal error, pops a frame)</th>",
        false => "",
    }
}

/// An answer row's most stable cell (or those tied within [`TEMPORAL_SPREAD`]) and the cells
/// ranked by temporal error; nothing for a still sweep.
fn motion_cell(at: &[&CellResult], variants: &Variants) -> String {
    let stable = most_stable(at);
    let Some(first) = stable.first() else {
        return match at.iter().any(|c| c.motion.is_some()) {
            true => "<td></td>".into(),
            false => String::new(),
        };
    };
    let label = |c: &CellResult| e(&variants.cell_label(c));
    let tied: Vec<String> = stable
        .iter()
        .filter(|c| temporal_error(c) - temporal_error(first) < TEMPORAL_SPREAD)
        .map(|c| format!("<b>{}</b>", label(c)))
        .collect();
    let verdict = match tied.len() {
        1 => tied[0].clone(),
        _ => format!("tied: {}", tied.join(", ")),
    };
    let ranked = stable
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let m = c.motion.as_ref().expect("filtered");
            format!(
                "{}. {} ({:.2e}, {:.0})",
                i + 1,
                label(c),
                m.temporal_error,
                m.pops_per_frame
            )
        })
        .collect::<Vec<_>>()
        .join("; ");
    format!(
        "<td style=\"text-align: left; white-space: normal\">{verdict}<br><span class=\"muted\">{ranked}</span></td>"
    )
}

/// One sentence per technique of the byte cells whose memory stops short of the largest
/// budget, or barely depends on its channel budget (its registry formula at the default
/// parameters, the cells' resolution, particles and frame).
fn budget_limits(results: &SweepResults, largest: u32) -> Vec<String> {
    let m = &results.metadata;
    let pixels = u64::from(m.width_px) * u64::from(m.height_px);
    let mut notes = Vec::new();
    for entry in smokeshadow_core::shadow::contenders() {
        let Some(cell) = results
            .cells
            .iter()
            .find(|c| c.technique == entry.name && !c.byte_budgets.is_empty())
        else {
            continue;
        };
        let kept = |channels: u32| {
            let params = smokeshadow_core::shadow::TechniqueParams::new(channels, cell.shadow_res);
            smokeshadow_core::shadow::planned_bytes_per_texel(
                entry,
                &params,
                u64::from(m.particles),
                pixels,
            )
        };
        let (least, most) = (kept(entry.min_channels), kept(entry.max_channels));
        let name = format!("<code>{}</code>", entry.name);
        if most - least < 1.0 && !entry.uses_budget {
            notes.push(format!(
                "{name} holds {most:.1} bytes a texel at any budget, and a larger one buys it \
                 nothing"
            ));
        } else if most - least < 1.0 {
            notes.push(format!(
                "{name} holds {least:.1} to {most:.1} bytes a texel from {} to {}: its budget \
                 buys it passes (time), not memory, so it runs at its largest wherever it fits",
                (entry.budget_caption)(entry.min_channels),
                (entry.budget_caption)(entry.max_channels),
            ));
        } else if most < f64::from(largest) {
            notes.push(format!(
                "{name} holds at most {most:.1} bytes a texel ({}), whatever the budget",
                (entry.budget_caption)(entry.max_channels)
            ));
        }
    }
    notes
}

fn charts_section(body: &mut String, charts: &[Chart]) {
    if charts.is_empty() {
        return;
    }
    body.push_str("<h2>Charts</h2>\n<div class=\"charts\">\n");
    for chart in charts {
        let _ = writeln!(
            body,
            "<figure><a href=\"{file}\"><img src=\"{file}\" alt=\"{title}\"></a>\
             <figcaption><b>{title}.</b> {caption}</figcaption></figure>",
            file = e(&chart.file),
            title = e(&chart.title),
            caption = e(&chart.caption),
        );
    }
    body.push_str("</div>\n");
}

/// Every cell, one row each, Pareto rows highlighted.
fn table(body: &mut String, results: &SweepResults, variants: &Variants, pareto: &[bool]) {
    let gpu = results.metadata.timestamp_queries;
    body.push_str(
        "<h2>Results</h2>\n<p>Times in milliseconds: the median over the timed frames, under it the minimum and maximum. \
         Overhead: frame time / the frame time without shadows (<code>none</code>). \
         FLIP: mean, 0 = identical. RMS T error: transmittance against <code>exact</code> at \
         the points the view shades. Highlighted: the Pareto front. Channels differ in width \
         (a half float is 2 bytes, a 32-bit float 4): bytes per texel is what a technique keeps \
         for the lookup divided by the shadow map's texels, the measure to compare at equal memory \
         (for <code>has</code> it includes its eye buffer and particle copies, for \
         <code>volume</code> its grid).</p>\n\
         <div class=\"wide\"><table><tr><th>technique</th><th>channels<br>(used)</th><th>byte<br>budget</th><th>res</th><th>splat</th>\
         <th>bytes</th><th>bytes per<br>texel</th><th>shadow<br>ms</th><th>render<br>ms</th><th>sort<br>ms</th><th>frame<br>ms</th>\
         <th>overhead</th><th>FLIP<br>vs own 24</th><th>FLIP<br>vs exact</th><th>RMSE<br>vs exact</th>\
         <th>RMS T<br>error</th>",
    );
    if variants.mixed_res {
        body.push_str(
            "<th>particle<br>res</th><th>particles<br>ms</th><th>up/down-<br>sample ms</th>\
             <th>particle<br>fragments</th><th>FLIP vs<br>full res</th>",
        );
    }
    body.push_str("</tr>\n");
    for (c, &on_front) in results.cells.iter().zip(pareto) {
        let class = if on_front {
            " class=\"pareto\""
        } else if c.technique == smokeshadow_core::shadow::frame_baseline().name {
            " class=\"baseline\""
        } else {
            ""
        };
        let channels = if c.channels_used == c.channels {
            c.channels.to_string()
        } else {
            format!("{} ({})", c.channels, c.channels_used)
        };
        let gpu_time = |t: &Timing| {
            if gpu { timing_range(t) } else { "n/a".into() }
        };
        let _ = writeln!(
            body,
            "<tr{class}><td>{}</td><td>{channels}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>\
             <td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>\
             <td>{}</td><td>{}</td>{}</tr>",
            e(&c.technique),
            match c.byte_budgets.as_slice() {
                [] => "—".to_owned(),
                b => b.iter().map(u32::to_string).collect::<Vec<_>>().join(", "),
            },
            c.shadow_res,
            c.splat.label(),
            match c.transient_bytes {
                0 => report::bytes(c.resident_bytes),
                t => format!(
                    "{} ({} transient)",
                    report::bytes(c.resident_bytes),
                    report::bytes(t)
                ),
            },
            bytes_per_texel(c),
            gpu_time(&c.gpu_shadow_ms),
            if gpu {
                ms(c.gpu_render_ms.median)
            } else {
                "n/a".into()
            },
            ms(c.cpu_sort_ms.median),
            timing_range(&c.frame_ms),
            c.overhead_ratio
                .filter(|r| r.is_finite())
                .map_or("—".into(), |r| format!("{r:.2}x")),
            metric(c.vs_own_24.map(|x| x.flip_mean)),
            metric(c.vs_exact.map(|x| x.flip_mean)),
            metric(c.vs_exact.map(|x| x.rmse)),
            metric(c.rms_transmittance_error),
            match variants.mixed_res {
                false => String::new(),
                true => format!(
                    "<td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>",
                    c.particle_res,
                    gpu_time(&c.particles_ms),
                    gpu_time(&c.upsample_ms),
                    c.particle_fragments.map_or("—".into(), |n| n.to_string()),
                    metric(c.vs_full_res.map(|x| x.flip_mean)),
                ),
            },
        );
    }
    body.push_str("</table></div>\n");
    // The deep captures' times are an emulation's: say so once, beside their rows.
    let emulated: Vec<&str> = smokeshadow_core::shadow::REGISTRY
        .iter()
        .filter(|t| t.compresses_captured_lists)
        .filter(|t| results.cells.iter().any(|c| c.technique == t.name))
        .map(|t| t.name)
        .collect();
    if !emulated.is_empty() {
        let _ = writeln!(
            body,
            "<p class=\"muted\">{}: the shadow and frame times are those of a capture-and-resolve \
             emulation (every fragment appended to its texel's list, then a sort and a compression \
             per texel in compute) of what hardware with fragment-shader interlock does in one \
             pass, inserting as fragments arrive; WebGPU has no interlock, so they bound an \
             engine's cost from above.</p>",
            emulated
                .iter()
                .map(|n| format!("<code>{n}</code>"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    // The techniques whose T depends on the order the particles are drawn (`has` draws them
    // in its own slices, which follow the view by design).
    let order_dependent: Vec<String> = smokeshadow_core::shadow::REGISTRY
        .iter()
        .filter(|t| !t.order_independent && !t.owns_particle_pass)
        .filter(|t| results.cells.iter().any(|c| c.technique == t.name))
        .map(|t| format!("<code>{}</code>", t.name))
        .collect();
    if !order_dependent.is_empty() {
        let _ = writeln!(
            body,
            "<p class=\"muted\">{}: T depends on the order the particles are drawn (the eye's \
             back-to-front sort; see each technique's parameters and notes), so a view from \
             elsewhere gives other numbers for the same smoke.</p>",
            order_dependent.join(", ")
        );
    }
    if variants.several() {
        body.push_str(
            "<p class=\"muted\">FLIP vs own 24 compares with the same technique at 24 channels \
             at the same resolution and splat.</p>\n",
        );
    }
}

fn skipped(body: &mut String, results: &SweepResults) {
    if results.skipped.is_empty() {
        return;
    }
    body.push_str(
        "<h2>Skipped</h2>\n<table><tr><th>technique</th><th>budget</th><th>reason</th></tr>\n",
    );
    for s in &results.skipped {
        let _ = writeln!(
            body,
            "<tr><td>{}</td><td>{}</td><td style=\"text-align: left; white-space: normal\">{}</td></tr>",
            e(&s.technique),
            s.budget(),
            e(&s.reason)
        );
    }
    body.push_str("</table>\n");
}

/// Rows technique (x resolution x splat), columns channel budgets, largest first as in the
/// thesis; the references (`exact`, and `none`) above them.
fn image_grid(body: &mut String, results: &SweepResults, variants: &Variants) {
    body.push_str(
        "<h2>Images</h2>\n<p>Click an image for full size. ×4: |a − b| × 4 as in the thesis; \
         FLIP: the FLIP error map (magma).</p>\n",
    );
    // References.
    body.push_str("<div class=\"grid\" style=\"grid-template-columns: repeat(4, 1fr)\">\n");
    let _ = writeln!(
        body,
        "<figure><a href=\"{x}\"><img loading=\"lazy\" src=\"{x}\" alt=\"exact\"></a>\
         <figcaption><b>exact</b> · closed form, {}² tiles · {} · the reference{}</figcaption></figure>",
        results.metadata.exact_tiles,
        report::bytes(results.metadata.exact_bytes),
        exr_link(results.exact_hdr_image.as_deref()),
        x = e(&results.exact_image),
    );
    for c in results
        .cells
        .iter()
        .filter(|c| c.technique == smokeshadow_core::shadow::frame_baseline().name)
    {
        let _ = writeln!(
            body,
            "<figure><a href=\"{x}\"><img loading=\"lazy\" src=\"{x}\" alt=\"none\"></a>\
             <figcaption><b>none</b> · no self-shadowing · frame {} ms{}</figcaption></figure>",
            ms(c.frame_ms.median),
            exr_link(c.hdr_image.as_deref()),
            x = e(&c.image),
        );
    }
    body.push_str("</div>\n");

    let shadowed: Vec<&CellResult> = results
        .cells
        .iter()
        .filter(|c| c.technique != smokeshadow_core::shadow::frame_baseline().name)
        .collect();
    if shadowed.is_empty() {
        return;
    }
    let mut budgets: Vec<u32> = shadowed.iter().map(|c| c.channels).collect();
    budgets.sort_unstable_by(|a, b| b.cmp(a));
    budgets.dedup();
    let _ = writeln!(
        body,
        "<div class=\"grid\" style=\"grid-template-columns: 110px repeat({}, 1fr)\">",
        budgets.len()
    );
    body.push_str("<div></div>");
    for b in &budgets {
        let _ = write!(body, "<div><b>{b} channels</b></div>");
    }
    body.push('\n');
    let mut rows: Vec<String> = Vec::new();
    for c in &shadowed {
        let row = variants.row_label(c);
        if !rows.contains(&row) {
            rows.push(row);
        }
    }
    for row in &rows {
        let _ = write!(body, "<div class=\"rowhead\">{}</div>", e(row));
        for &b in &budgets {
            let Some(c) = shadowed
                .iter()
                .find(|c| c.channels == b && &variants.row_label(c) == row)
            else {
                body.push_str("<div class=\"empty\">—</div>");
                continue;
            };
            let mut links = Vec::new();
            for (label, path) in [
                ("×4 vs own 24", &c.diff_own_24),
                ("FLIP vs own 24", &c.flip_own_24),
                ("×4 vs exact", &c.diff_exact),
                ("FLIP vs exact", &c.flip_exact),
            ] {
                if let Some(path) = path {
                    links.push(format!("<a href=\"{}\">{label}</a>", e(path)));
                }
            }
            if let Some(path) = &c.hdr_image {
                links.push(format!("<a href=\"{}\">EXR</a>", e(path)));
            }
            let used = if c.channels_used == c.channels {
                String::new()
            } else {
                format!(" ({} used)", c.channels_used)
            };
            let _ = write!(
                body,
                "<figure><a href=\"{x}\"><img loading=\"lazy\" src=\"{x}\" alt=\"{label}\"></a>\
                 <figcaption>{b} ch{used} · {bytes} · FLIP vs exact {flip}<br>\
                 <span class=\"links\">{links}</span></figcaption></figure>",
                x = e(&c.image),
                label = e(&variants.cell_label(c)),
                bytes = report::bytes(c.resident_bytes),
                flip = metric(c.vs_exact.map(|x| x.flip_mean)),
                links = links.join(" "),
            );
        }
        body.push('\n');
    }
    body.push_str("</div>\n");
}

/// " · EXR" linking a cell's HDR frame, when the sweep wrote one.
fn exr_link(path: Option<&str>) -> String {
    path.map(|p| format!(" · <a href=\"{}\">EXR</a>", e(p)))
        .unwrap_or_default()
}

/// Whether the sweep has several shadow resolutions or splat modes, so labels must name them.
struct Variants {
    several_res: bool,
    several_splats: bool,
    /// Some cell draws its particles below full resolution (`--particle-res`).
    mixed_res: bool,
}

impl Variants {
    fn of(cells: &[CellResult]) -> Self {
        let shadowed = || {
            cells
                .iter()
                .filter(|c| c.technique != smokeshadow_core::shadow::frame_baseline().name)
        };
        let several = |differ: &dyn Fn(&CellResult, &CellResult) -> bool| {
            shadowed()
                .next()
                .is_some_and(|first| shadowed().any(|c| differ(first, c)))
        };
        Self {
            several_res: several(&|a, b| a.shadow_res != b.shadow_res),
            several_splats: several(&|a, b| a.splat != b.splat),
            mixed_res: cells.iter().any(|c| c.particle_res != ParticleRes::Full),
        }
    }

    fn several(&self) -> bool {
        self.several_res || self.several_splats || self.mixed_res
    }

    /// Technique, with resolution and splat where the sweep varies them: `dom 512² segment`.
    fn row_label(&self, c: &CellResult) -> String {
        let mut label = c.technique.clone();
        if self.several_res {
            let _ = write!(label, " {}²", c.shadow_res);
        }
        if self.several_splats {
            let _ = write!(label, " {}", c.splat.name());
        }
        if self.mixed_res {
            let _ = write!(label, " particles {}", c.particle_res);
        }
        label
    }

    /// `osm at 24 channels` (plus resolution and splat where they vary).
    fn cell_label(&self, c: &CellResult) -> String {
        let mut label = format!("{} at {} channels", c.technique, c.channels);
        if self.several_res {
            let _ = write!(label, ", {}²", c.shadow_res);
        }
        if self.several_splats {
            let _ = write!(label, ", {} splat", c.splat.name());
        }
        if self.mixed_res {
            let _ = write!(label, ", particles at {}", c.particle_res);
        }
        label
    }
}

/// The bytes a cell holds (resident: its build scratch included, as byte budgets count them)
/// per shadow-map texel, one decimal; "—" without a map (`none`, `exact`'s lists are no map
/// either).
fn bytes_per_texel(c: &CellResult) -> String {
    let kept = c.resident_bytes;
    let texels = u64::from(c.shadow_res).pow(2);
    let has_map = smokeshadow_core::shadow::find(&c.technique)
        .is_ok_and(|t| t.role == smokeshadow_core::shadow::Role::Contender);
    if kept == 0 || texels == 0 || !has_map {
        return "—".into();
    }
    format!("{:.1}", kept as f64 / texels as f64)
}

fn ms(value: f64) -> String {
    if value.is_finite() {
        format!("{value:.3}")
    } else {
        "—".into()
    }
}

fn timing_range(t: &Timing) -> String {
    format!(
        "{}<br><span class=\"muted range\">{}–{}</span>",
        ms(t.median),
        ms(t.min),
        ms(t.max)
    )
}

fn metric(value: Option<f64>) -> String {
    match value {
        Some(v) if v.is_finite() => format!("{v:.4}"),
        _ => "—".into(),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::sweep::{ImageError, SkippedCell, SweepMetadata};
    use smokeshadow_core::shadow::SplatMode;

    fn timing(ms: f64) -> Timing {
        Timing {
            median: ms,
            min: ms * 0.9,
            max: ms * 1.1,
        }
    }

    fn cell(technique: &str, channels: u32, bytes: u64, flip: Option<f64>) -> CellResult {
        let error = flip.map(|f| ImageError {
            flip_mean: f,
            rmse: f / 2.0,
        });
        let name = format!("{technique}_{channels}");
        let with_error = |kind: &str| flip.map(|_| format!("images/{name}_{kind}.png"));
        CellResult {
            technique: technique.into(),
            channels,
            byte_budgets: Vec::new(),
            memory_budgets: Vec::new(),
            channel_axis: true,
            channels_used: if technique == "fom" { 11 } else { channels },
            shadow_res: 512,
            splat: SplatMode::Point,
            particle_res: Default::default(),
            resident_bytes: bytes,
            transient_bytes: 0,
            smoke_texels: 0,
            gpu_shadow_ms: timing(1.0),
            gpu_render_ms: timing(4.0),
            cpu_sort_ms: timing(0.5),
            frame_ms: timing(6.0),
            wall_ms: timing(8.0),
            particles_ms: Default::default(),
            upsample_ms: Default::default(),
            particle_fragments: None,
            frames_timed: 20,
            overhead_ratio: flip.map(|_| 1.42),
            shadow_ratio: None,
            vs_own_24: error.filter(|_| channels != 24),
            vs_exact: error,
            vs_full_res: None,
            rms_transmittance_error: flip.map(|f| f * 2.0),
            image: format!("images/{name}.png"),
            diff_own_24: with_error("diff_own").filter(|_| channels != 24),
            flip_own_24: with_error("flip_own").filter(|_| channels != 24),
            diff_exact: with_error("diff_exact"),
            flip_exact: with_error("flip_exact"),
            hdr_image: None,
            settings_key: "k".into(),
            measured_against: None,
            motion: None,
        }
    }

    /// A small sweep's results (the gallery's tests borrow it).
    pub(crate) fn results() -> SweepResults {
        SweepResults {
            metadata: SweepMetadata {
                framing: smokeshadow_core::scene::Framing::Fit,
                shapes: Default::default(),
                tool_version: "0.1.0".into(),
                scene: "thesis_plume".into(),
                description: String::new(),
                scene_sha256: "00".into(),
                seed: 7,
                particles: 2500,
                width_px: 1024,
                height_px: 768,
                adapter: "llvmpipe <LLVM>".into(),
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
                wall_s: 75.0,
                shards: Vec::new(),
                motion: None,
            },
            cells: vec![
                cell("none", 24, 0, None),
                cell("osm", 24, 12 << 20, Some(0.02)),
                cell("osm", 8, 4 << 20, Some(0.05)),
                // Larger than osm 8 and worse: not on the front.
                cell("dom", 8, 5 << 20, Some(0.06)),
                cell("fom", 24, 22 << 20, Some(0.01)),
            ],
            skipped: vec![SkippedCell {
                technique: "dom".into(),
                channels: 1,
                bytes_per_texel: None,
                memory: None,
                reason: "dom needs at least 2 channels".into(),
            }],
            exact_image: "images/exact.png".into(),
            exact_hdr_image: None,
            animation: None,
        }
    }

    #[test]
    fn pareto_front_keeps_cells_nothing_smaller_beats() {
        let r = results();
        assert_eq!(pareto_front(&r.cells), [false, true, true, false, true]);
        assert!(pareto_front(&[]).is_empty());
    }

    #[test]
    fn page_links_resolve_and_name_every_technique() {
        let r = results();
        let dir = std::env::temp_dir().join(format!("sweep-report-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("images")).unwrap();
        // Placeholders for what the sweep engine writes.
        let mut files = vec![
            r.exact_image.clone(),
            "results.csv".into(),
            "results.json".into(),
        ];
        for c in &r.cells {
            files.push(c.image.clone());
            for path in [&c.diff_own_24, &c.flip_own_24, &c.diff_exact, &c.flip_exact]
                .into_iter()
                .flatten()
            {
                files.push(path.clone());
            }
        }
        for f in &files {
            std::fs::write(dir.join(f), b"").unwrap();
        }

        let charts = super::super::charts::write_charts(&r, &dir).unwrap();
        write_html(&r, &charts, &dir).unwrap();
        let html = std::fs::read_to_string(dir.join(INDEX_HTML)).unwrap();

        let referenced = referenced_paths(&html);
        for chart in &charts {
            assert!(
                referenced.contains(&chart.file.clone().into()),
                "{}",
                chart.file
            );
        }
        for f in &files {
            assert!(referenced.contains(&f.into()), "page does not link {f}");
        }
        for path in &referenced {
            assert!(path.is_relative(), "{}", path.display());
            assert!(dir.join(path).is_file(), "broken link {}", path.display());
        }
        for technique in ["none", "osm", "dom", "fom", "exact"] {
            assert!(html.contains(technique), "page never mentions {technique}");
        }
        assert!(
            html.contains("dom needs at least 2 channels"),
            "skipped reason"
        );
        assert!(
            html.contains("llvmpipe &lt;LLVM&gt;"),
            "metadata is escaped"
        );
        assert!(html.contains("1.42x") && html.contains("24 (11)"));
        assert_eq!(html.matches("class=\"pareto\"").count(), 3);
        // The answer at equal time ranks each technique's best cell within the budget (every
        // cell here takes 1.42x none's frame).
        let answer = &html[html.find("<h2>Answer").unwrap()..html.find("<h2>Charts").unwrap()];
        let within = &answer[answer.find("≤ 1.5x none").unwrap()..];
        let within = &within[..within.find("</tr>").unwrap()];
        assert!(
            within.contains("<b>fom at 24 channels</b>")
                && within.find("2. osm at 24").is_some()
                && within.find("3. dom at 8").is_some(),
            "{within}"
        );
        // The answer names the front in order of bytes, and the best cell.
        let answer = &answer[answer.find("Over every cell").unwrap()..];
        let osm8 = answer.find("osm at 8 channels").unwrap();
        let osm24 = answer.find("osm at 24 channels").unwrap();
        assert!(osm8 < osm24, "{answer}");
        assert!(!answer.contains("dom at 8"), "{answer}");
        assert!(
            answer.contains("overall: <b>fom at 24 channels</b>"),
            "{answer}"
        );
        assert!(
            !html.contains("http://") && !html.contains("https://"),
            "no network"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn empty_results_still_give_a_page() {
        let mut r = results();
        r.cells.clear();
        r.skipped.clear();
        let html = page(&r, &[]);
        assert!(html.contains("no answer"));
        assert!(html.contains("results.csv"));
    }
}
