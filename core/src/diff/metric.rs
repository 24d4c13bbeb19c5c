//! Metric names and pass/fail thresholds: `diff --fail-above METRIC=VALUE`, and later the
//! baselines' tolerances, name a metric of [`Metrics`] by one snake_case word.
//!
//! For error metrics (everything except `psnr` and `ssim`) a threshold fails when the value is
//! **above** it. `psnr` and `ssim` grow as the images get closer, so for them a threshold fails
//! when the value is **below** it. To add a metric: a field in [`Metrics`], a variant here, its
//! row in [`Metric::ALL`] and its arm in [`Metrics::value`].

use std::fmt;
use std::str::FromStr;

use super::Metrics;

/// A metric that a threshold can name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Metric {
    /// `flip`: mean FLIP error ([`Metrics::flip_mean`]).
    Flip,
    /// `flip_q1`: FLIP weighted first quartile ([`Metrics::flip_q1`]).
    FlipQ1,
    /// `flip_median`: FLIP weighted median ([`Metrics::flip_weighted_median`]).
    FlipMedian,
    /// `flip_q3`: FLIP weighted third quartile ([`Metrics::flip_q3`]).
    FlipQ3,
    /// `flip_max`: largest per-pixel FLIP error ([`Metrics::flip_max`]).
    FlipMax,
    /// `rmse`: RMSE of the sRGB values ([`Metrics::rmse_srgb`]).
    Rmse,
    /// `rmse_linear`: RMSE of the linear values ([`Metrics::rmse_linear`]).
    RmseLinear,
    /// `max_abs`: largest channel difference, sRGB ([`Metrics::max_abs_srgb`]).
    MaxAbs,
    /// `beyond_one_step`: share of pixels off by more than 1/255 ([`Metrics::beyond_one_step_share`]).
    BeyondOneStep,
    /// `visible`: share of visibly different pixels ([`Metrics::visible_share`]).
    Visible,
    /// `psnr`: PSNR of the sRGB values in dB ([`Metrics::psnr_srgb_db`]); higher is better.
    Psnr,
    /// `psnr_linear`: PSNR of the linear values in dB ([`Metrics::psnr_linear_db`]); higher is
    /// better.
    PsnrLinear,
    /// `ssim`: structural similarity ([`Metrics::ssim`]); higher is better.
    Ssim,
}

impl Metric {
    /// Every metric with its short name and the field name `--json` prints it under, in the
    /// order they are listed to the user. Thresholds accept either name.
    pub const ALL: [(Metric, &'static str, &'static str); 13] = [
        (Metric::Flip, "flip", "flip_mean"),
        (Metric::FlipQ1, "flip_q1", "flip_q1"),
        (Metric::FlipMedian, "flip_median", "flip_weighted_median"),
        (Metric::FlipQ3, "flip_q3", "flip_q3"),
        (Metric::FlipMax, "flip_max", "flip_max"),
        (Metric::Rmse, "rmse", "rmse_srgb"),
        (Metric::RmseLinear, "rmse_linear", "rmse_linear"),
        (Metric::MaxAbs, "max_abs", "max_abs_srgb"),
        (
            Metric::BeyondOneStep,
            "beyond_one_step",
            "beyond_one_step_share",
        ),
        (Metric::Visible, "visible", "visible_share"),
        (Metric::Psnr, "psnr", "psnr_srgb_db"),
        (Metric::PsnrLinear, "psnr_linear", "psnr_linear_db"),
        (Metric::Ssim, "ssim", "ssim"),
    ];

    /// The short name thresholds use (`flip`, `psnr`, ...).
    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(m, _, _)| *m == self)
            .map_or("?", |(_, name, _)| name)
    }

    /// The valid names, comma separated, for error messages.
    pub fn names() -> String {
        Self::ALL
            .iter()
            .map(|(_, short, json)| {
                if short == json {
                    (*short).to_owned()
                } else {
                    format!("{short} ({json})")
                }
            })
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// True for `psnr` and `ssim`, which grow as the images get closer.
    pub fn higher_is_better(self) -> bool {
        matches!(self, Metric::Psnr | Metric::PsnrLinear | Metric::Ssim)
    }

    /// Whether `value` breaks `threshold`: above it for error metrics, below it for `psnr` and
    /// `ssim`. A value equal to the threshold passes; a NaN value always fails.
    pub fn exceeded(self, value: f64, threshold: f64) -> bool {
        if value.is_nan() {
            true
        } else if self.higher_is_better() {
            value < threshold
        } else {
            value > threshold
        }
    }
}

impl fmt::Display for Metric {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Metric {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let s = s.trim();
        Self::ALL
            .iter()
            .find(|(_, short, json)| *short == s || *json == s)
            .map(|(m, _, _)| *m)
            .ok_or_else(|| {
                format!(
                    "unknown metric \"{s}\": valid metrics are {}",
                    Self::names()
                )
            })
    }
}

impl serde::Serialize for Metric {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}

impl Metrics {
    /// The value a threshold on `metric` is checked against.
    pub fn value(&self, metric: Metric) -> f64 {
        match metric {
            Metric::Flip => self.flip_mean,
            Metric::FlipQ1 => self.flip_q1,
            Metric::FlipMedian => self.flip_weighted_median,
            Metric::FlipQ3 => self.flip_q3,
            Metric::FlipMax => self.flip_max,
            Metric::Rmse => self.rmse_srgb,
            Metric::RmseLinear => self.rmse_linear,
            Metric::MaxAbs => self.max_abs_srgb,
            Metric::BeyondOneStep => self.beyond_one_step_share,
            Metric::Visible => self.visible_share,
            Metric::Psnr => self.psnr_srgb_db,
            Metric::PsnrLinear => self.psnr_linear_db,
            Metric::Ssim => self.ssim,
        }
    }
}

/// Parses `METRIC=VALUE` (e.g. `flip=0.05`, `psnr=40`). The value must be a finite number; an
/// unknown metric gets the list of valid names.
pub fn parse_threshold(s: &str) -> Result<(Metric, f64), String> {
    let (name, value) = s
        .split_once('=')
        .ok_or_else(|| format!("\"{s}\" is not METRIC=VALUE (e.g. flip=0.05)"))?;
    let metric: Metric = name.parse()?;
    let threshold = value
        .trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| {
            format!(
                "threshold \"{}\" in \"{s}\" is not a finite number",
                value.trim()
            )
        })?;
    Ok((metric, threshold))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thresholds_parse_and_bad_ones_say_why() {
        assert_eq!(parse_threshold("flip=0.05"), Ok((Metric::Flip, 0.05)));
        assert_eq!(parse_threshold("psnr=40"), Ok((Metric::Psnr, 40.0)));
        assert_eq!(parse_threshold(" ssim = 0.99 "), Ok((Metric::Ssim, 0.99)));
        for (metric, short, json) in Metric::ALL {
            for name in [short, json] {
                let (m, v) = parse_threshold(&format!("{name}=1e-3")).unwrap();
                assert_eq!((m, v), (metric, 1e-3));
            }
        }
        let err = parse_threshold("flip").unwrap_err();
        assert!(err.contains("METRIC=VALUE"), "{err}");
        let err = parse_threshold("mse=1").unwrap_err();
        assert!(err.contains("\"mse\""), "{err}");
        for (_, short, json) in Metric::ALL {
            assert!(
                err.contains(short) && err.contains(json),
                "{err} lacks {short}"
            );
        }
        let err = parse_threshold("flip=abc").unwrap_err();
        assert!(err.contains("\"abc\"") && err.contains("finite"), "{err}");
        assert!(parse_threshold("flip=inf").is_err());
        assert!(parse_threshold("flip=NaN").is_err());
        assert!(parse_threshold("flip=").is_err());
    }

    #[test]
    fn every_name_the_json_prints_is_a_threshold_name() {
        let metrics = crate::diff::compare(
            &image::RgbImage::from_pixel(8, 8, image::Rgb([10, 20, 30])),
            &image::RgbImage::from_pixel(8, 8, image::Rgb([12, 20, 30])),
        )
        .unwrap()
        .metrics;
        let json = serde_json::to_value(&metrics).unwrap();
        let fields = json.as_object().unwrap();
        assert_eq!(fields.len(), Metric::ALL.len(), "{fields:?}");
        for (field, value) in fields {
            let (metric, _) = parse_threshold(&format!("{field}=0.5"))
                .unwrap_or_else(|e| panic!("--json prints {field}, thresholds say: {e}"));
            // The threshold reads the very value the JSON printed (null: an infinite PSNR).
            let printed = value.as_f64().unwrap_or(f64::INFINITY);
            assert_eq!(metrics.value(metric), printed, "{field}");
        }
    }

    #[test]
    fn higher_is_better_metrics_fail_below_their_threshold() {
        assert!(Metric::Flip.exceeded(0.2, 0.1));
        assert!(!Metric::Flip.exceeded(0.1, 0.1));
        assert!(!Metric::Flip.exceeded(0.05, 0.1));
        assert!(Metric::Psnr.exceeded(30.0, 40.0));
        assert!(!Metric::Psnr.exceeded(50.0, 40.0));
        assert!(!Metric::Psnr.exceeded(f64::INFINITY, 40.0));
        assert!(Metric::Ssim.exceeded(0.9, 0.95));
        assert!(!Metric::Ssim.exceeded(1.0, 0.95));
        assert!(Metric::Rmse.exceeded(f64::NAN, 1.0));
        assert!(Metric::Ssim.exceeded(f64::NAN, 0.0));
    }
}
