//! LDR-FLIP (Andersson et al., "FLIP: A Difference Evaluator for Alternating Images", 2020) in
//! Rust, with no C++ and no threads required: the error map of a test image against a
//! reference, both 8-bit sRGB, at a viewing distance of `ppd` pixels per degree.
//!
//! The two pipelines of the paper, as NVIDIA's reference code runs them (separable filters
//! with clamped edges, single floats):
//! - **colour**: sRGB → linear → XYZ → YCxCz; each channel filtered by the contrast
//!   sensitivity of its channel (a Gaussian for Y and Cx, a sum of two for Cz, separated into
//!   two row and column passes); back to linear RGB, clamped to [0, 1]; CIELab with the Hunt
//!   adjustment of a and b; the HyAB distance, raised to 0.7 and remapped so that a fraction
//!   `pc` of the largest distance (green against blue) maps to `pt`;
//! - **features**: the achromatic channel normalised to [0, 1], filtered with a Gaussian's
//!   first and second derivatives (edges and points, σ = 0.5 · 0.082 · ppd); the larger of the
//!   edge and point differences, over √2, raised to 0.5;
//! - the pixel's error: colour^(1 − feature).
//!
//! It is the FLIP every command reports ([`super::compare`], with [`Pool`]'s mean and weighted
//! quartiles). `tests/diff.rs` holds it to `nv-flip` (NVIDIA's C++ reference code) on every
//! committed baseline pair: the mean within 1e-4 and the quartiles within 1e-3 (worst seen:
//! 1.2e-5 and 1.8e-4 over 39 pairs, December 2026).

use image::RgbImage;

/// Pixels per degree of visual angle the comparisons assume: a 0.7 m wide 4K monitor seen from
/// 0.7 m (the paper's default, `nv_flip::DEFAULT_PIXELS_PER_DEGREE`).
pub const DEFAULT_PPD: f32 = 67.0;

const QC: f32 = 0.7;
const PC: f32 = 0.4;
const PT: f32 = 0.95;
const W: f32 = 0.082;
const QF: f32 = 0.5;
use std::f32::consts::PI;

/// The contrast sensitivity Gaussians' amplitudes and scales per channel (Y, Cx, Cz), and Cz's
/// second one.
const A1: [f32; 3] = [1.0, 1.0, 34.1];
const B1: [f32; 3] = [0.0047, 0.0053, 0.04];
const A2_CZ: f32 = 13.5;
const B2_CZ: f32 = 0.025;
/// The largest scale among the Gaussians (the filters' radius follows from it); the second
/// Gaussians of Y and Cx are zero with scale 1e-5.
const MAX_SCALE: f32 = 0.04;

/// The D65 white and its inverse.
const WHITE: [f32; 3] = [0.950_428_5, 1.0, 1.088_900_4];
const INV_WHITE: [f32; 3] = [1.052_156_9, 1.0, 0.918_357_7];

type Rgb = [f32; 3];

fn linear_to_xyz([r, g, b]: Rgb) -> Rgb {
    [
        (10_135_552.0 / 24_577_794.0) * r
            + (8_788_810.0 / 24_577_794.0) * g
            + (4_435_075.0 / 24_577_794.0) * b,
        (2_613_072.0 / 12_288_897.0) * r
            + (8_788_810.0 / 12_288_897.0) * g
            + (887_015.0 / 12_288_897.0) * b,
        (1_425_312.0 / 73_733_382.0) * r
            + (8_788_810.0 / 73_733_382.0) * g
            + (70_074_185.0 / 73_733_382.0) * b,
    ]
}

fn xyz_to_linear([x, y, z]: Rgb) -> Rgb {
    [
        3.241_003_3 * x - 1.537_398_9 * y - 0.498_615_86 * z,
        -0.969_224_3 * x + 1.875_930_1 * y + 0.041_554_224 * z,
        0.055_639_423 * x - 0.204_011_2 * y + 1.057_148_9 * z,
    ]
}

fn xyz_to_ycxcz(xyz: Rgb) -> Rgb {
    let [x, y, z] = [0, 1, 2].map(|i| xyz[i] * INV_WHITE[i]);
    [116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z)]
}

fn ycxcz_to_xyz([l, cx, cz]: Rgb) -> Rgb {
    let y = (l + 16.0) / 116.0;
    let xyz = [y + cx / 500.0, y, y - cz / 200.0];
    [0, 1, 2].map(|i| xyz[i] * WHITE[i])
}

fn xyz_to_lab(xyz: Rgb) -> Rgb {
    let delta = 6.0f32 / 29.0;
    let cube = delta * delta * delta;
    let factor = 1.0 / (3.0 * delta * delta);
    let term = 4.0f32 / 29.0;
    let f = |v: f32| match v > cube {
        true => v.powf(1.0 / 3.0),
        false => factor * v + term,
    };
    let [x, y, z] = [0, 1, 2].map(|i| f(xyz[i] * INV_WHITE[i]));
    [116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z)]
}

/// CIELab with a and b Hunt-adjusted (scaled by L / 100).
fn hunt_lab(linear: Rgb) -> Rgb {
    let [l, a, b] = xyz_to_lab(linear_to_xyz(linear));
    [l, 0.01 * l * a, 0.01 * l * b]
}

fn hyab(a: Rgb, b: Rgb) -> f32 {
    (a[0] - b[0]).abs() + ((a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// The Gaussian in the paper's form, a √(π/b) e^(−π² x² / b), and its square root's (the
/// separable half of a 2D sum of Gaussians).
fn gaussian(x2: f32, a: f32, b: f32) -> f32 {
    a * (PI / b).sqrt() * (-PI * PI * x2 / b).exp()
}

fn gaussian_sqrt(x2: f32, a: f32, b: f32) -> f32 {
    (a * (PI / b).sqrt()).sqrt() * (-PI * PI * x2 / b).exp()
}

/// The colour pipeline's 1D filters: (Y, Cx) normalised to sum 1, and Cz's two Gaussians
/// normalised together.
fn spatial_filters(ppd: f32) -> (Vec<[f32; 2]>, Vec<[f32; 2]>) {
    let radius = (3.0 * (MAX_SCALE / (2.0 * PI * PI)).sqrt() * ppd).ceil() as i32;
    let dx = 1.0 / ppd;
    let (mut ycx, mut cz) = (Vec::new(), Vec::new());
    for i in -radius..=radius {
        let x = i as f32 * dx;
        let x2 = x * x;
        ycx.push([gaussian(x2, A1[0], B1[0]), gaussian(x2, A1[1], B1[1])]);
        cz.push([
            gaussian_sqrt(x2, A1[2], B1[2]),
            gaussian_sqrt(x2, A2_CZ, B2_CZ),
        ]);
    }
    let sum = |v: &[[f32; 2]], k: usize| v.iter().map(|w| w[k]).sum::<f32>();
    let (sy, scx) = (sum(&ycx, 0), sum(&ycx, 1));
    let norm_cz = 1.0 / (sum(&cz, 0).powi(2) + sum(&cz, 1).powi(2)).sqrt();
    for w in &mut ycx {
        *w = [w[0] / sy, w[1] / scx];
    }
    for w in &mut cz {
        *w = [w[0] * norm_cz, w[1] * norm_cz];
    }
    (ycx, cz)
}

/// The feature pipeline's 1D filter: a Gaussian (sum 1), its first derivative and its second
/// (positive and negative weights each summing to ±1).
fn feature_filter(ppd: f32) -> Vec<[f32; 3]> {
    let sd = 0.5 * W * ppd;
    let radius = (3.0 * sd).ceil() as i32;
    let raw: Vec<[f32; 3]> = (-radius..=radius)
        .map(|i| {
            let x = i as f32;
            let g = (-(x * x) / (2.0 * sd * sd)).exp();
            [g, -x * g, (x * x / (sd * sd) - 1.0) * g]
        })
        .collect();
    let g_sum: f32 = raw.iter().map(|w| w[0]).sum();
    let parts = |k: usize| {
        raw.iter()
            .fold((0.0f32, 0.0f32), |(pos, neg), w| match w[k] > 0.0 {
                true => (pos + w[k], neg),
                false => (pos, neg - w[k]),
            })
    };
    let (d_pos, d_neg) = parts(1);
    let (dd_pos, dd_neg) = parts(2);
    raw.iter()
        .map(|w| {
            [
                w[0] / g_sum,
                w[1] / if w[1] > 0.0 { d_pos } else { d_neg },
                w[2] / if w[2] > 0.0 { dd_pos } else { dd_neg },
            ]
        })
        .collect()
}

/// An image's pixels in YCxCz.
fn to_ycxcz(image: &RgbImage) -> Vec<Rgb> {
    let decode: [f32; 256] = std::array::from_fn(|v| {
        let s = v as f32 / 255.0;
        match s <= 0.04045 {
            true => s / 12.92,
            false => ((s + 0.055) / 1.055).powf(2.4),
        }
    });
    image
        .pixels()
        .map(|p| xyz_to_ycxcz(linear_to_xyz(p.0.map(|c| decode[c as usize]))))
        .collect()
}

/// Convolves the rows (`along_x`) or the columns of a `w` x `h` field with the 1D `filter`
/// through `tap` (which accumulates the weighted sample into the output), clamping at the
/// edges.
fn convolve<T: Copy + Default + Send, F: Copy + Sync, S: Copy + Sync>(
    input: &[S],
    (w, h): (usize, usize),
    filter: &[F],
    along_x: bool,
    tap: impl Fn(&mut T, F, S) + Sync,
) -> Vec<T> {
    let r = (filter.len() / 2) as isize;
    let row = |y: usize| -> Vec<T> {
        (0..w)
            .map(|x| {
                let mut acc = T::default();
                for (k, &f) in filter.iter().enumerate() {
                    let o = k as isize - r;
                    let i = match along_x {
                        true => y * w + (x as isize + o).clamp(0, w as isize - 1) as usize,
                        false => (y as isize + o).clamp(0, h as isize - 1) as usize * w + x,
                    };
                    tap(&mut acc, f, input[i]);
                }
                acc
            })
            .collect()
    };
    // Where no thread can start (the web), rayon runs the rows on the calling thread.
    use rayon::prelude::*;
    (0..h).into_par_iter().flat_map_iter(row).collect()
}

/// The FLIP error of each pixel of `test` against `reference` (the same size), row-major.
pub fn flip_map(reference: &RgbImage, test: &RgbImage, ppd: f32) -> Vec<f32> {
    let size = (reference.width() as usize, reference.height() as usize);
    let (r, t) = (to_ycxcz(reference), to_ycxcz(test));
    let pair: Vec<(Rgb, Rgb)> = r.iter().copied().zip(t.iter().copied()).collect();

    // Colour: filter both images' channels, rows then columns.
    let (ycx, cz) = spatial_filters(ppd);
    let filters: Vec<([f32; 2], [f32; 2])> = ycx.iter().copied().zip(cz.iter().copied()).collect();
    type Acc = ([f32; 4], [f32; 4]);
    let add = |acc: &mut Acc, (wy, wz): ([f32; 2], [f32; 2]), v: [Rgb; 2]| {
        for (k, c) in v.iter().enumerate() {
            acc.0[2 * k] += wy[0] * c[0];
            acc.0[2 * k + 1] += wy[1] * c[1];
            acc.1[2 * k] += wz[0] * c[2];
            acc.1[2 * k + 1] += wz[1] * c[2];
        }
    };
    let rows: Vec<Acc> = convolve(
        &pair,
        size,
        &filters,
        true,
        |acc: &mut Acc, f, (a, b): (Rgb, Rgb)| add(acc, f, [a, b]),
    );
    let cols: Vec<Acc> = convolve(
        &rows,
        size,
        &filters,
        false,
        |acc: &mut Acc, (wy, wz), v: Acc| {
            for k in 0..2 {
                acc.0[2 * k] += wy[0] * v.0[2 * k];
                acc.0[2 * k + 1] += wy[1] * v.0[2 * k + 1];
                acc.1[2 * k] += wz[0] * v.1[2 * k];
                acc.1[2 * k + 1] += wz[1] * v.1[2 * k + 1];
            }
        },
    );
    let cmax = {
        let (g, b) = (hunt_lab([0.0, 1.0, 0.0]), hunt_lab([0.0, 0.0, 1.0]));
        hyab(g, b).powf(QC)
    };
    let pccmax = PC * cmax;
    let colour: Vec<f32> = cols
        .iter()
        .map(|(ycx, cz)| {
            let lab = |k: usize| {
                let ycxcz = [ycx[2 * k], ycx[2 * k + 1], cz[2 * k] + cz[2 * k + 1]];
                let linear = xyz_to_linear(ycxcz_to_xyz(ycxcz)).map(|c| c.clamp(0.0, 1.0));
                hunt_lab(linear)
            };
            let d = hyab(lab(0), lab(1)).powf(QC);
            match d < pccmax {
                true => d * (PT / pccmax),
                false => PT + ((d - pccmax) / (cmax - pccmax)) * (1.0 - PT),
            }
        })
        .collect();

    // Features: edges and points of the normalised achromatic channel.
    let feature = feature_filter(ppd);
    let gray: Vec<[f32; 2]> = pair
        .iter()
        .map(|(a, b)| [a[0], b[0]].map(|y| y * (1.0 / 116.0) + 16.0 / 116.0))
        .collect();
    // Per image: (d/dx, d²/dx², Gaussian) along the rows.
    type Rows = [[f32; 3]; 2];
    let rows: Vec<Rows> = convolve(
        &gray,
        size,
        &feature,
        true,
        |acc: &mut Rows, f, g: [f32; 2]| {
            for k in 0..2 {
                acc[k][0] += f[1] * g[k];
                acc[k][1] += f[2] * g[k];
                acc[k][2] += f[0] * g[k];
            }
        },
    );
    // Per image: (dx, ddx, dy, ddy) after the columns.
    type Cols = [[f32; 4]; 2];
    let cols: Vec<Cols> = convolve(
        &rows,
        size,
        &feature,
        false,
        |acc: &mut Cols, f, v: Rows| {
            for k in 0..2 {
                acc[k][0] += f[0] * v[k][0];
                acc[k][1] += f[0] * v[k][1];
                acc[k][2] += f[1] * v[k][2];
                acc[k][3] += f[2] * v[k][2];
            }
        },
    );
    cols.iter()
        .zip(colour)
        .map(|(c, colour)| {
            let edge = |k: usize| (c[k][0] * c[k][0] + c[k][2] * c[k][2]).sqrt();
            let point = |k: usize| (c[k][1] * c[k][1] + c[k][3] * c[k][3]).sqrt();
            let difference = (edge(0) - edge(1)).abs().max((point(0) - point(1)).abs());
            let feature = ((1.0 / 2.0f32.sqrt()) * difference).powf(QF);
            colour.powf(1.0 - feature)
        })
        .collect()
}

/// The pooled figures of an error map, as FLIP's pool computes them: the mean, and weighted
/// percentiles (the error below which a share of the summed error lies).
pub struct Pool {
    sorted: Vec<f32>,
    sum: f64,
}

impl Pool {
    /// The pool of `map`'s errors.
    pub fn of(map: &[f32]) -> Self {
        let mut sorted = map.to_vec();
        sorted.sort_by(f32::total_cmp);
        let sum = sorted.iter().map(|&v| f64::from(v)).sum();
        Self { sorted, sum }
    }

    /// The mean error (0 for an empty map).
    pub fn mean(&self) -> f64 {
        match self.sorted.is_empty() {
            true => 0.0,
            false => self.sum / self.sorted.len() as f64,
        }
    }

    /// The smallest error at which the running sum of the sorted errors first exceeds `share`
    /// of their sum (FLIP's `getPercentile(share, weighted = true)`); 0 when there is none.
    pub fn weighted_percentile(&self, share: f64) -> f64 {
        let target = share * self.sum;
        let mut running = 0.0;
        for &v in &self.sorted {
            running += f64::from(v);
            if running > target {
                return f64::from(v);
            }
        }
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weighted_percentiles_split_the_summed_error() {
        // Errors 1, 2, 3, 4 sum to 10: the running sums 1, 3, 6, 10 first pass 2.5 at 2, 5 at
        // 3, 7.5 at 4.
        let pool = Pool::of(&[4.0, 1.0, 3.0, 2.0]);
        assert_eq!(pool.mean(), 2.5);
        assert_eq!(pool.weighted_percentile(0.25), 2.0);
        assert_eq!(pool.weighted_percentile(0.5), 3.0);
        assert_eq!(pool.weighted_percentile(0.75), 4.0);
        assert_eq!(Pool::of(&[0.0; 5]).weighted_percentile(0.5), 0.0);
    }

    #[test]
    fn identical_images_have_no_error_and_green_against_blue_the_most() {
        let a = RgbImage::from_fn(16, 12, |x, y| image::Rgb([x as u8 * 9, y as u8 * 13, 77]));
        assert!(flip_map(&a, &a, DEFAULT_PPD).iter().all(|&e| e == 0.0));
        let green = RgbImage::from_pixel(40, 40, image::Rgb([0, 255, 0]));
        let blue = RgbImage::from_pixel(40, 40, image::Rgb([0, 0, 255]));
        // Flat fields: no features, and the colour distance is the largest there is (1).
        let e = flip_map(&green, &blue, DEFAULT_PPD);
        assert!(e.iter().all(|&v| (v - 1.0).abs() < 1e-4), "{:?}", &e[..4]);
    }

    #[test]
    fn the_filters_are_normalised_as_the_paper_says() {
        let (ycx, cz) = spatial_filters(DEFAULT_PPD);
        assert_eq!(ycx.len() % 2, 1);
        for k in 0..2 {
            let s: f32 = ycx.iter().map(|w| w[k]).sum();
            assert!((s - 1.0).abs() < 1e-5);
        }
        let (a, b): (f32, f32) = (cz.iter().map(|w| w[0]).sum(), cz.iter().map(|w| w[1]).sum());
        assert!((a * a + b * b - 1.0).abs() < 1e-5);
        let f = feature_filter(DEFAULT_PPD);
        let (pos, neg): (f32, f32) =
            f.iter().map(|w| w[1]).fold(
                (0.0, 0.0),
                |(p, n), v| if v > 0.0 { (p + v, n) } else { (p, n + v) },
            );
        assert!((pos - 1.0).abs() < 1e-5 && (neg + 1.0).abs() < 1e-5);
    }
}
