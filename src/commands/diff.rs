//! `smokeshadow diff`: compares two PNGs with [`crate::diff`] (FLIP, RMSE, PSNR, SSIM, ...),
//! writes the thesis' enhanced difference and the FLIP heat map on request, and turns
//! `--fail-above METRIC=VALUE` thresholds into the exit code: 0 within every threshold, 1 when one
//! is exceeded, 2 (an `Err`, mapped in `main.rs`) when the images cannot be compared.

use std::path::PathBuf;
use std::process::ExitCode;

use serde::Serialize;

use crate::diff::{self, Comparison, Metric, Metrics};

const AFTER_HELP: &str = "\
Images are PNGs, 8- or 16-bit, grey or colour. An image with alpha is composited over black \
before comparing (smokeshadow's renders are opaque). Thresholds fail when an error metric is \
above the value; for psnr and ssim, which grow as images get closer, they fail when the value \
is below it. Exit status: 0 within every threshold, 1 when one is exceeded (the outputs are \
still written), 2 when the images cannot be compared.";

#[derive(Clone, Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct DiffArgs {
    /// The reference PNG (e.g. the `exact` render or a baseline).
    pub reference: PathBuf,
    /// The PNG to compare with it, of the same size.
    pub test: PathBuf,
    /// Write the difference image, |reference - test| x --enhance per channel, to this PNG.
    #[arg(long, short = 'o', value_name = "DIFF.png")]
    pub output: Option<PathBuf>,
    /// Factor the difference image is enhanced by (the thesis uses 4); > 0.
    #[arg(long, default_value_t = diff::DEFAULT_ENHANCE, value_parser = positive_finite_f32,
          allow_negative_numbers = true, value_name = "FACTOR")]
    pub enhance: f32,
    /// Write the FLIP error map, drawn with the magma colour map, to this PNG.
    #[arg(long, value_name = "FLIP.png")]
    pub flip_map: Option<PathBuf>,
    /// Exit with status 1 when METRIC is worse than VALUE (above it; below it for psnr and
    /// ssim). Metrics by their short name or the name `--json` prints: flip (flip_mean),
    /// flip_q1, flip_median (flip_weighted_median), flip_q3, flip_max, rmse (rmse_srgb),
    /// rmse_linear, max_abs (max_abs_srgb), beyond_one_step (beyond_one_step_share), visible
    /// (visible_share), psnr (psnr_srgb_db), psnr_linear (psnr_linear_db), ssim. Repeatable.
    #[arg(long, value_name = "METRIC=VALUE", value_parser = diff::parse_threshold)]
    pub fail_above: Vec<(Metric, f64)>,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}

fn positive_finite_f32(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("\"{s}\" is not a finite number > 0")),
    }
}

/// One threshold and how the images fared against it.
#[derive(Debug, Serialize)]
struct ThresholdResult {
    metric: Metric,
    threshold: f64,
    #[serde(serialize_with = "diff::finite_or_null")]
    value: f64,
    failed: bool,
}

#[derive(Debug, Serialize)]
struct Report<'a> {
    reference: String,
    test: String,
    width: u32,
    height: u32,
    metrics: &'a Metrics,
    thresholds: Vec<ThresholdResult>,
    passed: bool,
}

/// Runs `diff`: `Ok(0)` within all thresholds, `Ok(1)` when one is exceeded, `Err` when the
/// images cannot be read or compared or an output cannot be written.
pub fn run(args: &DiffArgs) -> anyhow::Result<ExitCode> {
    let (reference, test) = diff::load_pair(&args.reference, &args.test)?;
    let comparison = diff::compare(&reference, &test)?;

    if let Some(path) = &args.output {
        let difference = diff::enhanced_difference(&reference, &test, args.enhance);
        crate::output::write_png_rgb(path, &difference)?;
    }
    if let Some(path) = &args.flip_map {
        crate::output::write_png_rgb(path, &diff::flip_heatmap(&comparison))?;
    }

    let thresholds: Vec<ThresholdResult> = args
        .fail_above
        .iter()
        .map(|&(metric, threshold)| {
            let value = comparison.metrics.value(metric);
            ThresholdResult {
                metric,
                threshold,
                value,
                failed: metric.exceeded(value, threshold),
            }
        })
        .collect();
    let passed = thresholds.iter().all(|t| !t.failed);

    if args.json {
        let report = Report {
            reference: args.reference.display().to_string(),
            test: args.test.display().to_string(),
            width: comparison.width,
            height: comparison.height,
            metrics: &comparison.metrics,
            thresholds,
            passed,
        };
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_table(args, &comparison, &thresholds);
    }
    Ok(if passed {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

fn print_table(args: &DiffArgs, comparison: &Comparison, thresholds: &[ThresholdResult]) {
    let m = &comparison.metrics;
    println!("reference  {}", args.reference.display());
    println!("test       {}", args.test.display());
    println!("size       {}x{} px", comparison.width, comparison.height);
    println!();
    let visible = format!(
        "share of pixels with a channel off by more than {}/255",
        diff::VISIBLE_THRESHOLD
    );
    let rows: [(&str, String, &str); 13] = [
        (
            "flip",
            fraction(m.flip_mean),
            "FLIP mean error (0 = identical, 1 = worst)",
        ),
        (
            "flip_q1",
            fraction(m.flip_q1),
            "FLIP weighted first quartile",
        ),
        (
            "flip_median",
            fraction(m.flip_weighted_median),
            "FLIP weighted median",
        ),
        (
            "flip_q3",
            fraction(m.flip_q3),
            "FLIP weighted third quartile",
        ),
        ("flip_max", fraction(m.flip_max), "FLIP largest pixel error"),
        (
            "rmse",
            fraction(m.rmse_srgb),
            "RMSE of the sRGB values in [0, 1]",
        ),
        ("psnr", decibels(m.psnr_srgb_db), "PSNR of the sRGB values"),
        (
            "rmse_linear",
            fraction(m.rmse_linear),
            "RMSE of the linear values in [0, 1]",
        ),
        (
            "psnr_linear",
            decibels(m.psnr_linear_db),
            "PSNR of the linear values",
        ),
        (
            "max_abs",
            fraction(m.max_abs_srgb),
            "largest channel difference, sRGB in [0, 1]",
        ),
        (
            "beyond_one_step",
            fraction(m.beyond_one_step_share),
            "share of pixels with a channel off by more than 1/255",
        ),
        ("visible", fraction(m.visible_share), &visible),
        (
            "ssim",
            fraction(m.ssim),
            "structural similarity (1 = identical)",
        ),
    ];
    println!("{:<12} {:>10}  meaning", "metric", "value");
    for (name, value, meaning) in rows {
        println!("{name:<12} {value:>10}  {meaning}");
    }
    if thresholds.is_empty() {
        return;
    }
    println!();
    for t in thresholds {
        let op = if t.metric.higher_is_better() {
            "<"
        } else {
            ">"
        };
        println!(
            "{:<6} fail when {} {op} {}: {}",
            if t.failed { "FAILED" } else { "ok" },
            t.metric,
            t.threshold,
            format_plain(t.value),
        );
    }
    let failed = thresholds.iter().filter(|t| t.failed).count();
    if failed == 0 {
        println!("passed: within all {} thresholds", thresholds.len());
    } else {
        println!(
            "failed: {failed} of {} thresholds exceeded",
            thresholds.len()
        );
    }
}

/// A metric in [0, 1] (or SSIM in [-1, 1]) for the table.
fn fraction(v: f64) -> String {
    format!("{v:.6}")
}

/// A PSNR for the table; identical images print `inf dB`.
fn decibels(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.2} dB")
    } else {
        "inf dB".to_owned()
    }
}

/// A threshold's value at full precision, `inf` for an infinite PSNR.
fn format_plain(v: f64) -> String {
    if v.is_finite() {
        format!("{v}")
    } else {
        "inf".to_owned()
    }
}
