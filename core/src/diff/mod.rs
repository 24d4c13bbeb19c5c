//! Image differences: how far a test image (a technique's render) is from a reference (the
//! `exact` technique, or a committed baseline), as numbers and as pictures.
//!
//! The numbers are [`Metrics`]: NVIDIA's FLIP (Andersson et al. 2020, the perceptual error the
//! golden-image tests use), RMSE and PSNR of the sRGB values and of the linear values they
//! encode, the largest channel difference, the share of visibly different pixels, and SSIM. The
//! pictures are the thesis' "difference enhanced 4x" ([`enhanced_difference`], Giuliatti 2013,
//! 4.2.2.2) and the FLIP error map through the magma colour map ([`flip_heatmap`]).
//!
//! Images are 8-bit sRGB RGB ([`decode_png`] converts anything else). Thresholds name a metric
//! ([`Metric`], `METRIC=VALUE` via [`parse_threshold`]). To add a metric: compute it in
//! [`compare`], add the field to [`Metrics`] and, if thresholds may name it, a [`Metric`].

pub mod flip;
mod load;
pub mod magma;
mod metric;

use std::path::PathBuf;

use image::RgbImage;
use serde::Serialize;

pub use load::{decode_png, same_size};
pub use metric::{Metric, parse_threshold};

/// The enhancement factor of the thesis' difference images ("difference enhanced 4x").
pub const DEFAULT_ENHANCE: f32 = 4.0;

/// A pixel counts as visibly different when one of its channels differs by more than this many
/// 8-bit sRGB steps (3/255). sRGB spends its 256 steps roughly evenly in perceived lightness, and
/// on a typical display one or two steps are invisible outside the darkest tones (they are what
/// rounding, dithering or another GPU's arithmetic produce); about three steps is where a
/// difference becomes just noticeable, so this counts pixels a viewer could see change.
pub const VISIBLE_THRESHOLD: u8 = 3;

/// Why two images could not be compared. Each message is one line naming the file or the sizes.
#[derive(Debug, thiserror::Error)]
pub enum DiffError {
    /// The file could not be read at all. (`cause` is not a `#[source]`: the message already
    /// says it, and a source would repeat it in `{:#}` chains.)
    #[error("cannot read {}: {cause}", .path.display())]
    Read {
        path: PathBuf,
        cause: std::io::Error,
    },
    /// The file does not start with the PNG signature.
    #[error("{} is not a PNG file (it lacks the PNG signature)", .path.display())]
    NotPng { path: PathBuf },
    /// The file starts like a PNG but does not decode.
    #[error("{} is a corrupt or unsupported PNG: {reason}", .path.display())]
    CorruptPng { path: PathBuf, reason: String },
    /// The images differ in size. `reference` and `test` describe the images, e.g.
    /// "reference a.png" or "reference image".
    #[error(
        "{reference} is {}x{} but {test} is {}x{}",
        .reference_size_px.0, .reference_size_px.1, .test_size_px.0, .test_size_px.1
    )]
    SizeMismatch {
        reference: String,
        reference_size_px: (u32, u32),
        test: String,
        test_size_px: (u32, u32),
    },
    /// The SSIM implementation refused the images.
    #[error("cannot compute SSIM: {0}")]
    Ssim(String),
}

/// How far a test image is from a reference. Errors are 0 for identical images; all values
/// derived from pixel values use the range [0, 1].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Metrics {
    /// Mean FLIP error over the pixels (FLIP's recommended single number), in [0, 1].
    pub flip_mean: f64,
    /// FLIP weighted median: the error below which half of the summed error lies, as FLIP's
    /// pool computes it (`get_percentile(0.5, weighted = true)`).
    pub flip_weighted_median: f64,
    /// FLIP weighted first quartile.
    pub flip_q1: f64,
    /// FLIP weighted third quartile.
    pub flip_q3: f64,
    /// Largest per-pixel FLIP error.
    pub flip_max: f64,
    /// RMSE over all RGB channel values after decoding sRGB to linear, values in [0, 1].
    pub rmse_linear: f64,
    /// PSNR of the linear values, 10 log10(1 / MSE) in dB; infinite for identical images
    /// (serialized as `null`).
    #[serde(serialize_with = "finite_or_null")]
    pub psnr_linear_db: f64,
    /// RMSE over all RGB channel values as stored (8-bit sRGB scaled to [0, 1]).
    pub rmse_srgb: f64,
    /// PSNR of the sRGB values, 10 log10(1 / MSE) in dB; infinite for identical images
    /// (serialized as `null`).
    #[serde(serialize_with = "finite_or_null")]
    pub psnr_srgb_db: f64,
    /// Largest |reference - test| over all channels, sRGB in [0, 1].
    pub max_abs_srgb: f64,
    /// Share of pixels whose largest channel difference exceeds one 8-bit step, in [0, 1]: what
    /// another CPU's rounding never produces (see `baseline::criterion`).
    pub beyond_one_step_share: f64,
    /// Share of pixels whose largest channel difference exceeds [`VISIBLE_THRESHOLD`] 8-bit
    /// steps, in [0, 1].
    pub visible_share: f64,
    /// Structural similarity (image-compare's MSSIMSimple: 8x8 windows, per RGB channel, the
    /// lowest channel's score); 1 = identical. NaN (`null` in JSON) where it was not asked for
    /// ([`Ssim::Skip`]).
    pub ssim: f64,
}

/// Whether [`compare_with`] computes SSIM: a tenth of a comparison's time, which the sweep,
/// reporting FLIP and RMSE, does not spend.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ssim {
    Compute,
    Skip,
}

/// The result of [`compare`]: the metrics and the per-pixel FLIP error they pool.
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    pub metrics: Metrics,
    /// FLIP error per pixel in [0, 1], `width * height` values, row-major from the top left.
    pub flip_map: Vec<f32>,
    pub width: u32,
    pub height: u32,
}

/// Serializes a non-finite number (an infinite PSNR) as `null`, which JSON can hold.
pub fn finite_or_null<S: serde::Serializer>(value: &f64, serializer: S) -> Result<S::Ok, S::Error> {
    if value.is_finite() {
        serializer.serialize_f64(*value)
    } else {
        serializer.serialize_none()
    }
}

/// Compares `test` with `reference`: FLIP at FLIP's default 67 pixels per degree (a 0.7 m
/// viewing distance from a 24" 4K monitor), the pixel statistics and SSIM. Fails when the sizes
/// differ (the error gives both).
pub fn compare(reference: &RgbImage, test: &RgbImage) -> Result<Comparison, DiffError> {
    compare_with(reference, test, Ssim::Compute)
}

/// [`compare`], with SSIM only when `ssim` asks for it.
pub fn compare_with(
    reference: &RgbImage,
    test: &RgbImage,
    ssim: Ssim,
) -> Result<Comparison, DiffError> {
    if reference.dimensions() != test.dimensions() {
        return Err(DiffError::SizeMismatch {
            reference: "reference image".to_owned(),
            reference_size_px: reference.dimensions(),
            test: "test image".to_owned(),
            test_size_px: test.dimensions(),
        });
    }
    let (width, height) = reference.dimensions();

    let flip_map = flip::flip_map(reference, test, flip::DEFAULT_PPD);
    let pool = flip::Pool::of(&flip_map);

    let pixels = pixel_statistics(reference, test);
    let ssim = match ssim {
        Ssim::Compute => {
            image_compare::rgb_similarity_structure(
                &image_compare::Algorithm::MSSIMSimple,
                reference,
                test,
            )
            .map_err(|err| DiffError::Ssim(err.to_string()))?
            .score
        }
        Ssim::Skip => f64::NAN,
    };

    let metrics = Metrics {
        flip_mean: pool.mean(),
        flip_weighted_median: pool.weighted_percentile(0.5),
        flip_q1: pool.weighted_percentile(0.25),
        flip_q3: pool.weighted_percentile(0.75),
        flip_max: f64::from(flip_map.iter().copied().fold(0.0f32, f32::max)),
        rmse_linear: pixels.mse_linear.sqrt(),
        psnr_linear_db: psnr_db(pixels.mse_linear),
        rmse_srgb: pixels.mse_srgb.sqrt(),
        psnr_srgb_db: psnr_db(pixels.mse_srgb),
        max_abs_srgb: f64::from(pixels.max_abs_steps) / 255.0,
        beyond_one_step_share: pixels.beyond_one_step_px as f64
            / f64::from(width * height).max(1.0),
        visible_share: pixels.visible_px as f64 / f64::from(width * height).max(1.0),
        ssim,
    };
    Ok(Comparison {
        metrics,
        flip_map,
        width,
        height,
    })
}

/// The thesis' difference image: per channel `min(255, round(|reference - test| * enhance))`
/// ([`DEFAULT_ENHANCE`] = 4). Callers compare sizes first ([`compare`], [`same_size`]); should
/// they differ, the result covers the region the two images share.
pub fn enhanced_difference(reference: &RgbImage, test: &RgbImage, enhance: f32) -> RgbImage {
    let width = reference.width().min(test.width());
    let height = reference.height().min(test.height());
    RgbImage::from_fn(width, height, |x, y| {
        let a = reference.get_pixel(x, y).0;
        let b = test.get_pixel(x, y).0;
        image::Rgb(std::array::from_fn(|c| {
            let scaled = (f32::from(a[c].abs_diff(b[c])) * enhance).round();
            // `as` saturates, so a huge or NaN product cannot wrap.
            scaled.clamp(0.0, 255.0) as u8
        }))
    })
}

/// The FLIP error map drawn through FLIP's magma colour map (black = no error, pale yellow =
/// error 1), as FLIP's own tool draws it. Pixels missing from a malformed `flip_map` are drawn as
/// error 0.
pub fn flip_heatmap(comparison: &Comparison) -> RgbImage {
    let width = comparison.width;
    RgbImage::from_fn(width, comparison.height, |x, y| {
        let index = y as usize * width as usize + x as usize;
        let error = comparison.flip_map.get(index).copied().unwrap_or(0.0);
        // FLIP's colorMap: entry round(error * 255) of the 256-entry LUT.
        let entry = (error * 255.0 + 0.5).clamp(0.0, 255.0) as usize;
        image::Rgb(magma::MAGMA[entry.min(255)])
    })
}

/// 10 log10(1 / MSE) for values in [0, 1]; infinite when the MSE is 0.
fn psnr_db(mse: f64) -> f64 {
    if mse > 0.0 {
        10.0 * (1.0 / mse).log10()
    } else {
        f64::INFINITY
    }
}

/// The per-channel statistics behind the RMSE, PSNR, max-abs and visible-share metrics.
struct PixelStatistics {
    mse_srgb: f64,
    mse_linear: f64,
    max_abs_steps: u8,
    beyond_one_step_px: u64,
    visible_px: u64,
}

fn pixel_statistics(reference: &RgbImage, test: &RgbImage) -> PixelStatistics {
    let to_linear: [f64; 256] = std::array::from_fn(|v| srgb_to_linear(v as f64 / 255.0));
    let mut sum_sq_srgb = 0.0;
    let mut sum_sq_linear = 0.0;
    let mut max_abs_steps = 0u8;
    let mut visible_px = 0u64;
    let mut beyond_one_step_px = 0u64;
    for (a, b) in reference.pixels().zip(test.pixels()) {
        let mut pixel_max = 0u8;
        for c in 0..3 {
            let (va, vb) = (a.0[c], b.0[c]);
            let steps = va.abs_diff(vb);
            pixel_max = pixel_max.max(steps);
            sum_sq_srgb += (f64::from(steps) / 255.0).powi(2);
            sum_sq_linear += (to_linear[usize::from(va)] - to_linear[usize::from(vb)]).powi(2);
        }
        max_abs_steps = max_abs_steps.max(pixel_max);
        if pixel_max > 1 {
            beyond_one_step_px += 1;
        }
        if pixel_max > VISIBLE_THRESHOLD {
            visible_px += 1;
        }
    }
    let values = (reference.as_raw().len() as f64).max(1.0);
    PixelStatistics {
        mse_srgb: sum_sq_srgb / values,
        mse_linear: sum_sq_linear / values,
        max_abs_steps,
        beyond_one_step_px,
        visible_px,
    }
}

/// The sRGB decoding function (IEC 61966-2-1), `encoded` in [0, 1].
pub fn srgb_to_linear(encoded: f64) -> f64 {
    if encoded <= 0.04045 {
        encoded / 12.92
    } else {
        ((encoded + 0.055) / 1.055).powf(2.4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4x4 image with varied content, so that FLIP and SSIM see some structure.
    fn base() -> RgbImage {
        RgbImage::from_fn(4, 4, |x, y| {
            image::Rgb([0, (x * 60) as u8, (y * 70 + 10) as u8])
        })
    }

    /// The textbook sRGB decoding, written out again for the expected values.
    fn linear(v: u8) -> f64 {
        let c = f64::from(v) / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    }

    #[test]
    fn identical_images_have_no_error() {
        let a = base();
        let c = compare(&a, &a.clone()).unwrap();
        let m = &c.metrics;
        for (name, v) in [
            ("flip_mean", m.flip_mean),
            ("flip_weighted_median", m.flip_weighted_median),
            ("flip_q1", m.flip_q1),
            ("flip_q3", m.flip_q3),
            ("flip_max", m.flip_max),
            ("rmse_linear", m.rmse_linear),
            ("rmse_srgb", m.rmse_srgb),
            ("max_abs_srgb", m.max_abs_srgb),
            ("beyond_one_step_share", m.beyond_one_step_share),
            ("visible_share", m.visible_share),
        ] {
            assert_eq!(v, 0.0, "{name}");
        }
        assert_eq!(m.psnr_srgb_db, f64::INFINITY);
        assert_eq!(m.psnr_linear_db, f64::INFINITY);
        assert_eq!(m.ssim, 1.0);
        assert_eq!(c.flip_map, vec![0.0; 16]);
        assert_eq!((c.width, c.height), (4, 4));
        let json = serde_json::to_value(m).unwrap();
        assert!(json["psnr_srgb_db"].is_null() && json["psnr_linear_db"].is_null());
        assert_eq!(json["rmse_srgb"], 0.0);
        // All-zero error draws as the LUT's first entry everywhere.
        let heat = flip_heatmap(&c);
        assert!(heat.pixels().all(|p| p == heat.get_pixel(0, 0)));
    }

    #[test]
    fn skipping_ssim_changes_nothing_else() {
        let a = base();
        let mut b = a.clone();
        b.get_pixel_mut(1, 1).0[1] = 200;
        let with = compare(&a, &b).unwrap();
        let without = compare_with(&a, &b, Ssim::Skip).unwrap();
        assert!(with.metrics.ssim < 1.0 && without.metrics.ssim.is_nan());
        let json = serde_json::to_value(&without.metrics).unwrap();
        assert!(json["ssim"].is_null(), "{json}");
        assert_eq!(
            Metrics {
                ssim: 0.0,
                ..with.metrics
            },
            Metrics {
                ssim: 0.0,
                ..without.metrics
            }
        );
        assert_eq!(with.flip_map, without.flip_map);
    }

    #[test]
    fn a_known_difference_gives_hand_computed_metrics() {
        let a = base();
        let mut b = a.clone();
        // Three pixels: red 0 -> 51 (0.2, visible). One pixel: blue +3 (not over the threshold).
        for (x, y) in [(0, 0), (1, 2), (3, 3)] {
            b.get_pixel_mut(x, y).0[0] = 51;
        }
        let blue = a.get_pixel(2, 1).0[2];
        b.get_pixel_mut(2, 1).0[2] = blue + 3;

        let m = compare(&a, &b).unwrap().metrics;
        let values = 4.0 * 4.0 * 3.0;
        let mse_srgb = (3.0 * 0.2f64.powi(2) + (3.0f64 / 255.0).powi(2)) / values;
        let lin_51 = ((0.2f64 + 0.055) / 1.055).powf(2.4);
        let mse_linear =
            (3.0 * lin_51.powi(2) + (linear(blue + 3) - linear(blue)).powi(2)) / values;
        let close = |got: f64, want: f64| (got - want).abs() < 1e-12 * want.abs().max(1.0);
        assert!(close(m.rmse_srgb, mse_srgb.sqrt()), "{m:?}");
        assert!(
            close(m.psnr_srgb_db, 10.0 * (1.0 / mse_srgb).log10()),
            "{m:?}"
        );
        assert!(close(m.rmse_linear, mse_linear.sqrt()), "{m:?}");
        assert!(close(m.psnr_linear_db, -10.0 * mse_linear.log10()), "{m:?}");
        assert!(close(m.max_abs_srgb, 0.2), "{m:?}");
        assert_eq!(m.visible_share, 3.0 / 16.0);
        // The blue +3 pixel is beyond one step too, though not visible.
        assert_eq!(m.beyond_one_step_share, 4.0 / 16.0);
        assert!(m.flip_mean > 0.0 && m.flip_max >= m.flip_q3, "{m:?}");
        assert!(m.flip_q3 >= m.flip_weighted_median && m.flip_weighted_median >= m.flip_q1);
        assert!(m.ssim < 1.0, "{m:?}");
        // sRGB PSNR by hand for the three red pixels alone: MSE = 3 * 0.04 / 48 = 0.0025,
        // PSNR = 10 log10(400) = 26.02 dB; the +3 blue step lowers it a little.
        assert!(m.psnr_srgb_db < 26.0206 && m.psnr_srgb_db > 26.0, "{m:?}");
    }

    #[test]
    fn enhanced_difference_scales_and_clamps() {
        let a = RgbImage::from_raw(2, 1, vec![0, 100, 255, 10, 10, 10]).unwrap();
        let b = RgbImage::from_raw(2, 1, vec![51, 90, 0, 10, 11, 13]).unwrap();
        let d = enhanced_difference(&a, &b, DEFAULT_ENHANCE);
        // |a-b| = 51, 10, 255 | 0, 1, 3  -> x4 = 204, 40, 1020 -> 255 | 0, 4, 12
        assert_eq!(d.as_raw(), &vec![204, 40, 255, 0, 4, 12]);
        let d = enhanced_difference(&a, &b, 2.5);
        // 127.5 -> 128 (round half away from zero), 25, 637.5 -> 255 | 0, 2.5 -> 3, 7.5 -> 8
        assert_eq!(d.as_raw(), &vec![128, 25, 255, 0, 3, 8]);
    }

    #[test]
    fn different_sizes_are_an_error_naming_both() {
        let a = RgbImage::new(1024, 768);
        let b = RgbImage::new(640, 480);
        let err = compare(&a, &b).unwrap_err().to_string();
        assert!(err.contains("1024x768") && err.contains("640x480"), "{err}");
        assert_eq!(err, "reference image is 1024x768 but test image is 640x480");
    }
}
