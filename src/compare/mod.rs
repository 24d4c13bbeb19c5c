//! The thesis' accuracy comparison (Images 7–33 of chapter 4.2.2.2), reproduced and measured.
//!
//! For one scene: every technique's 24-channel image (its baseline) and the pairwise
//! differences between those; every technique at the lower budgets and its difference from its
//! own 24-channel image, all enhanced 4x as in the thesis; and beyond the thesis, every image's
//! difference from `exact` with FLIP and RMSE for every pair. Written to a folder as PNGs,
//! `metrics.csv` and a self-contained `index.html` whose first table answers "which technique
//! is most accurate for a given memory".

use crate::Wait;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use serde::Serialize;

use crate::diff::{self, Metrics};
use crate::report;
use smokeshadow_core::gpu::Gpu;
use smokeshadow_core::render::{
    OUTPUT_FORMAT, OffscreenTarget, RenderOptions, Renderer, TechniqueConfig,
};
use smokeshadow_core::scene::Scene;
use smokeshadow_core::shadow::{self, SplatMode};

/// What to compare.
#[derive(Clone, Debug)]
pub struct CompareOptions {
    /// Techniques, in display order (registry names; `none` and `exact` are not compared).
    pub techniques: Vec<String>,
    /// Budgets, the first being the baseline budget (the thesis: 24, 16, 8, 6).
    pub budgets: Vec<u32>,
    pub splat: SplatMode,
}

impl Default for CompareOptions {
    fn default() -> Self {
        Self {
            techniques: smokeshadow_core::shadow::default_compare(),
            budgets: vec![24, 16, 8, 6],
            splat: SplatMode::Point,
        }
    }
}

/// One rendered image of the grid.
#[derive(Clone, Debug, Serialize)]
pub struct Cell {
    pub technique: String,
    pub channels: u32,
    pub channels_used: u32,
    pub bytes: u64,
    /// Relative paths (from the output folder).
    pub image: String,
    pub vs_baseline: Option<PairFiles>,
    pub vs_exact: PairFiles,
}

/// The files and metrics of one compared pair.
#[derive(Clone, Debug, Serialize)]
pub struct PairFiles {
    pub difference: String,
    pub flip_map: String,
    pub metrics: Metrics,
}

/// Compares `test` with `reference` and writes the x4 difference and the FLIP map as
/// `diffs/{stem}_x4.png` and `diffs/{stem}_flip.png` under `dir` (the sweep's comparisons too,
/// without SSIM: `ssim`).
pub fn write_pair(
    dir: &Path,
    reference: &image::RgbImage,
    test: &image::RgbImage,
    stem: &str,
    ssim: diff::Ssim,
) -> anyhow::Result<PairFiles> {
    let comparison = diff::compare_with(reference, test, ssim)?;
    let difference = format!("diffs/{stem}_x4.png");
    let flip_map = format!("diffs/{stem}_flip.png");
    crate::output::write_png_rgb(
        &dir.join(&difference),
        &diff::enhanced_difference(reference, test, diff::DEFAULT_ENHANCE),
    )?;
    crate::output::write_png_rgb(&dir.join(&flip_map), &diff::flip_heatmap(&comparison))?;
    Ok(PairFiles {
        difference,
        flip_map,
        metrics: comparison.metrics,
    })
}

/// Everything `compare` produced.
#[derive(Debug)]
pub struct CompareReport {
    pub scene: String,
    pub cells: Vec<Cell>,
    /// Differences between the techniques' baselines: (a, b, files).
    pub baseline_pairs: Vec<(String, String, PairFiles)>,
    pub exact_image: String,
    pub exact_bytes: u64,
    /// `exact`'s self-check against the f64 closed form (core/src/render/reference_check.rs).
    pub exact_check: Option<smokeshadow_core::render::reference_check::ReferenceCheck>,
    /// Every file written, relative to the output folder.
    pub files: Vec<String>,
}

/// Renders, compares and writes the report into `out_dir` (created if missing).
pub fn run(
    gpu: &Gpu,
    scene: &Scene,
    options: &CompareOptions,
    out_dir: &Path,
) -> anyhow::Result<CompareReport> {
    if options.budgets.is_empty() || options.techniques.is_empty() {
        anyhow::bail!("compare needs at least one technique and one budget");
    }
    for t in &options.techniques {
        let entry = shadow::find(t)?;
        for &b in &options.budgets {
            shadow::check_channels(entry, b)?;
        }
    }
    if out_dir.is_file() {
        anyhow::bail!("output {} is a file; give a folder", out_dir.display());
    }
    for sub in ["images", "diffs"] {
        std::fs::create_dir_all(out_dir.join(sub))
            .with_context(|| format!("cannot create {}", out_dir.join(sub).display()))?;
    }
    let particles = crate::particles::scene_particles(scene)?;
    let (w, h) = (scene.output.width_px, scene.output.height_px);
    let config = |name: &str, channels: u32| {
        let mut params = scene.shadow.params(channels);
        params.splat = options.splat;
        TechniqueConfig {
            name: name.to_owned(),
            params,
        }
    };
    let mut renderer = Renderer::new(
        gpu,
        w,
        h,
        OUTPUT_FORMAT,
        &config(smokeshadow_core::shadow::frame_baseline().name, 1),
    )
    .wait()?;
    let target = OffscreenTarget::new(gpu, w, h);
    let mut check = None;
    let mut render =
        |config: &TechniqueConfig, file: &str| -> anyhow::Result<(image::RgbImage, u32, u64)> {
            renderer.set_technique(gpu, config).wait()?;
            renderer
                .render(
                    gpu,
                    scene,
                    &particles,
                    &RenderOptions::default(),
                    &target.view,
                )
                .wait()?;
            let rgb = target.read_rgb(gpu).wait()?;
            // The reference checks itself before anything is compared with it.
            if let Some(c) = smokeshadow_core::render::reference_check::verify_if_reference(
                &mut renderer,
                gpu,
                scene,
                &particles,
            )
            .wait()?
            {
                check = Some(c);
            }
            crate::output::write_png_rgb(&out_dir.join(file), &rgb)?;
            let t = renderer.technique();
            Ok((rgb, t.channels_used(), t.memory().peak_bytes()))
        };

    let exact_config = config(smokeshadow_core::shadow::reference().name, 1);
    let exact_image = "images/exact.png".to_owned();
    let (exact, _, exact_bytes) = render(&exact_config, &exact_image)?;

    let pair = |reference: &image::RgbImage, test: &image::RgbImage, stem: &str| {
        write_pair(out_dir, reference, test, stem, diff::Ssim::Compute)
    };

    let baseline_budget = options.budgets[0];
    let mut cells = Vec::new();
    let mut baselines: Vec<(String, image::RgbImage)> = Vec::new();
    for name in &options.techniques {
        let mut baseline_image = None;
        for &b in &options.budgets {
            let image_path = format!("images/{name}_{b}.png");
            let (image, channels_used, bytes) = render(&config(name, b), &image_path)?;
            let vs_baseline = match &baseline_image {
                None => None,
                Some(reference) => Some(pair(
                    reference,
                    &image,
                    &format!("{name}_{b}_vs_{name}_{baseline_budget}"),
                )?),
            };
            let vs_exact = pair(&exact, &image, &format!("{name}_{b}_vs_exact"))?;
            cells.push(Cell {
                technique: name.clone(),
                channels: b,
                channels_used,
                bytes,
                image: image_path,
                vs_baseline,
                vs_exact,
            });
            if baseline_image.is_none() {
                baseline_image = Some(image);
            }
        }
        baselines.push((name.clone(), baseline_image.expect("budgets are not empty")));
    }
    let mut baseline_pairs = Vec::new();
    for i in 0..baselines.len() {
        for j in i + 1..baselines.len() {
            let (a, ia) = &baselines[i];
            let (b, ib) = &baselines[j];
            let files = pair(
                ia,
                ib,
                &format!("{a}_{baseline_budget}_vs_{b}_{baseline_budget}"),
            )?;
            baseline_pairs.push((a.clone(), b.clone(), files));
        }
    }

    let mut files = vec![exact_image.clone()];
    for c in &cells {
        files.push(c.image.clone());
        for p in c.vs_baseline.iter().chain([&c.vs_exact]) {
            files.extend([p.difference.clone(), p.flip_map.clone()]);
        }
    }
    for (_, _, p) in &baseline_pairs {
        files.extend([p.difference.clone(), p.flip_map.clone()]);
    }
    files.extend(["metrics.csv".to_owned(), "index.html".to_owned()]);
    let report = CompareReport {
        scene: scene.name.clone(),
        cells,
        baseline_pairs,
        exact_image,
        exact_bytes,
        exact_check: check,
        files,
    };
    write_csv(&report, baseline_budget, &out_dir.join("metrics.csv"))?;
    report::write_studies(out_dir)?;
    crate::output::write_atomic(
        &out_dir.join("index.html"),
        html(&report, options, scene).as_bytes(),
    )?;
    Ok(report)
}

/// One row per compared pair.
fn write_csv(report: &CompareReport, baseline_budget: u32, path: &Path) -> anyhow::Result<()> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    writer.write_record([
        "test",
        "reference",
        "kind",
        "technique",
        "channels",
        "channels_used",
        "bytes",
        "flip_mean",
        "flip_weighted_median",
        "flip_max",
        "rmse_srgb",
        "psnr_srgb_db",
        "rmse_linear",
        "ssim",
        "visible_share",
    ])?;
    let mut row = |test: &str, reference: &str, kind: &str, cell: Option<&Cell>, m: &Metrics| {
        let (technique, channels, used, bytes) = cell
            .map(|c| {
                (
                    c.technique.clone(),
                    c.channels.to_string(),
                    c.channels_used.to_string(),
                    c.bytes.to_string(),
                )
            })
            .unwrap_or_default();
        writer.write_record([
            test.to_owned(),
            reference.to_owned(),
            kind.to_owned(),
            technique,
            channels,
            used,
            bytes,
            format!("{:.6}", m.flip_mean),
            format!("{:.6}", m.flip_weighted_median),
            format!("{:.6}", m.flip_max),
            format!("{:.6}", m.rmse_srgb),
            format!("{:.3}", m.psnr_srgb_db),
            format!("{:.6}", m.rmse_linear),
            format!("{:.6}", m.ssim),
            format!("{:.6}", m.visible_share),
        ])
    };
    for c in &report.cells {
        let label = format!("{}_{}", c.technique, c.channels);
        row(
            &label,
            smokeshadow_core::shadow::reference().name,
            "vs_exact",
            Some(c),
            &c.vs_exact.metrics,
        )?;
        if let Some(own) = &c.vs_baseline {
            let reference = format!("{}_{baseline_budget}", c.technique);
            row(&label, &reference, "vs_own_baseline", Some(c), &own.metrics)?;
        }
    }
    for (a, b, files) in &report.baseline_pairs {
        row(
            &format!("{b}_{baseline_budget}"),
            &format!("{a}_{baseline_budget}"),
            "baseline_pair",
            None,
            &files.metrics,
        )?;
    }
    let bytes = writer.into_inner().context("cannot encode metrics.csv")?;
    crate::output::write_atomic(path, &bytes)
}

/// The page: the summary table, the image grid with its view toggles, baseline pairs, and
/// every metric.
fn html(report: &CompareReport, options: &CompareOptions, scene: &Scene) -> String {
    let e = report::escape;
    let mut body = String::new();
    let _ = write!(
        body,
        "<h1>smokeshadow compare: {}</h1>\n<p class=\"muted\">{}x{} frame, {} particles, shadow map {}², {} splat; \
         reference: <code>exact</code>, the closed form per point ({}; {}). Differences are |a − b| × {} as in the thesis; FLIP maps use the magma scale.</p>\n",
        e(&report.scene),
        scene.output.width_px,
        scene.output.height_px,
        crate::particles::count(scene),
        scene.shadow.resolution_px,
        options.splat.label(),
        report::bytes(report.exact_bytes),
        report
            .exact_check
            .map_or("not checked".to_owned(), |c| e(&c.to_string())),
        diff::DEFAULT_ENHANCE
    );
    body.push_str(&report::studies_paragraph());

    // Which technique is most accurate for a given memory: FLIP mean against exact.
    body.push_str("<h2>Most accurate per budget</h2>\n<p>FLIP mean against <code>exact</code> (lower is better) and the memory each technique allocated. The best in each row is highlighted.</p>\n<table><tr><th>channels</th>");
    for t in &options.techniques {
        let _ = write!(body, "<th>{}</th>", e(t));
    }
    body.push_str("<th>most accurate</th></tr>\n");
    let mut verdicts = Vec::new();
    for &b in &options.budgets {
        let row: Vec<&Cell> = options
            .techniques
            .iter()
            .filter_map(|t| {
                report
                    .cells
                    .iter()
                    .find(|c| &c.technique == t && c.channels == b)
            })
            .collect();
        let best = row.iter().min_by(|x, y| {
            x.vs_exact
                .metrics
                .flip_mean
                .total_cmp(&y.vs_exact.metrics.flip_mean)
        });
        let _ = write!(body, "<tr><td>{b}</td>");
        for c in &row {
            let class = if best.is_some_and(|x| x.technique == c.technique) {
                " class=\"best\""
            } else {
                ""
            };
            let _ = write!(
                body,
                "<td{class}>{:.4}<br><span class=\"muted\">{}</span></td>",
                c.vs_exact.metrics.flip_mean,
                report::bytes(c.bytes)
            );
        }
        if let Some(best) = best {
            let _ = write!(body, "<td>{}</td>", e(&best.technique));
            verdicts.push(format!(
                "{b} channels: {} ({:.4}, {})",
                best.technique,
                best.vs_exact.metrics.flip_mean,
                report::bytes(best.bytes)
            ));
        }
        body.push_str("</tr>\n");
    }
    body.push_str("</table>\n");
    let _ = writeln!(
        body,
        "<p><b>Closest to exact</b> — {}.</p>",
        e(&verdicts.join("; "))
    );

    // The same question by memory: every configuration by bytes; the Pareto front (nothing
    // else is both smaller and closer to exact) is highlighted.
    body.push_str("<h2>Accuracy per memory</h2>\n<p>Every configuration by the bytes it allocated. Highlighted: the Pareto front — no other configuration is both smaller and closer to <code>exact</code>.</p>\n<table><tr><th>configuration</th><th>bytes</th><th>FLIP vs exact</th><th>RMSE vs exact</th></tr>\n");
    let mut by_bytes: Vec<&Cell> = report.cells.iter().collect();
    by_bytes.sort_by(|a, b| {
        a.bytes.cmp(&b.bytes).then(
            a.vs_exact
                .metrics
                .flip_mean
                .total_cmp(&b.vs_exact.metrics.flip_mean),
        )
    });
    let mut best_so_far = f64::INFINITY;
    for c in by_bytes {
        let flip = c.vs_exact.metrics.flip_mean;
        let pareto = flip < best_so_far;
        best_so_far = best_so_far.min(flip);
        let class = if pareto { " class=\"best\"" } else { "" };
        let _ = writeln!(
            body,
            "<tr><td{class}>{} at {} channels</td><td{class}>{}</td><td{class}>{:.4}</td><td{class}>{:.4}</td></tr>",
            e(&c.technique),
            c.channels,
            report::bytes(c.bytes),
            flip,
            c.vs_exact.metrics.rmse_srgb
        );
    }
    body.push_str("</table>\n");

    // The grid.
    let views = [
        ("image", "image"),
        ("own", "× 4 vs own baseline"),
        ("exact", "× 4 vs exact"),
        ("flip", "FLIP vs exact"),
    ];
    body.push_str("<h2>Images</h2>\n<div class=\"toolbar\">Show: ");
    for (i, (key, label)) in views.iter().enumerate() {
        let on = if i == 0 { " class=\"on\"" } else { "" };
        let _ = write!(body, "<button data-view=\"{key}\"{on}>{label}</button>");
    }
    body.push_str(
        " <span class=\"muted\">(or click an image to cycle its own view)</span></div>\n",
    );
    let columns = options.budgets.len() + 1;
    let _ = writeln!(
        body,
        "<div class=\"grid\" style=\"grid-template-columns: 90px repeat({}, 1fr)\">",
        columns - 1
    );
    body.push_str("<div></div>");
    for &b in &options.budgets {
        let _ = write!(body, "<div><b>{b} channels</b></div>");
    }
    body.push('\n');
    for t in &options.techniques {
        let _ = write!(body, "<div class=\"rowhead\">{}</div>", e(t));
        for c in report.cells.iter().filter(|c| &c.technique == t) {
            let own = c
                .vs_baseline
                .as_ref()
                .map_or(c.image.as_str(), |p| p.difference.as_str());
            let _ = write!(
                body,
                "<figure><img loading=\"lazy\" src=\"{img}\" data-image=\"{img}\" data-own=\"{own}\" data-exact=\"{ex}\" data-flip=\"{fl}\" alt=\"{t} at {b} channels\">\
                 <figcaption>{used} ch used · {bytes}<br>vs exact: FLIP {fe:.4} · RMSE {re:.4}{own_line}</figcaption></figure>",
                img = e(&c.image),
                own = e(own),
                ex = e(&c.vs_exact.difference),
                fl = e(&c.vs_exact.flip_map),
                t = e(t),
                b = c.channels,
                used = c.channels_used,
                bytes = report::bytes(c.bytes),
                fe = c.vs_exact.metrics.flip_mean,
                re = c.vs_exact.metrics.rmse_srgb,
                own_line = c.vs_baseline.as_ref().map_or(String::new(), |p| format!(
                    "<br>vs own {}: FLIP {:.4} · RMSE {:.4}",
                    options.budgets[0], p.metrics.flip_mean, p.metrics.rmse_srgb
                )),
            );
        }
        body.push('\n');
    }
    let _ = writeln!(
        body,
        "<div class=\"rowhead\">exact</div><figure><img loading=\"lazy\" src=\"{x}\" data-image=\"{x}\" data-own=\"{x}\" data-exact=\"{x}\" data-flip=\"{x}\" alt=\"exact\"><figcaption>reference · {}</figcaption></figure>",
        report::bytes(report.exact_bytes),
        x = e(&report.exact_image)
    );
    body.push_str("</div>\n");

    // Pairwise differences between the baselines (thesis Images 10–12).
    let _ = writeln!(
        body,
        "<h2>Differences between the {}-channel baselines (× 4)</h2>\n<div class=\"grid\" style=\"grid-template-columns: repeat(4, 1fr)\">",
        options.budgets[0]
    );
    for (a, b, p) in &report.baseline_pairs {
        let _ = write!(
            body,
            "<figure><img loading=\"lazy\" src=\"{}\" alt=\"{a} vs {b}\"><figcaption>{} vs {}: FLIP {:.4} · RMSE {:.4} · <a href=\"{}\">FLIP map</a></figcaption></figure>",
            e(&p.difference),
            e(a),
            e(b),
            p.metrics.flip_mean,
            p.metrics.rmse_srgb,
            e(&p.flip_map)
        );
    }
    body.push_str("</div>\n");

    // Every metric.
    body.push_str("<h2>All metrics</h2>\n<p><a href=\"metrics.csv\">metrics.csv</a> has the same rows.</p>\n<table><tr><th>test</th><th>reference</th><th>bytes</th><th>FLIP mean</th><th>FLIP median</th><th>FLIP max</th><th>RMSE (sRGB)</th><th>PSNR dB</th><th>SSIM</th><th>visible %</th></tr>\n");
    let mut metric_row = |test: String, reference: String, bytes: String, m: &Metrics| {
        let _ = writeln!(
            body,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.4}</td><td>{:.4}</td><td>{:.3}</td><td>{:.4}</td><td>{:.2}</td><td>{:.4}</td><td>{:.2}</td></tr>",
            e(&test),
            e(&reference),
            bytes,
            m.flip_mean,
            m.flip_weighted_median,
            m.flip_max,
            m.rmse_srgb,
            m.psnr_srgb_db,
            m.ssim,
            m.visible_share * 100.0
        );
    };
    for c in &report.cells {
        let label = format!("{} {}", c.technique, c.channels);
        metric_row(
            label.clone(),
            "exact".into(),
            report::bytes(c.bytes),
            &c.vs_exact.metrics,
        );
        if let Some(p) = &c.vs_baseline {
            metric_row(
                label,
                format!("{} {}", c.technique, options.budgets[0]),
                report::bytes(c.bytes),
                &p.metrics,
            );
        }
    }
    for (a, b, p) in &report.baseline_pairs {
        metric_row(
            format!("{b} {}", options.budgets[0]),
            format!("{a} {}", options.budgets[0]),
            String::new(),
            &p.metrics,
        );
    }
    body.push_str("</table>\n");
    report::page(
        &format!("smokeshadow compare: {}", report.scene),
        &body,
        SCRIPT,
    )
}

/// View toggles: the toolbar switches every image; a click cycles one.
const SCRIPT: &str = r#"
const views = ["image", "own", "exact", "flip"];
function show(img, view) { img.src = img.dataset[view]; img.dataset.view = view; }
document.querySelectorAll(".toolbar button").forEach(button => {
  button.addEventListener("click", () => {
    document.querySelectorAll(".toolbar button").forEach(b => b.classList.toggle("on", b === button));
    document.querySelectorAll("img[data-image]").forEach(img => show(img, button.dataset.view));
  });
});
document.querySelectorAll("img[data-image]").forEach(img => {
  img.addEventListener("click", () => {
    const next = views[(views.indexOf(img.dataset.view || "image") + 1) % views.length];
    show(img, next);
  });
});
"#;

/// Every path the page references (`src` and `href` attributes), for checking a report.
pub fn referenced_paths(html: &str) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for attr in [
        "src=\"",
        "href=\"",
        "data-image=\"",
        "data-own=\"",
        "data-exact=\"",
        "data-flip=\"",
    ] {
        let mut rest = html;
        while let Some(i) = rest.find(attr) {
            rest = &rest[i + attr.len()..];
            if let Some(end) = rest.find('"') {
                // A link to a section names the file before its '#'.
                let link = &rest[..end];
                out.push(PathBuf::from(link.split('#').next().unwrap_or(link)));
                rest = &rest[end..];
            }
        }
    }
    out
}
