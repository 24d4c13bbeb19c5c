//! `smokeshadow diff` end to end: metrics of known image pairs against values worked out by hand,
//! the enhanced-difference PNG, the exit codes (0 within thresholds, 1 over one, 2 for bad
//! input) and one-line errors. Needs no GPU.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::{error_lines, scratch, smokeshadow};

use image::{Rgb, RgbImage, Rgba, RgbaImage};

fn code(out: &Output) -> i32 {
    out.status.code().expect("exited, not killed")
}

/// Asserts exit status 2 and one stderr line containing every needle.
fn assert_error(out: &Output, needles: &[&str]) {
    let lines = error_lines(out);
    assert_eq!(code(out), 2, "{lines:#?}");
    assert_eq!(lines.len(), 1, "one line expected, got {lines:#?}");
    for needle in needles {
        assert!(lines[0].contains(needle), "`{}` lacks `{needle}`", lines[0]);
    }
    assert!(!lines[0].contains("panicked"), "{}", lines[0]);
}

/// Runs `diff --json` with extra arguments and returns the exit status and the parsed report.
fn diff_json(reference: &Path, test: &Path, extra: &[&str]) -> (i32, serde_json::Value) {
    let mut args = vec![
        "diff",
        reference.to_str().unwrap(),
        test.to_str().unwrap(),
        "--json",
    ];
    args.extend_from_slice(extra);
    let out = smokeshadow(&args);
    assert!(error_lines(&out).is_empty(), "{:#?}", error_lines(&out));
    let report = serde_json::from_slice(&out.stdout).unwrap_or_else(|err| {
        panic!(
            "stdout is not JSON ({err}): {}",
            String::from_utf8_lossy(&out.stdout)
        )
    });
    (code(&out), report)
}

fn number(report: &serde_json::Value, metric: &str) -> f64 {
    report["metrics"][metric]
        .as_f64()
        .unwrap_or_else(|| panic!("metrics.{metric} is not a number: {report}"))
}

/// A 16x16 image with structure in green and blue and red 0 everywhere.
fn base() -> RgbImage {
    RgbImage::from_fn(16, 16, |x, y| Rgb([0, (x * 15) as u8, (y * 12 + 20) as u8]))
}

/// The pixels `known_pair` changes: red 0 -> 51 (0.2) on five, red 0 -> 200 on one.
const CHANGED_51: [(u32, u32); 5] = [(0, 0), (3, 7), (8, 8), (15, 2), (11, 15)];
const CHANGED_200: (u32, u32) = (5, 12);

fn known_pair(dir: &Path) -> (PathBuf, PathBuf) {
    let reference = base();
    let mut test = reference.clone();
    for (x, y) in CHANGED_51 {
        test.get_pixel_mut(x, y).0[0] = 51;
    }
    test.get_pixel_mut(CHANGED_200.0, CHANGED_200.1).0[0] = 200;
    let (a, b) = (dir.join("reference.png"), dir.join("test.png"));
    reference.save(&a).unwrap();
    test.save(&b).unwrap();
    (a, b)
}

/// sRGB decoding (IEC 61966-2-1), written out for the expected values.
fn linear(v: u8) -> f64 {
    let c = f64::from(v) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn assert_close(got: f64, want: f64, what: &str) {
    // The binary computes in f64 too; only summation order differs.
    assert!(
        (got - want).abs() <= 1e-9 * want.abs().max(1.0),
        "{what}: got {got}, want {want}"
    );
}

#[test]
fn identical_images_have_zero_error_and_infinite_psnr() {
    let dir = scratch("diff-identical");
    let a = dir.join("a.png");
    base().save(&a).unwrap();
    let (status, report) = diff_json(
        &a,
        &a,
        &["--fail-above", "flip=0", "--fail-above", "psnr=1000"],
    );
    assert_eq!(status, 0, "{report}");
    for metric in [
        "flip_mean",
        "flip_weighted_median",
        "flip_q1",
        "flip_q3",
        "flip_max",
        "rmse_linear",
        "rmse_srgb",
        "max_abs_srgb",
        "visible_share",
    ] {
        assert_eq!(number(&report, metric), 0.0, "{metric}: {report}");
    }
    assert!(report["metrics"]["psnr_srgb_db"].is_null(), "{report}");
    assert!(report["metrics"]["psnr_linear_db"].is_null(), "{report}");
    assert_eq!(number(&report, "ssim"), 1.0);
    assert_eq!(
        (report["width"].as_u64(), report["height"].as_u64()),
        (Some(16), Some(16))
    );
    assert_eq!(report["passed"], true);
    assert_eq!(report["thresholds"][1]["metric"], "psnr");
    assert!(report["thresholds"][1]["value"].is_null(), "{report}");

    // The table says "inf" for the PSNR.
    let out = smokeshadow(&["diff", a.to_str().unwrap(), a.to_str().unwrap()]);
    assert_eq!(code(&out), 0);
    let table = String::from_utf8_lossy(&out.stdout);
    let psnr_row = table
        .lines()
        .find(|l| l.starts_with("psnr "))
        .unwrap_or_else(|| panic!("no psnr row in\n{table}"));
    assert!(psnr_row.contains("inf"), "{psnr_row}");
}

#[test]
fn a_known_difference_gives_hand_computed_metrics_and_difference_image() {
    let dir = scratch("diff-known");
    let (a, b) = known_pair(&dir);
    let diff_png = dir.join("diff.png");
    let flip_png = dir.join("flip.png");
    let (status, report) = diff_json(
        &a,
        &b,
        &[
            "-o",
            diff_png.to_str().unwrap(),
            "--flip-map",
            flip_png.to_str().unwrap(),
        ],
    );
    assert_eq!(status, 0, "{report}");

    // 16x16 pixels x 3 channels = 768 values; only red changes, on 6 pixels.
    let values = 768.0;
    let mse_srgb = (5.0 * 0.2f64.powi(2) + (200.0f64 / 255.0).powi(2)) / values;
    let mse_linear = (5.0 * linear(51).powi(2) + linear(200).powi(2)) / values;
    assert_close(number(&report, "rmse_srgb"), mse_srgb.sqrt(), "rmse_srgb");
    assert_close(
        number(&report, "psnr_srgb_db"),
        10.0 * (1.0 / mse_srgb).log10(),
        "psnr",
    );
    assert_close(
        number(&report, "rmse_linear"),
        mse_linear.sqrt(),
        "rmse_linear",
    );
    assert_close(
        number(&report, "psnr_linear_db"),
        10.0 * (1.0 / mse_linear).log10(),
        "psnr_linear",
    );
    assert_close(number(&report, "max_abs_srgb"), 200.0 / 255.0, "max_abs");
    assert_close(
        number(&report, "visible_share"),
        6.0 / 256.0,
        "visible_share",
    );
    let flip = number(&report, "flip_mean");
    assert!(flip > 0.0 && flip < number(&report, "flip_max"), "{report}");
    assert!(number(&report, "ssim") < 1.0, "{report}");

    // Enhanced 4x: 51 -> 204; 200 -> 800, clamped to 255; unchanged pixels black.
    let difference = image::open(&diff_png).unwrap().into_rgb8();
    assert_eq!(difference.dimensions(), (16, 16));
    for (x, y, pixel) in difference.enumerate_pixels() {
        let want = if CHANGED_51.contains(&(x, y)) {
            [204, 0, 0]
        } else if (x, y) == CHANGED_200 {
            [255, 0, 0]
        } else {
            [0, 0, 0]
        };
        assert_eq!(pixel.0, want, "difference pixel ({x}, {y})");
    }
    let heat = image::open(&flip_png).unwrap().into_rgb8();
    assert_eq!(heat.dimensions(), (16, 16));
    // The most-changed pixel is brighter in the heat map than an unchanged corner far from it.
    let luma = |p: &Rgb<u8>| p.0.iter().map(|&c| u32::from(c)).sum::<u32>();
    assert!(luma(heat.get_pixel(CHANGED_200.0, CHANGED_200.1)) > luma(heat.get_pixel(15, 15)));

    // --enhance 2: 51 -> 102, 200 -> 400 -> 255.
    let out = smokeshadow(&[
        "diff",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--enhance",
        "2",
        "-o",
        diff_png.to_str().unwrap(),
    ]);
    assert_eq!(code(&out), 0, "{:#?}", error_lines(&out));
    let difference = image::open(&diff_png).unwrap().into_rgb8();
    assert_eq!(difference.get_pixel(0, 0).0, [102, 0, 0]);
    assert_eq!(
        difference.get_pixel(CHANGED_200.0, CHANGED_200.1).0,
        [255, 0, 0]
    );
}

#[test]
fn thresholds_fail_exactly_when_exceeded() {
    let dir = scratch("diff-thresholds");
    let (a, b) = known_pair(&dir);
    let (_, report) = diff_json(&a, &b, &[]);
    let rmse = number(&report, "rmse_srgb");
    let flip = number(&report, "flip_mean");
    let psnr = number(&report, "psnr_srgb_db");
    let ssim = number(&report, "ssim");
    let visible = number(&report, "visible_share");
    // (threshold, expected exit status): error metrics fail above, psnr and ssim below.
    let cases = [
        (format!("rmse={}", rmse * 1.001), 0),
        (format!("rmse={}", rmse * 0.999), 1),
        (format!("flip={}", flip * 1.001), 0),
        (format!("flip={}", flip * 0.999), 1),
        (format!("visible={visible}"), 0),
        (format!("psnr={}", psnr - 0.01), 0),
        (format!("psnr={}", psnr + 0.01), 1),
        (format!("ssim={}", ssim - 1e-4), 0),
        (format!("ssim={}", ssim + 1e-4), 1),
    ];
    for (threshold, want) in &cases {
        let (status, report) = diff_json(&a, &b, &["--fail-above", threshold]);
        assert_eq!(status, *want, "--fail-above {threshold}: {report}");
        assert_eq!(report["passed"], *want == 0, "{report}");
        assert_eq!(report["thresholds"][0]["failed"], *want == 1, "{report}");
    }

    // Several thresholds: one over is enough for 1, and the outputs are still written.
    let diff_png = dir.join("diff.png");
    let out = smokeshadow(&[
        "diff",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "-o",
        diff_png.to_str().unwrap(),
        "--fail-above",
        &format!("psnr={}", psnr - 1.0),
        "--fail-above",
        "max_abs=0.5",
    ]);
    assert_eq!(code(&out), 1, "{:#?}", error_lines(&out));
    assert!(error_lines(&out).is_empty(), "{:#?}", error_lines(&out));
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(
        table.contains("FAILED") && table.contains("max_abs"),
        "{table}"
    );
    assert!(diff_png.exists());
}

#[test]
fn bad_inputs_exit_2_with_one_line() {
    let dir = scratch("diff-bad");
    let (a, b) = known_pair(&dir);
    let (a, b) = (a.to_str().unwrap(), b.to_str().unwrap());

    let small = dir.join("small.png");
    RgbImage::new(8, 4).save(&small).unwrap();
    let small = small.to_str().unwrap();
    let out = smokeshadow(&["diff", a, small]);
    assert_error(&out, &["16x16", "8x4", "reference.png", "small.png"]);

    // Bytes from a fixed LCG: not a PNG, whatever the name says.
    let random = dir.join("random.png");
    let mut state = 0x2545_f491_u32;
    let bytes: Vec<u8> = (0..256)
        .map(|_| {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 24) as u8
        })
        .collect();
    std::fs::write(&random, bytes).unwrap();
    assert_error(
        &smokeshadow(&["diff", a, random.to_str().unwrap()]),
        &["random.png", "not a PNG"],
    );

    // A real PNG cut short: the signature is right, the data is not.
    let truncated = dir.join("truncated.png");
    let whole = std::fs::read(a).unwrap();
    std::fs::write(&truncated, &whole[..whole.len() / 2]).unwrap();
    assert_error(
        &smokeshadow(&["diff", truncated.to_str().unwrap(), b]),
        &["truncated.png", "corrupt"],
    );

    let missing = dir.join("missing.png");
    assert_error(
        &smokeshadow(&["diff", a, missing.to_str().unwrap()]),
        &["missing.png", "cannot read"],
    );

    assert_error(
        &smokeshadow(&["diff", a, b, "--fail-above", "mse=1"]),
        &["mse", "flip", "flip_median", "rmse_linear", "psnr", "ssim"],
    );
    assert_error(
        &smokeshadow(&["diff", a, b, "--fail-above", "flip"]),
        &["METRIC=VALUE"],
    );
    assert_error(
        &smokeshadow(&["diff", a, b, "--fail-above", "flip=lots"]),
        &["lots"],
    );
    for enhance in ["0", "-1", "inf", "nan"] {
        assert_error(
            &smokeshadow(&["diff", a, b, "--enhance", enhance]),
            &["--enhance"],
        );
    }

    // An output into a missing folder is an error too, and nothing is left behind.
    assert_error(
        &smokeshadow(&["diff", a, b, "-o", "/no/such/dir/diff.png"]),
        &["does not exist"],
    );
}

#[test]
fn rgba_is_compared_as_composited_over_black() {
    let dir = scratch("diff-rgba");
    let rgba = RgbaImage::from_fn(8, 8, |x, y| {
        Rgba([200, (x * 30) as u8, (y * 30) as u8, (x * 36) as u8])
    });
    let over_black = RgbImage::from_fn(8, 8, |x, y| {
        let p = rgba.get_pixel(x, y).0;
        let a = f32::from(p[3]) / 255.0;
        let c = |v: u8| (f32::from(v) * a).round() as u8;
        Rgb([c(p[0]), c(p[1]), c(p[2])])
    });
    let (a, b) = (dir.join("rgba.png"), dir.join("rgb.png"));
    rgba.save(&a).unwrap();
    over_black.save(&b).unwrap();
    let (status, report) = diff_json(&a, &b, &["--fail-above", "max_abs=0"]);
    assert_eq!(status, 0, "{report}");
    assert_eq!(number(&report, "max_abs_srgb"), 0.0, "{report}");
}

/// Our own FLIP (`diff::flip`, no C++), as the tool reports it (`diff::compare`), against
/// `nv-flip`'s (NVIDIA's C++ reference code) on every committed baseline's image against its
/// scene's `exact`, and on a pair of noisy images: their means agree within 1e-4, their
/// weighted quartiles within 1e-3.
#[test]
fn the_rust_flip_matches_nv_flips_mean_on_every_baseline_pair() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("baselines");
    let mut pairs = Vec::new();
    for scene in std::fs::read_dir(&root).unwrap() {
        let dir = scene.unwrap().path();
        if !dir.is_dir() {
            continue;
        }
        let exact = image::open(dir.join("exact.png")).unwrap().to_rgb8();
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "png") && !path.ends_with("exact.png") {
                pairs.push((
                    path.display().to_string(),
                    exact.clone(),
                    image::open(&path).unwrap().to_rgb8(),
                ));
            }
        }
    }
    assert!(pairs.len() >= 30, "{} pairs", pairs.len());
    // And two unrelated noisy images: every pixel differs, edges everywhere.
    let mut state = 12345u32;
    let mut noise = |w, h| {
        image::RgbImage::from_fn(w, h, |_, _| {
            image::Rgb(std::array::from_fn(|_| {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (state >> 24) as u8
            }))
        })
    };
    pairs.push(("noise".to_owned(), noise(97, 61), noise(97, 61)));
    // The pairs side by side on the cores (a debug build's FLIP takes about a second a pair).
    use rayon::prelude::*;
    let agreement = pairs
        .par_iter()
        .map(|(name, reference, test)| {
            assert_eq!(
                smokeshadow::diff::flip::DEFAULT_PPD,
                nv_flip::DEFAULT_PIXELS_PER_DEGREE
            );
            let ours =
                smokeshadow::diff::compare_with(reference, test, smokeshadow::diff::Ssim::Skip)
                    .unwrap()
                    .metrics;
            let (w, h) = reference.dimensions();
            let map = nv_flip::flip(
                nv_flip::FlipImageRgb8::with_data(w, h, reference.as_raw()),
                nv_flip::FlipImageRgb8::with_data(w, h, test.as_raw()),
                nv_flip::DEFAULT_PIXELS_PER_DEGREE,
            );
            let mut pool = nv_flip::FlipPool::from_image(&map);
            let theirs = [
                pool.mean(),
                pool.get_percentile(0.25, true),
                pool.get_percentile(0.5, true),
                pool.get_percentile(0.75, true),
            ]
            .map(f64::from);
            let ours = [
                ours.flip_mean,
                ours.flip_q1,
                ours.flip_weighted_median,
                ours.flip_q3,
            ];
            let mean = (ours[0] - theirs[0]).abs();
            let quartiles = (1..4)
                .map(|i| (ours[i] - theirs[i]).abs())
                .fold(0.0, f64::max);
            (
                mean,
                quartiles,
                format!("{name}: ours {ours:?}, nv-flip {theirs:?}"),
            )
        })
        .collect::<Vec<_>>();
    let worst_mean = agreement
        .iter()
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .expect("pairs");
    let worst_quartile = agreement
        .iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .expect("pairs");
    assert!(
        worst_mean.0 < 1e-4 && worst_quartile.1 < 1e-3,
        "worst over {} pairs: mean {} ({}), quartile {} ({})",
        pairs.len(),
        worst_mean.0,
        worst_mean.2,
        worst_quartile.1,
        worst_quartile.2
    );
}

/// The FLIP heat map's colours are FLIP's own magma table, entry by entry.
#[test]
fn the_heat_maps_colour_table_is_nv_flips() {
    let theirs = nv_flip::magma_lut().to_vec();
    let ours: Vec<u8> = smokeshadow::diff::magma::MAGMA
        .iter()
        .flatten()
        .copied()
        .collect();
    assert_eq!(ours, theirs);
}
