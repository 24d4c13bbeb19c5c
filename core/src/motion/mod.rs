//! Smoke that moves: the span of consecutive frames an animated sweep renders
//! (`smokeshadow sweep --animate START..END --fps F`) and what it measures of a technique over
//! them against `exact` rendered at the same times.
//!
//! The thesis shows each technique "after a wind effect", and its sources name artifacts that
//! only show in motion: opacity-map slices that particles cross pop, a deep opacity map's
//! per-texel start depth jumps when the nearest particle changes, a tightly fitted light
//! frustum shimmers as the smoke's bounds change. A still frame's error does not see them. So
//! every measure here compares a technique's *change* from one frame to the next with the
//! reference's change over the same two frames: a technique wrong by the same amount in every
//! frame scores 0, one whose error jumps about does not.
//!
//! - `temporal_error`: over the frame pairs, the mean of the per-pixel
//!   |(I_t − I_t−1) − (R_t − R_t−1)| on linear luminance (I the technique's frame, R `exact`'s);
//! - `temporal_p999`: the 99.9th percentile of that per pair, its mean over the pairs, and its
//!   worst pair (`temporal_p999_worst`): a few pixels that jump;
//! - `pops_per_frame`: pixels whose change is visible (the sRGB-encoded luminance moves by
//!   more than [`POP_THRESHOLD`], `diff`'s "visible" 3/255) where `exact`'s is not, per pair;
//! - `t_temporal_error`, `t_temporal_p999`: the same on the shadow's transmittance at the
//!   frame's shaded points (the particles' lighting points, the lit ground), so the shadow's
//!   flicker is told apart from the image's;
//! - `frame_error`: the still measure on the same frames, mean |I − R|, for the two rankings
//!   side by side; `flip_median`, `flip_p95`, `flip_std`: the per-frame FLIP against `exact`
//!   over the span.
//!
//! A new measure is a field of [`Motion`] computed in [`Recorder`], a `results.csv` column
//! (`sweep::CSV_COLUMNS`) and a row of docs/sweeps.md's table of them.

use image::RgbImage;
use serde::{Deserialize, Serialize};

/// The most frames a span may have: the reference's frames are held in memory while every
/// cell is rendered over them.
pub const MAX_FRAMES: usize = 240;
/// Frames per second of a span when none is given (and the scene's particles are no sequence).
pub const DEFAULT_FPS: f32 = 30.0;
/// The frame rate of a span over `scene` when none is given: its particle or volume
/// sequence's own, else [`DEFAULT_FPS`].
pub fn default_fps(scene: &crate::scene::Scene) -> f32 {
    scene.sequence_rate_hz().unwrap_or(DEFAULT_FPS)
}

/// A change of the sRGB-encoded luminance larger than this is visible: `diff`'s threshold of
/// 3 8-bit steps ([`crate::diff::VISIBLE_THRESHOLD`]).
pub const POP_THRESHOLD: f32 = crate::diff::VISIBLE_THRESHOLD as f32 / 255.0;
/// The tail the `*_p999` measures give.
pub const TAIL_QUANTILE: f64 = 0.999;

/// Consecutive frames 1/`fps` apart from `start_s`, the last within half a frame of `end_s`
/// (scene time, the scene's `sim.duration_s` at each).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Span {
    pub start_s: f32,
    pub end_s: f32,
    pub fps: f32,
    /// Degrees the camera turns about the vertical through its target over the span (0: it
    /// stays): a view that turns reorders every build's draw order ([`Span::camera_at`]).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub orbit_deg: f32,
    /// Degrees the light turns about the vertical through its target over the span (0: it
    /// stays): every map's frustum, slices and texels move with it ([`Span::light_at`]).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub light_orbit_deg: f32,
}

/// `degrees` of a turn over a span, checked (finite, at most 360 in size); `flag` names it.
fn turn_degrees(flag: &str, degrees: f32) -> Result<f32, String> {
    match degrees.is_finite() && degrees.abs() <= 360.0 {
        true => Ok(degrees),
        false => Err(format!(
            "{flag} {degrees} is out of range: allowed -360..=360 degrees"
        )),
    }
}

fn is_zero(v: &f32) -> bool {
    *v == 0.0
}

impl Span {
    /// A span, checked: 0 <= `start_s` < `end_s` <= 600 (the scene clock's range), `fps` in
    /// (0, 240], 2 to [`MAX_FRAMES`] frames.
    pub fn new(start_s: f32, end_s: f32, fps: f32) -> Result<Self, String> {
        if !(fps.is_finite() && fps > 0.0 && fps <= 240.0) {
            return Err(format!("--fps {fps} is out of range: allowed (0, 240]"));
        }
        if !(start_s.is_finite() && end_s.is_finite() && start_s >= 0.0 && end_s <= 600.0) {
            return Err(format!(
                "--animate {start_s}..{end_s} is out of range: times in seconds within 0..600"
            ));
        }
        if end_s <= start_s {
            return Err(format!(
                "--animate {start_s}..{end_s}: the end must come after the start"
            ));
        }
        let span = Self {
            start_s,
            end_s,
            fps,
            orbit_deg: 0.0,
            light_orbit_deg: 0.0,
        };
        let frames = span.frames();
        if frames < 2 {
            return Err(format!(
                "--animate {start_s}..{end_s} at {fps} fps is {frames} frame: give a span of at least two frames (1/{fps} s apart)"
            ));
        }
        if frames > MAX_FRAMES {
            return Err(format!(
                "--animate {start_s}..{end_s} at {fps} fps is {frames} frames: at most {MAX_FRAMES} (a shorter span or a lower --fps)"
            ));
        }
        Ok(span)
    }

    /// The span with the camera turning by `degrees` over it, checked: finite, at most 360 in
    /// size.
    pub fn with_orbit(self, degrees: f32) -> Result<Self, String> {
        Ok(Self {
            orbit_deg: turn_degrees("--orbit", degrees)?,
            ..self
        })
    }

    /// The span with the light turning by `degrees` over it, checked as [`Span::with_orbit`].
    pub fn with_light_orbit(self, degrees: f32) -> Result<Self, String> {
        Ok(Self {
            light_orbit_deg: turn_degrees("--light-orbit", degrees)?,
            ..self
        })
    }

    /// The turn about the vertical by `degrees` times the share of the span run at `time_s`.
    fn turn_at(&self, degrees: f32, time_s: f32) -> glam::Quat {
        let last = self.times().last().copied().unwrap_or(self.end_s);
        let share = ((time_s - self.start_s) / (last - self.start_s).max(f32::MIN_POSITIVE))
            .clamp(0.0, 1.0);
        glam::Quat::from_rotation_y((degrees * share).to_radians())
    }

    /// The scene as the span's frame at `time_s` shows it: at that time, its camera and light
    /// turned by their orbits' shares ([`Span::camera_at`], [`Span::light_at`]).
    pub fn scene_at(&self, scene: &crate::scene::Scene, time_s: f32) -> crate::scene::Scene {
        let mut at = scene.at_time(time_s);
        at.camera = self.camera_at(&scene.camera, time_s);
        at.light = self.light_at(&scene.light, time_s);
        at
    }

    /// The camera at frame time `time_s`: `camera` turned about the vertical through its
    /// target by the share of [`Span::orbit_deg`] the span has run by then.
    pub fn camera_at(&self, camera: &crate::scene::Camera, time_s: f32) -> crate::scene::Camera {
        let turn = self.turn_at(self.orbit_deg, time_s);
        crate::scene::Camera {
            position: camera.target + turn * (camera.position - camera.target),
            ..camera.clone()
        }
    }

    /// The light at frame time `time_s`: `light` turned about the vertical through its target
    /// by the share of [`Span::light_orbit_deg`] the span has run by then.
    pub fn light_at(
        &self,
        light: &crate::scene::Spotlight,
        time_s: f32,
    ) -> crate::scene::Spotlight {
        let turn = self.turn_at(self.light_orbit_deg, time_s);
        crate::scene::Spotlight {
            position: light.target + turn * (light.position - light.target),
            ..light.clone()
        }
    }

    /// Parses `START..END` (seconds) at `fps`.
    pub fn parse(range: &str, fps: f32) -> Result<Self, String> {
        let (a, b) = range.split_once("..").ok_or_else(|| {
            format!("--animate \"{range}\" is not START..END (seconds, e.g. 7.1..7.87)")
        })?;
        let number = |s: &str| {
            s.trim().parse::<f32>().map_err(|_| {
                format!(
                    "--animate \"{range}\": \"{}\" is not a number of seconds",
                    s.trim()
                )
            })
        };
        Self::new(number(a)?, number(b)?, fps)
    }

    /// How many frames it has.
    pub fn frames(&self) -> usize {
        ((f64::from(self.end_s) - f64::from(self.start_s)) * f64::from(self.fps)).round() as usize
            + 1
    }

    /// The scene time of each frame, seconds.
    pub fn times(&self) -> Vec<f32> {
        (0..self.frames())
            .map(|k| (f64::from(self.start_s) + k as f64 / f64::from(self.fps)) as f32)
            .collect()
    }

    /// "24 frames at 30 fps, t = 7.1 .. 7.87 s".
    pub fn describe(&self) -> String {
        let times = self.times();
        // Milliseconds: a frame time 1/30 s after a round start is not round in f32.
        let ms = |t: f32| (f64::from(t) * 1e3).round() / 1e3;
        let mut orbit = match self.orbit_deg {
            0.0 => String::new(),
            deg => format!(", the camera turning {deg}°"),
        };
        if self.light_orbit_deg != 0.0 {
            orbit.push_str(&format!(", the light turning {}°", self.light_orbit_deg));
        }
        format!(
            "{} frames at {} fps, t = {} .. {} s{orbit}",
            times.len(),
            self.fps,
            ms(self.start_s),
            ms(times.last().copied().unwrap_or(self.start_s))
        )
    }
}

/// The sRGB decoding of each 8-bit value.
fn decode_table() -> [f32; 256] {
    std::array::from_fn(|v| crate::diff::srgb_to_linear(v as f64 / 255.0) as f32)
}

/// The sRGB encoding (IEC 61966-2-1) of a linear value in [0, 1].
fn srgb_encode(linear: f32) -> f32 {
    let l = linear.clamp(0.0, 1.0);
    if l <= 0.003_130_8 {
        l * 12.92
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    }
}

/// Each pixel's linear luminance (Rec. 709 weights of the sRGB-decoded channels): what the
/// temporal measures compare.
pub fn linear_luminance(image: &RgbImage) -> Vec<f32> {
    let table = decode_table();
    image
        .pixels()
        .map(|p| {
            0.2126 * table[p[0] as usize]
                + 0.7152 * table[p[1] as usize]
                + 0.0722 * table[p[2] as usize]
        })
        .collect()
}

/// What one frame gives the measures: its luminance and the shadow's transmittance at its
/// shaded points.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameSample {
    /// Linear luminance per pixel ([`linear_luminance`]).
    pub luminance: Vec<f32>,
    /// T at the frame's points.
    pub transmittance: Vec<f32>,
    /// How many of the first points are the same in every frame of the span (the lit ground's;
    /// the particles' lighting points follow them, comparable between two frames only when the
    /// frames have as many points).
    pub fixed_points: usize,
}

impl FrameSample {
    /// Bytes it holds.
    pub fn bytes(&self) -> u64 {
        4 * (self.luminance.len() + self.transmittance.len()) as u64
    }
}

/// How far a frame pair's changes are apart: the mean and the [`TAIL_QUANTILE`] of
/// |(a1 − a0) − (b1 − b0)| over the values.
fn change_difference(a0: &[f32], a1: &[f32], b0: &[f32], b1: &[f32]) -> (f64, f64) {
    let mut d: Vec<f32> = a0
        .iter()
        .zip(a1)
        .zip(b0.iter().zip(b1))
        .map(|((a0, a1), (b0, b1))| ((a1 - a0) - (b1 - b0)).abs())
        .collect();
    if d.is_empty() {
        return (0.0, 0.0);
    }
    let mean = d.iter().map(|&v| f64::from(v)).sum::<f64>() / d.len() as f64;
    (mean, f64::from(quantile(&mut d, TAIL_QUANTILE)))
}

/// The mean of |a − b| over the values (a frame's still error, a frame pair's own change).
fn mean_abs_difference(a: &[f32], b: &[f32]) -> f64 {
    if a.is_empty() {
        return 0.0;
    }
    a.iter()
        .zip(b)
        .map(|(a, b)| f64::from((a - b).abs()))
        .sum::<f64>()
        / a.len() as f64
}

/// The nearest-rank `q` quantile of `values` (reordered).
fn quantile(values: &mut [f32], q: f64) -> f32 {
    *values
        .select_nth_unstable_by(nearest_rank(values.len(), q), f32::total_cmp)
        .1
}

/// The index, in ascending order, of the nearest-rank `q` quantile of `len` (> 0) values.
fn nearest_rank(len: usize, q: f64) -> usize {
    ((q * len as f64).ceil() as usize).clamp(1, len) - 1
}

/// Pixels whose luminance change from `a0` to `a1` is visible ([`POP_THRESHOLD`] on the
/// sRGB-encoded luminance) where the change from `b0` to `b1` is not.
fn pops(a0: &[f32], a1: &[f32], b0: &[f32], b1: &[f32]) -> u64 {
    let visible = |x0: f32, x1: f32| (srgb_encode(x1) - srgb_encode(x0)).abs() > POP_THRESHOLD;
    a0.iter()
        .zip(a1)
        .zip(b0.iter().zip(b1))
        .filter(|((a0, a1), (b0, b1))| visible(**a0, **a1) && !visible(**b0, **b1))
        .count() as u64
}

/// The reference's own change over a span: the scale the temporal errors are read against.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceChange {
    pub span: Span,
    pub frames: u32,
    /// Mean over the frame pairs of mean |R_t − R_t−1|, linear luminance.
    pub luminance: f64,
    /// The same of `exact`'s T at the shaded points.
    pub transmittance: f64,
}

impl ReferenceChange {
    /// Of `exact`'s frames over `span`.
    pub fn of(span: Span, frames: &[FrameSample]) -> Self {
        let (mut lum, mut t) = (Vec::new(), Vec::new());
        for pair in frames.windows(2) {
            lum.push(mean_abs_difference(&pair[1].luminance, &pair[0].luminance));
            let (t0, t1) = comparable(&pair[0], &pair[1]);
            t.push(mean_abs_difference(t1, t0));
        }
        Self {
            span,
            frames: frames.len() as u32,
            luminance: mean(&lum),
            transmittance: mean(&t),
        }
    }
}

/// The points of two frames that correspond: all of them when the frames have as many,
/// else the fixed ones.
fn comparable<'a>(a: &'a FrameSample, b: &'a FrameSample) -> (&'a [f32], &'a [f32]) {
    let n = match a.transmittance.len() == b.transmittance.len() {
        true => a.transmittance.len(),
        false => a.fixed_points.min(b.fixed_points),
    };
    (&a.transmittance[..n], &b.transmittance[..n])
}

fn mean(values: &[f64]) -> f64 {
    match values.is_empty() {
        true => 0.0,
        false => values.iter().sum::<f64>() / values.len() as f64,
    }
}

/// A cell over a span, against `exact` over the same frames (module docs for each measure).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Motion {
    /// Frames measured (pairs: one fewer).
    pub frames: u32,
    pub temporal_error: f64,
    pub temporal_p999: f64,
    pub temporal_p999_worst: f64,
    pub pops_per_frame: f64,
    pub t_temporal_error: f64,
    pub t_temporal_p999: f64,
    pub frame_error: f64,
    pub flip_median: f64,
    pub flip_p95: f64,
    pub flip_std: f64,
    /// The FLIP against `exact` of each frame, and the temporal error of each pair (the
    /// report's charts over time).
    #[serde(default)]
    pub flip_per_frame: Vec<f64>,
    #[serde(default)]
    pub temporal_per_pair: Vec<f64>,
}

/// Takes a technique's frames over a span, in order, beside `exact`'s, and gives its
/// [`Motion`]. Holds only the previous frame.
#[derive(Default)]
pub struct Recorder {
    previous: Option<FrameSample>,
    frames: u32,
    image: Vec<(f64, f64)>,
    pops: Vec<u64>,
    shadow: Vec<(f64, f64)>,
    frame_errors: Vec<f64>,
}

impl Recorder {
    pub fn new() -> Self {
        Self::default()
    }

    /// The technique's next frame; `exact` holds the reference's frames of the whole span (the
    /// frame is compared with the one at its index, and its change with that one's).
    pub fn push(&mut self, frame: FrameSample, exact: &[FrameSample]) {
        let k = self.frames as usize;
        let r = &exact[k];
        self.frame_errors
            .push(mean_abs_difference(&frame.luminance, &r.luminance));
        if let Some(prev) = &self.previous {
            let r0 = &exact[k - 1];
            self.image.push(change_difference(
                &prev.luminance,
                &frame.luminance,
                &r0.luminance,
                &r.luminance,
            ));
            self.pops.push(pops(
                &prev.luminance,
                &frame.luminance,
                &r0.luminance,
                &r.luminance,
            ));
            let (a0, a1) = comparable(prev, &frame);
            let (b0, b1) = comparable(r0, r);
            self.shadow.push(change_difference(a0, a1, b0, b1));
        }
        self.previous = Some(frame);
        self.frames += 1;
    }

    /// The measures, with the per-frame FLIP against `exact` (`flips`, one a frame).
    pub fn finish(self, flips: &[f64]) -> Motion {
        let first = |v: &[(f64, f64)]| v.iter().map(|p| p.0).collect::<Vec<f64>>();
        let second = |v: &[(f64, f64)]| v.iter().map(|p| p.1).collect::<Vec<f64>>();
        let mut sorted = flips.to_vec();
        sorted.sort_by(f64::total_cmp);
        let at = |q: f64| match sorted.is_empty() {
            true => 0.0,
            false => sorted[nearest_rank(sorted.len(), q)],
        };
        let flip_mean = mean(flips);
        let variance = mean(
            &flips
                .iter()
                .map(|f| (f - flip_mean).powi(2))
                .collect::<Vec<f64>>(),
        );
        Motion {
            frames: self.frames,
            temporal_error: mean(&first(&self.image)),
            temporal_p999: mean(&second(&self.image)),
            temporal_p999_worst: second(&self.image).into_iter().fold(0.0, f64::max),
            pops_per_frame: mean(&self.pops.iter().map(|&p| p as f64).collect::<Vec<f64>>()),
            t_temporal_error: mean(&first(&self.shadow)),
            t_temporal_p999: mean(&second(&self.shadow)),
            frame_error: mean(&self.frame_errors),
            flip_median: at(0.5),
            flip_p95: at(0.95),
            flip_std: variance.sqrt(),
            flip_per_frame: flips.to_vec(),
            temporal_per_pair: first(&self.image),
        }
    }
}

/// How much the change pictures amplify a change of linear luminance: 1/16 of full scale
/// shows at full brightness (a frame's changes are a few thousandths; the sweep's own measure is
/// of the unamplified values).
pub const CHANGE_GAIN: f32 = 16.0;

/// One frame pair of a technique beside `exact`'s, as the viewer's temporal compare shows it:
/// each one's change from the earlier frame to the later and the difference of the changes,
/// as pictures ([`change_picture`]), with the pair's measures as the sweep takes them.
pub struct ChangePictures {
    /// I_t − I_t−1 of the technique.
    pub technique: RgbImage,
    /// R_t − R_t−1 of `exact`.
    pub exact: RgbImage,
    /// (I_t − I_t−1) − (R_t − R_t−1): what the pair's `temporal_error` is the mean size of.
    pub difference: RgbImage,
    /// The pair's `temporal_error` and `temporal_p999` (linear luminance) and its pops.
    pub temporal_error: f64,
    pub temporal_p999: f64,
    pub pops: u64,
    /// `exact`'s own change, mean |R_t − R_t−1|: the scale to read the error against.
    pub exact_change: f64,
}

impl ChangePictures {
    /// Of a technique's frames `a0` (earlier) and `a1` beside `exact`'s `r0` and `r1` (all of
    /// one size, which the caller rendered them at).
    pub fn of(a0: &RgbImage, a1: &RgbImage, r0: &RgbImage, r1: &RgbImage) -> Self {
        let (w, h) = a1.dimensions();
        let [a0, a1, r0, r1] = [a0, a1, r0, r1].map(linear_luminance);
        let (temporal_error, temporal_p999) = change_difference(&a0, &a1, &r0, &r1);
        let change = |x0: &[f32], x1: &[f32]| -> Vec<f32> {
            x0.iter().zip(x1).map(|(x0, x1)| x1 - x0).collect()
        };
        let (da, dr) = (change(&a0, &a1), change(&r0, &r1));
        let difference: Vec<f32> = da.iter().zip(&dr).map(|(a, r)| a - r).collect();
        Self {
            technique: change_picture(&da, w, h),
            exact: change_picture(&dr, w, h),
            difference: change_picture(&difference, w, h),
            temporal_error,
            temporal_p999,
            pops: pops(&a0, &a1, &r0, &r1),
            exact_change: mean_abs_difference(&r1, &r0),
        }
    }
}

/// A signed change of linear luminance per pixel as a picture: brightening orange, darkening
/// blue, black where nothing changed, [`CHANGE_GAIN`] times the change on the sRGB-encoded
/// brightness (so 1/16 or more shows at full brightness).
pub fn change_picture(change: &[f32], width: u32, height: u32) -> RgbImage {
    let mut out = RgbImage::new(width, height);
    for (pixel, &d) in out.pixels_mut().zip(change) {
        let m = srgb_encode((d.abs() * CHANGE_GAIN).min(1.0));
        let tint: [f32; 3] = if d > 0.0 {
            [255.0, 153.0, 26.0]
        } else {
            [26.0, 153.0, 255.0]
        };
        pixel.0 = tint.map(|t| (t * m).round() as u8);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(luminance: Vec<f32>, transmittance: Vec<f32>) -> FrameSample {
        FrameSample {
            luminance,
            transmittance,
            fixed_points: 0,
        }
    }

    /// A technique's frames and exact's, as luminance rows of one value per pixel.
    fn measure(technique: &[Vec<f32>], exact: &[Vec<f32>]) -> Motion {
        let exact: Vec<FrameSample> = exact.iter().map(|l| sample(l.clone(), vec![])).collect();
        let mut r = Recorder::new();
        for l in technique {
            r.push(sample(l.clone(), vec![]), &exact);
        }
        r.finish(&vec![0.0; technique.len()])
    }

    #[test]
    fn spans_count_their_frames_and_refuse_what_they_cannot_render() {
        let s = Span::parse("7.5..7.9", 30.0).unwrap();
        assert_eq!(s.frames(), 13);
        let t = s.times();
        assert!((t[1] - t[0] - 1.0 / 30.0).abs() < 1e-6);
        assert!((t[12] - 7.9).abs() < 1e-5);
        assert_eq!(s.describe(), "13 frames at 30 fps, t = 7.5 .. 7.9 s");
        for (range, fps, says) in [
            ("3..2", 30.0, "after the start"),
            ("7", 30.0, "is not START..END"),
            ("a..2", 30.0, "\"a\" is not a number"),
            ("1..1.01", 30.0, "at least two frames"),
            ("0..100", 30.0, "at most 240"),
            ("-1..2", 30.0, "out of range"),
            ("1..2", 0.0, "--fps 0 is out of range"),
        ] {
            let err = Span::parse(range, fps).unwrap_err();
            assert!(err.contains(says), "{range} at {fps}: {err}");
        }
    }

    #[test]
    fn an_orbiting_span_turns_the_camera_about_its_target_by_its_share() {
        let span = Span::parse("1..2", 4.0).unwrap().with_orbit(90.0).unwrap();
        let camera = crate::scene::Camera {
            position: glam::Vec3::new(0.0, 2.0, 5.0),
            target: glam::Vec3::new(0.0, 1.0, 0.0),
            ..crate::scene::Camera::default()
        };
        // The first frame's camera is the scene's; the last has turned the whole 90°, about
        // the vertical through the target: +z to +x, the height and the distance kept.
        assert_eq!(span.camera_at(&camera, 1.0).position, camera.position);
        let last = span.camera_at(&camera, 2.0).position;
        assert!(
            (last - glam::Vec3::new(5.0, 2.0, 0.0)).length() < 1e-5,
            "{last}"
        );
        let half = span.camera_at(&camera, 1.5).position - camera.target;
        let expected = glam::Vec3::new(5.0 * 0.5f32.sqrt(), 1.0, 5.0 * 0.5f32.sqrt());
        assert!((half - expected).length() < 1e-5, "{half}");
        assert!(span.describe().ends_with("the camera turning 90°"));
        // The light likewise, about its own target.
        let light = crate::scene::Spotlight::default();
        let turned = span.with_light_orbit(-90.0).unwrap();
        let moved = turned.light_at(&light, 2.0);
        assert!(
            (moved.position.distance(light.target) - light.position.distance(light.target)).abs()
                < 1e-4
        );
        assert!((moved.position.y - light.position.y).abs() < 1e-5);
        assert_eq!(turned.light_at(&light, 1.0).position, light.position);
        assert!(turned.describe().ends_with("the light turning -90°"));
        let err = Span::parse("1..2", 4.0)
            .unwrap()
            .with_orbit(400.0)
            .unwrap_err();
        assert!(err.contains("--orbit 400 is out of range"), "{err}");
    }

    #[test]
    fn luminance_decodes_srgb_and_weighs_the_channels() {
        let mut img = RgbImage::new(3, 1);
        img.put_pixel(0, 0, image::Rgb([255, 255, 255]));
        img.put_pixel(1, 0, image::Rgb([0, 255, 0]));
        img.put_pixel(2, 0, image::Rgb([188, 188, 188]));
        let l = linear_luminance(&img);
        assert!((l[0] - 1.0).abs() < 1e-6);
        assert!((l[1] - 0.7152).abs() < 1e-6);
        // sRGB 188/255 = 0.737 decodes to ((0.737 + 0.055) / 1.055)^2.4 = 0.5029.
        assert!((l[2] - 0.5029).abs() < 1e-3, "{}", l[2]);
    }

    #[test]
    fn a_technique_that_equals_exact_or_errs_alike_in_every_frame_has_no_temporal_error() {
        let exact = vec![
            vec![0.1, 0.2, 0.3],
            vec![0.2, 0.25, 0.5],
            vec![0.4, 0.1, 0.2],
        ];
        let same = measure(&exact, &exact);
        assert_eq!(same.temporal_error, 0.0);
        assert_eq!(same.temporal_p999, 0.0);
        assert_eq!(same.pops_per_frame, 0.0);
        assert_eq!(same.frame_error, 0.0);
        // Darker by 0.05 everywhere, always: a still error of 0.05, no temporal one.
        let offset: Vec<Vec<f32>> = exact
            .iter()
            .map(|f| f.iter().map(|v| v - 0.05).collect())
            .collect();
        let m = measure(&offset, &exact);
        assert!(m.temporal_error < 1e-7, "{}", m.temporal_error);
        assert!((m.frame_error - 0.05).abs() < 1e-7);
        assert_eq!(m.pops_per_frame, 0.0);
    }

    #[test]
    fn a_frozen_technique_errs_by_exacts_whole_change() {
        // exact moves by 0.1 then 0.3 per pixel; the technique stands still: its temporal
        // error is exact's mean change, (0.1 + 0.3) / 2.
        let exact = vec![vec![0.2; 4], vec![0.3; 4], vec![0.6; 4]];
        let frozen = vec![vec![0.2; 4]; 3];
        let m = measure(&frozen, &exact);
        assert!(
            (m.temporal_error - 0.2).abs() < 1e-6,
            "{}",
            m.temporal_error
        );
        assert!((m.temporal_p999 - 0.2).abs() < 1e-6);
        assert!((m.temporal_p999_worst - 0.3).abs() < 1e-6);
        assert_eq!(m.pops_per_frame, 0.0, "a frozen frame never pops");
        let change = ReferenceChange::of(
            Span::new(0.0, 2.0 / 30.0, 30.0).unwrap(),
            &exact
                .iter()
                .map(|l| sample(l.clone(), vec![]))
                .collect::<Vec<_>>(),
        );
        assert!((change.luminance - 0.2).abs() < 1e-6);
    }

    #[test]
    fn one_pixel_that_jumps_is_the_tail_and_a_pop() {
        // 2000 pixels; exact still; one technique pixel jumps from 0.2 to 0.4 and back.
        let exact = vec![vec![0.2f32; 2000]; 3];
        let mut jump = exact.clone();
        jump[1][7] = 0.4;
        let m = measure(&jump, &exact);
        // Mean over pixels: 0.2 / 2000 per pair.
        assert!((m.temporal_error - 0.2 / 2000.0).abs() < 1e-8);
        // The 99.9th percentile of 2000 values is the 1998th smallest: 0 (one outlier).
        assert_eq!(m.temporal_p999, 0.0);
        // Each pair: the jump is visible (sRGB 0.48 -> 0.66), exact's 0 is not.
        assert_eq!(m.pops_per_frame, 1.0);
        // Three jumping pixels of 2000 reach the tail (the 1998th value of the sorted changes).
        let mut three = exact.clone();
        for i in [1, 2, 3] {
            three[1][i] = 0.4;
        }
        assert!((measure(&three, &exact).temporal_p999 - 0.2).abs() < 1e-6);
        // A change exact makes too does not pop, whatever its size difference.
        let mut both = exact.clone();
        both[1][7] = 0.5;
        let mut ex = exact.clone();
        ex[1][7] = 0.4;
        assert_eq!(measure(&both, &ex).pops_per_frame, 0.0);
        // A change below 3/255 of sRGB-encoded luminance is not visible.
        let mut small = exact.clone();
        small[1][7] = 0.2 + 0.002;
        assert_eq!(measure(&small, &exact).pops_per_frame, 0.0);
    }

    #[test]
    fn the_shadows_change_compares_only_points_that_correspond() {
        let f = |t: Vec<f32>, fixed| FrameSample {
            luminance: vec![0.0],
            transmittance: t,
            fixed_points: fixed,
        };
        // Two fixed points then particle points; frame 1 has a particle more (its points do
        // not correspond), so only the fixed ones count.
        let exact = vec![f(vec![0.5, 0.5, 0.9], 2), f(vec![0.6, 0.5, 0.1, 0.1], 2)];
        let mut r = Recorder::new();
        r.push(f(vec![0.5, 0.5, 0.9], 2), &exact);
        r.push(f(vec![0.5, 0.7, 0.8, 0.8], 2), &exact);
        let m = r.finish(&[0.1, 0.3]);
        // |0 - 0.1| and |0.2 - 0| over the two fixed points.
        assert!(
            (m.t_temporal_error - 0.15).abs() < 1e-6,
            "{}",
            m.t_temporal_error
        );
        assert!((m.flip_median - 0.1).abs() < 1e-12);
        assert!((m.flip_p95 - 0.3).abs() < 1e-12);
        assert!((m.flip_std - 0.1).abs() < 1e-12);
    }

    #[test]
    fn the_change_pictures_show_each_change_and_their_difference() {
        let grey = |v: u8| image::Rgb([v, v, v]);
        let image = |values: [u8; 3]| {
            let mut out = RgbImage::new(3, 1);
            for (x, v) in values.into_iter().enumerate() {
                out.put_pixel(x as u32, 0, grey(v));
            }
            out
        };
        // Pixel 0 brightens in both, pixel 1 darkens in the technique only, pixel 2 stays.
        let (a0, a1) = (image([100, 200, 50]), image([140, 120, 50]));
        let (r0, r1) = (image([100, 200, 50]), image([140, 200, 50]));
        let p = ChangePictures::of(&a0, &a1, &r0, &r1);
        let l = |v: u8| crate::diff::srgb_to_linear(f64::from(v) / 255.0);
        let dark = l(120) - l(200);
        // The pair's error is pixel 1's alone, a third of it on average; it is a pop.
        assert!(
            (p.temporal_error - dark.abs() / 3.0).abs() < 1e-6,
            "{}",
            p.temporal_error
        );
        assert!((p.temporal_p999 - dark.abs()).abs() < 1e-6);
        assert_eq!(p.pops, 1);
        assert!((p.exact_change - (l(140) - l(100)) / 3.0).abs() < 1e-6);
        // Brightening is orange, darkening blue (the gain saturates both), unchanged black.
        let brighten = [255, 153, 26];
        assert_eq!(p.technique.get_pixel(0, 0).0, brighten);
        assert_eq!(p.technique.get_pixel(1, 0).0, [26, 153, 255]);
        assert_eq!(p.exact.get_pixel(0, 0).0, brighten);
        assert_eq!(p.exact.get_pixel(1, 0).0, [0, 0, 0]);
        // The difference: nothing at pixel 0 (the same change), the technique's darkening at 1.
        assert_eq!(p.difference.get_pixel(0, 0).0, [0, 0, 0]);
        assert_eq!(p.difference.get_pixel(1, 0).0, [26, 153, 255]);
        assert_eq!(p.difference.get_pixel(2, 0).0, [0, 0, 0]);
        // A small change shows in proportion: 1/64 of full scale is a quarter before encoding.
        let q = change_picture(&[1.0 / 64.0], 1, 1);
        let m = srgb_encode(0.25);
        assert_eq!(q.get_pixel(0, 0).0[0], (m * 255.0).round() as u8);
    }
}
