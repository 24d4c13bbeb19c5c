//! `smokeshadow tune`: one procedure chooses every technique's registry parameters, on training
//! scenes kept apart from the scenes the answers are given for (the thesis and the gallery).
//!
//! The procedure, the same for every technique that has parameters (the derived ones, whose
//! default is "derived per frame", stay derived):
//! - **budgets**: each candidate runs at the largest configuration whose resident bytes fit
//!   each byte budget per texel ([`crate::shadow::fit_bytes_per_texel`]), at the technique's own
//!   precision ([`free_params`] says why the search leaves it);
//! - **score**: the mean, over the training scenes and the budgets the starting values fit, of
//!   the RMS difference of T from `exact` at the points the frame shades (the sweep's RMS T
//!   column, [`crate::render::Renderer::probe_shaded`]); a candidate that does not fit one of
//!   those budgets is out;
//! - **search**: exactly `evaluations` candidates per technique: the starting values (the
//!   registry defaults, or `--params`), then half the rest drawn uniformly over every
//!   parameter's declared range (log-uniformly over a range spanning 100x or more, or from 0
//!   when the default is at most a hundredth of the top; a choice uniformly), then the other
//!   half perturbing the best so far with a step that shrinks by 0.7 each time; values rounded to 3 significant digits (whole numbers where the technique
//!   reads them so), so what is written is what was scored. One seeded generator per technique,
//!   seeded alike, so no technique gets a luckier stream;
//! - **stability**: a technique the registry does not hold order independent (`msm`: 8 power
//!   moments amplify the f32 rounding of the sums) must also keep T within
//!   [`ORDER_RMS_BOUND`] RMS of itself when the particles are drawn in reverse (the camera
//!   mirrored through its target, as `tests/moments.rs` reverses them); a candidate that does
//!   not is out, so the error alone cannot pick a value that makes the shadow flicker as the
//!   view turns;
//! - **convergence**: for a technique the registry holds to converge with its budget
//!   (`converges_with_budget`), a candidate whose error on a training scene rises from one byte
//!   budget to a larger one (by more than [`RISE_BOUND`]) is out: the shipped defaults must not
//!   trade the large budgets' accuracy for the small ones';
//! - **held out**: the starting and the chosen values are scored again on held-out scenes (by
//!   default the thesis scene), which the search never saw.
//!
//! The output is a parameter file ([`ParamsFile`]) that `--params FILE` reads: `[params]` with
//! the chosen values, `[tune]` with the command, the scenes, the budgets and every technique's
//! training and held-out error. `--params paper` names the papers' values instead ([`PAPER`]).

use crate::Wait;
use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Context;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use smokeshadow_core::gpu::Gpu;
use smokeshadow_core::render::shaded::{frame_points, rms_difference};
use smokeshadow_core::render::{OUTPUT_FORMAT, Renderer, TechniqueConfig};
use smokeshadow_core::scene::Scene;
use smokeshadow_core::shadow::{self, ParamSpec, ParamValue, TechniqueEntry, TechniqueParams};
use smokeshadow_core::sim::Particle;

/// The papers' values, for `--params paper`: (key, value, source). A parameter without a
/// published value for this use keeps its default, and `smokeshadow info` says which.
pub const PAPER: &[(&str, f32, &str)] = &[
    // Münstermann, Krumpen, Klein & Peters 2018 (moment-based OIT, doi:10.1145/3203206) and
    // their released code: β per moment count and precision, with their bias vectors for power
    // moments ([`crate::shadow::msm::PAPER_BIAS`]: 5e-7, 5e-6, 5e-5 for 4, 6, 8 single-float
    // power moments; 4e-7, 8e-7, 1.5e-6 for 2, 3, 4 trigonometric ones).
    (
        "msm_bias_table",
        1.0,
        "Münstermann et al. 2018 and their code: β and bias vector per moment count (32-bit)",
    ),
    (
        "tmsm_bias_table",
        1.0,
        "Münstermann et al. 2018 and their code: β per moment count (32-bit)",
    ),
    // The same paper's overestimation η for every moment count.
    (
        "msm_overestimation",
        0.25,
        "Münstermann et al. 2018 (η = 0.25)",
    ),
    (
        "tmsm_overestimation",
        0.25,
        "Münstermann et al. 2018 (η = 0.25)",
    ),
    // Its wrapping zone for trigonometric moments: 0.1π.
    (
        "tmsm_wrapping_zone_rad",
        0.1 * std::f32::consts::PI,
        "Münstermann et al. 2018 (0.1π)",
    ),
];

/// The RMS change of T, over a scene's shaded points, that reversing the draw order may cause in
/// a technique the registry does not hold order independent (`tests/moments.rs` holds `msm`'s
/// defaults to it).
pub const ORDER_RMS_BOUND: f64 = 0.01;

/// How much a converging technique's RMS T error may rise from one byte budget to a larger one
/// on a training scene before `tune` rejects the candidate: (relative, absolute), the error at
/// the larger budget at most `relative` times the smaller's plus `absolute` (room for the
/// rounding of configurations that differ by one channel).
pub const RISE_BOUND: (f64, f64) = (1.05, 1e-4);

/// Whether errors `(budget, error)` of one scene never rise with the budget beyond
/// [`RISE_BOUND`].
pub fn falls_with_budget(errors: &[(u32, f64)]) -> bool {
    let mut by_budget = errors.to_vec();
    by_budget.sort_by_key(|&(b, _)| b);
    by_budget
        .windows(2)
        .all(|w| w[1].1 <= w[0].1 * RISE_BOUND.0 + RISE_BOUND.1)
}

/// A parameter file as `--params FILE` reads it and `tune` writes it.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParamsFile {
    /// How the values were chosen (written by `tune`; ignored when read).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tune: Option<TuneRecord>,
    /// KEY = VALUE, as a scene's `[shadow.params]`.
    #[serde(default)]
    pub params: BTreeMap<String, ParamValue>,
    /// The map resolution `tune` chose per technique and memory budget (total bytes, as a
    /// string key): `[shapes.dom]` `12582912 = { resolution = 256, training = 0.0012 }`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub shapes: BTreeMap<String, BTreeMap<String, Shape>>,
}

pub use smokeshadow_core::sweep::{Shape, Shapes, shipped_shapes};

impl ParamsFile {
    /// Its shapes, by memory budget in bytes (a key that is not a whole number is skipped).
    pub fn shapes(&self) -> Shapes {
        smokeshadow_core::sweep::shapes_of(&self.shapes)
    }
}

/// What `tune` records beside its values.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TuneRecord {
    pub command: String,
    pub training: Vec<String>,
    pub held_out: Vec<String>,
    pub bytes_per_texel: Vec<u32>,
    pub evaluations: u32,
    pub seed: u64,
    /// The memory budgets (total bytes) and map resolutions the shapes were chosen over.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub memory: Vec<u64>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub shape_resolutions: Vec<u32>,
    pub adapter: String,
    pub tool_version: String,
    /// Per technique tuned: its errors at the starting and the chosen values.
    pub techniques: BTreeMap<String, TechniqueRecord>,
}

/// A technique's RMS T error (mean over scenes and budgets) before and after tuning.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TechniqueRecord {
    pub start_training: f64,
    pub chosen_training: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_held_out: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chosen_held_out: Option<f64>,
}

/// A parameter set as `--params` gives it ([`param_set`]), and the file's shapes (none for
/// `paper`).
#[derive(Clone, Debug, PartialEq)]
pub struct ParamSet(pub Vec<(String, ParamValue)>, pub Shapes);

impl ParamSet {
    /// Parses `--params FILE|paper`.
    pub fn parse(name: &str) -> Result<Self, String> {
        if name == "paper" {
            return param_set(name).map(|set| Self(set, Shapes::new()));
        }
        let file = read_params_file(name)?;
        Ok(Self(checked_params(name, &file)?, file.shapes()))
    }
}

/// The values of a named set (`paper`) or of a parameter file, checked against the registry,
/// in the form settings keep. `Err`: one line naming the file and what is wrong.
pub fn param_set(name: &str) -> Result<Vec<(String, ParamValue)>, String> {
    if name == "paper" {
        return Ok(PAPER
            .iter()
            .map(|(key, value, _)| ((*key).to_owned(), ParamValue::Number(*value)))
            .collect());
    }
    checked_params(name, &read_params_file(name)?)
}

/// The `[params]` of the parameter file `name`, checked against the registry.
fn checked_params(name: &str, file: &ParamsFile) -> Result<Vec<(String, ParamValue)>, String> {
    file.params
        .iter()
        .map(|(key, value)| {
            let spec = shadow::find_param(key).map_err(|e| format!("--params {name}: {e}"))?;
            let value = spec
                .canonical(value)
                .map_err(|e| format!("--params {name}: {e}"))?;
            Ok((spec.key.to_owned(), value))
        })
        .collect()
}

/// A parameter file, read and decoded. `Err`: one line naming the file and what is wrong.
fn read_params_file(name: &str) -> Result<ParamsFile, String> {
    let path = Path::new(name);
    let text = std::fs::read_to_string(path).map_err(|err| {
        format!("--params {name}: cannot read it ({err}); give a parameter file or `paper`")
    })?;
    let file: ParamsFile = toml::from_str(&text).map_err(|err| {
        // toml's message: where, the line with a caret, and what is wrong, on separate lines.
        let text = err.to_string();
        let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
        match (lines.first(), lines.last()) {
            (Some(first), Some(last)) if first != last => {
                format!("--params {name}: {}: {}", first.trim(), last.trim())
            }
            _ => format!("--params {name}: {}", text.replace('\n', " ")),
        }
    })?;
    Ok(file)
}

/// What the search varies: a technique's parameters that have a default (the derived ones stay
/// derived) and that the registry marks `tuned`. Not a layered map's precision: half floats
/// change what the error does not measure (the bytes; `fom`'s T then depends on the draw
/// order), so it stays the technique's own choice, and `--param KEY_precision=...` compares the
/// other in a sweep. Not `avsm_insert`: its `sorted` is not what a one-pass engine can do.
pub fn free_params(entry: &TechniqueEntry) -> Vec<&'static ParamSpec> {
    entry
        .params
        .iter()
        .filter(|p| p.default.is_some() && p.tuned)
        .collect()
}

/// `x` to 3 significant digits.
fn round_sig(x: f32) -> f32 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let digits = 2 - x.abs().log10().floor() as i32;
    let scale = 10f64.powi(digits);
    ((f64::from(x) * scale).round() / scale) as f32
}

/// The range a parameter is searched over on a log scale, if it is: a positive range spanning
/// 100x or more, or a range from 0 whose default is at most a hundredth of its top (a bias:
/// then from a millionth of the top).
fn log_range(spec: &ParamSpec) -> Option<(f32, f32)> {
    if !spec.choices.is_empty() {
        return None;
    }
    if spec.min > 0.0 && spec.max / spec.min >= 100.0 {
        return Some((spec.min, spec.max));
    }
    let small_default = spec.default.is_some_and(|d| d <= spec.max / 100.0);
    (spec.min == 0.0 && spec.max > 0.0 && small_default).then_some((spec.max * 1e-6, spec.max))
}

/// A value as the search proposes it: within the range, whole where the technique rounds, 3
/// significant digits.
fn snap(spec: &ParamSpec, x: f32) -> f32 {
    let x = x.clamp(spec.min, spec.max);
    let x = if spec.integer || !spec.choices.is_empty() {
        x.round()
    } else {
        round_sig(x)
    };
    x.clamp(spec.min, spec.max)
}

/// A value drawn over the whole range.
fn draw(spec: &ParamSpec, rng: &mut impl Rng) -> f32 {
    if !spec.choices.is_empty() {
        return rng.random_range(0..spec.choices.len()) as f32;
    }
    let u: f32 = rng.random();
    let x = if let Some((lo, hi)) = log_range(spec) {
        (lo.ln() + u * (hi.ln() - lo.ln())).exp()
    } else {
        spec.min + u * (spec.max - spec.min)
    };
    snap(spec, x)
}

/// A standard normal sample (Box–Muller).
fn normal(rng: &mut impl Rng) -> f32 {
    let u1: f32 = rng.random::<f32>().max(f32::MIN_POSITIVE);
    let u2: f32 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
}

/// `x` moved by a step of `scale` (a share of the range, in log space for a log-scaled one); a
/// choice switches to a random one with probability 1/3.
fn perturb(spec: &ParamSpec, x: f32, scale: f32, rng: &mut impl Rng) -> f32 {
    if !spec.choices.is_empty() {
        return match rng.random_range(0..3) {
            0 => draw(spec, rng),
            _ => x,
        };
    }
    let y = if let Some((lo, hi)) = log_range(spec) {
        // Within the log range: a bias never falls to 0 by a long step.
        (x.max(lo).ln() + normal(rng) * scale * (hi / lo).ln())
            .exp()
            .clamp(lo, hi)
    } else {
        x + normal(rng) * scale * (spec.max - spec.min)
    };
    snap(spec, y)
}

/// One scene as the search scores on it: the particles, the shaded points, and `exact`'s T
/// there (its self-check passed).
pub struct Case {
    pub scene: Scene,
    /// The scene with the camera mirrored through its target: the renderer sorts the particles
    /// for the camera, so this draws them in reverse ([`ORDER_RMS_BOUND`]).
    behind: Scene,
    particles: Vec<Particle>,
    points: Vec<glam::Vec3>,
    owners: Vec<u32>,
    exact_t: Vec<f32>,
    renderer: Renderer,
}

impl Case {
    /// Simulates `scene`, renders `exact` and checks it against the closed form (refusing a
    /// reference that disagrees), and keeps its T at the shaded points.
    pub fn new(gpu: &Gpu, scene: Scene) -> anyhow::Result<Self> {
        let particles = crate::particles::scene_particles(&scene)?;
        let (w, h) = (scene.output.width_px, scene.output.height_px);
        let exact = TechniqueConfig {
            name: shadow::reference().name.to_owned(),
            params: scene.shadow.params(1),
        };
        let mut renderer = Renderer::new(gpu, w, h, OUTPUT_FORMAT, &exact).wait()?;
        renderer.load_volume(gpu, &scene).wait()?;
        let (points, owners) = frame_points(&renderer, &scene, &particles);
        let exact_t = renderer
            .probe_shaded(gpu, &scene, &particles, &points, &owners)
            .wait()?;
        smokeshadow_core::render::reference_check::verify(&mut renderer, gpu, &scene, &particles)
            .wait()?;
        let mut behind = scene.clone();
        behind.camera.position = scene.camera.target * 2.0 - scene.camera.position;
        Ok(Self {
            scene,
            behind,
            particles,
            points,
            owners,
            exact_t,
            renderer,
        })
    }

    /// The technique `entry` with `values` set over the scene's parameters, at the
    /// configuration that fits `bytes` per texel (`None`: it fits none), at the scene's map
    /// resolution or at `resolution`.
    fn config(
        &self,
        entry: &TechniqueEntry,
        values: &BTreeMap<String, ParamValue>,
        bytes: u32,
        resolution: Option<u32>,
    ) -> Option<TechniqueConfig> {
        let mut params: TechniqueParams = self.scene.shadow.params(entry.min_channels);
        params.values.extend(values.clone());
        if let Some(res) = resolution {
            params.resolution_px = res;
        }
        let particles = self.particles.len() as u64;
        let pixels = u64::from(self.scene.output.width_px) * u64::from(self.scene.output.height_px);
        let fit = shadow::fit_bytes_per_texel(entry, &params, bytes, particles, pixels).ok()?;
        params.channels = fit.channels;
        Some(TechniqueConfig {
            name: entry.name.to_owned(),
            params,
        })
    }

    /// The RMS change of `config`'s T at the shaded points (probed as free points) when the
    /// particles are drawn in reverse.
    fn order_change(&mut self, gpu: &Gpu, config: &TechniqueConfig) -> anyhow::Result<f64> {
        self.renderer.set_technique(gpu, config).wait()?;
        let front = self
            .renderer
            .probe(gpu, &self.scene, &self.particles, &self.points)
            .wait()?;
        let back = self
            .renderer
            .probe(gpu, &self.behind, &self.particles, &self.points)
            .wait()?;
        Ok(rms_difference(&front, &back))
    }

    /// RMS T error of `config` against `exact` at the shaded points.
    fn score(&mut self, gpu: &Gpu, config: &TechniqueConfig) -> anyhow::Result<f64> {
        self.renderer.set_technique(gpu, config).wait()?;
        let t = self
            .renderer
            .probe_shaded(
                gpu,
                &self.scene,
                &self.particles,
                &self.points,
                &self.owners,
            )
            .wait()?;
        Ok(rms_difference(&t, &self.exact_t))
    }
}

/// What the search is asked to do.
#[derive(Clone, Debug)]
pub struct TuneOptions {
    pub bytes_per_texel: Vec<u32>,
    /// Candidates scored per technique, the starting values included (at least 1).
    pub evaluations: u32,
    pub seed: u64,
}

/// One technique's search.
#[derive(Clone, Debug)]
pub struct Tuned {
    pub technique: &'static str,
    /// The values it started from and the ones chosen, for every free parameter.
    pub start: BTreeMap<String, ParamValue>,
    pub chosen: BTreeMap<String, ParamValue>,
    pub start_training: f64,
    pub chosen_training: f64,
    pub start_held_out: Option<f64>,
    pub chosen_held_out: Option<f64>,
    /// Candidates scored (the options' `evaluations`).
    pub evaluations: u32,
}

/// Values as settings keep them: choices by name.
fn as_values(specs: &[&'static ParamSpec], x: &[f32]) -> BTreeMap<String, ParamValue> {
    specs
        .iter()
        .zip(x)
        .map(|(spec, &v)| {
            let value = match spec.choices.is_empty() {
                true => ParamValue::Number(v),
                false => ParamValue::Choice(spec.choices[v as usize].to_owned()),
            };
            (spec.key.to_owned(), value)
        })
        .collect()
}

/// Training pairs: (index of a [`Case`], bytes per texel).
type Pairs = Vec<(usize, u32)>;

/// Hears of each candidate: (evaluation, its values, its score, `None` when it does not fit).
pub type Report<'a> = dyn FnMut(u32, &BTreeMap<String, ParamValue>, Option<f64>) + 'a;

/// The (scene, budget) pairs `values` is scored over, and its mean RMS T error there; `None`
/// when it does not fit one of `pairs`, fails the stability bound ([`ORDER_RMS_BOUND`]) on
/// one, or (a converging technique) its error rises with the budget on a scene
/// ([`falls_with_budget`]). With `pairs` `None`, every pair it fits.
fn mean_error(
    gpu: &Gpu,
    cases: &mut [Case],
    entry: &TechniqueEntry,
    values: &BTreeMap<String, ParamValue>,
    budgets: &[u32],
    pairs: Option<&[(usize, u32)]>,
) -> anyhow::Result<Option<(f64, Pairs)>> {
    let all: Vec<(usize, u32)> = (0..cases.len())
        .flat_map(|i| budgets.iter().map(move |&b| (i, b)))
        .collect();
    let want = pairs.unwrap_or(&all);
    let mut scored = Vec::new();
    let mut errors: Vec<(usize, u32, f64)> = Vec::new();
    let mut sum = 0.0;
    for &(i, bytes) in want {
        match cases[i].config(entry, values, bytes, None) {
            Some(config) => {
                if !entry.order_independent
                    && cases[i].order_change(gpu, &config)? > ORDER_RMS_BOUND
                {
                    return Ok(None);
                }
                let error = cases[i].score(gpu, &config)?;
                sum += error;
                errors.push((i, bytes, error));
                scored.push((i, bytes));
            }
            None if pairs.is_some() => return Ok(None),
            None => {}
        }
    }
    if scored.is_empty() {
        return Ok(None);
    }
    if entry.converges_with_budget {
        for i in 0..cases.len() {
            let scene: Vec<(u32, f64)> = errors
                .iter()
                .filter(|e| e.0 == i)
                .map(|e| (e.1, e.2))
                .collect();
            if !falls_with_budget(&scene) {
                return Ok(None);
            }
        }
    }
    Ok(Some((sum / scored.len() as f64, scored)))
}

/// Runs the procedure (the module doc) for `entry` from `start` (every free parameter's value).
/// `report` hears of each candidate: (evaluation, its values, its score).
pub fn tune_technique(
    gpu: &Gpu,
    entry: &'static TechniqueEntry,
    start: &TechniqueParams,
    training: &mut [Case],
    held_out: &mut [Case],
    options: &TuneOptions,
    report: &mut Report<'_>,
) -> anyhow::Result<Tuned> {
    let specs = free_params(entry);
    let x0: Vec<f32> = specs
        .iter()
        .map(|s| start.get(s).expect("free parameters have a value"))
        .collect();
    let start_values = as_values(&specs, &x0);
    let Some((start_score, pairs)) = mean_error(
        gpu,
        training,
        entry,
        &start_values,
        &options.bytes_per_texel,
        None,
    )?
    else {
        anyhow::bail!(
            "tune: {} at its starting values fits none of the byte budgets {:?}, its T moves \
             by more than {ORDER_RMS_BOUND} RMS when the draw order reverses, or its error rises \
             with the budget on a training scene",
            entry.name,
            options.bytes_per_texel
        );
    };
    report(1, &start_values, Some(start_score));
    let mut best = (x0.clone(), start_score);
    let evaluations = options.evaluations.max(1);
    if !specs.is_empty() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(options.seed);
        let random = (evaluations - 1) / 2;
        let mut scale = 0.25f32;
        // A candidate proposed again (a small space of choices) keeps its score: it counts as an
        // evaluation, as for every technique, but is not rendered twice.
        let mut seen: Vec<(Vec<f32>, Option<f64>)> = vec![(x0.clone(), Some(start_score))];
        for k in 2..=evaluations {
            let x: Vec<f32> = if k - 1 <= random {
                specs.iter().map(|s| draw(s, &mut rng)).collect()
            } else {
                let x = specs
                    .iter()
                    .zip(&best.0)
                    .map(|(s, &v)| perturb(s, v, scale, &mut rng))
                    .collect();
                scale *= 0.7;
                x
            };
            let values = as_values(&specs, &x);
            let score = match seen.iter().find(|(y, _)| *y == x) {
                Some((_, score)) => *score,
                None => {
                    let score = mean_error(
                        gpu,
                        training,
                        entry,
                        &values,
                        &options.bytes_per_texel,
                        Some(&pairs),
                    )?
                    .map(|(s, _)| s);
                    seen.push((x.clone(), score));
                    score
                }
            };
            report(k, &values, score);
            if let Some(s) = score
                && s < best.1
            {
                best = (x, s);
            }
        }
    }
    let chosen = as_values(&specs, &best.0);
    // Held out: the chosen values over the pairs the starting values fit there.
    let (start_held_out, chosen_held_out) = match held_out.is_empty() {
        true => (None, None),
        false => match mean_error(
            gpu,
            held_out,
            entry,
            &start_values,
            &options.bytes_per_texel,
            None,
        )? {
            None => (None, None),
            Some((start, held_pairs)) => {
                let chosen = mean_error(
                    gpu,
                    held_out,
                    entry,
                    &chosen,
                    &options.bytes_per_texel,
                    Some(&held_pairs),
                )?
                .map(|(s, _)| s);
                (Some(start), chosen)
            }
        },
    };
    Ok(Tuned {
        technique: entry.name,
        start: start_values,
        chosen,
        start_training: start_score,
        chosen_training: best.1,
        start_held_out,
        chosen_held_out,
        evaluations: if specs.is_empty() { 1 } else { evaluations },
    })
}

/// Each memory budget's shape for `entry` with `values`: of `resolutions`, the one whose largest
/// configuration within the budget (a whole number of bytes a texel there) fits on every
/// training scene with the lowest mean RMS T error over them (the first of equals), and that
/// error; a budget no resolution fits is left out. `report` hears of each (budget, resolution,
/// mean error or `None`).
pub fn choose_shapes(
    gpu: &Gpu,
    cases: &mut [Case],
    entry: &TechniqueEntry,
    values: &BTreeMap<String, ParamValue>,
    memory: &[u64],
    resolutions: &[u32],
    report: &mut dyn FnMut(u64, u32, Option<f64>),
) -> anyhow::Result<BTreeMap<u64, Shape>> {
    let mut shapes = BTreeMap::new();
    for &total in memory {
        let mut best: Option<Shape> = None;
        for &res in resolutions {
            let bytes = shadow::memory_per_texel(total, res).ok();
            let mut errors = Vec::new();
            for case in cases.iter_mut() {
                let Some(config) = bytes.and_then(|b| case.config(entry, values, b, Some(res)))
                else {
                    break;
                };
                errors.push(case.score(gpu, &config)?);
            }
            let mean = (errors.len() == cases.len() && !errors.is_empty())
                .then(|| errors.iter().sum::<f64>() / errors.len() as f64);
            report(total, res, mean);
            if let Some(m) = mean
                && best.is_none_or(|b| m < b.training)
            {
                best = Some(Shape {
                    resolution: res,
                    training: m,
                });
            }
        }
        if let Some(b) = best {
            shapes.insert(total, b);
        }
    }
    Ok(shapes)
}

/// Writes `tuned` and the chosen `shapes` (per technique) as a parameter file at `path`,
/// atomically.
pub fn write_params_file(
    path: &Path,
    record: TuneRecord,
    tuned: &[Tuned],
    shapes: &[(&str, BTreeMap<u64, Shape>)],
) -> anyhow::Result<()> {
    let mut record = record;
    let mut params = BTreeMap::new();
    for t in tuned {
        params.extend(t.chosen.clone());
        record.techniques.insert(
            t.technique.to_owned(),
            TechniqueRecord {
                start_training: t.start_training,
                chosen_training: t.chosen_training,
                start_held_out: t.start_held_out,
                chosen_held_out: t.chosen_held_out,
            },
        );
    }
    let file = ParamsFile {
        tune: Some(record),
        params,
        shapes: shapes
            .iter()
            .filter(|(_, s)| !s.is_empty())
            .map(|(technique, s)| {
                let by_memory = s.iter().map(|(total, s)| (total.to_string(), *s)).collect();
                ((*technique).to_owned(), by_memory)
            })
            .collect(),
    };
    let text = format!(
        "# Written by `smokeshadow tune` (src/tune/mod.rs describes the procedure). `--params \
         FILE` reads [params]; [tune] records how they were chosen: the command, the training and \
         held-out scenes, and each technique's mean RMS T error against exact there at its \
         starting values and at the chosen ones; [shapes] the map resolution chosen per \
         technique and memory budget (total bytes) on the training scenes, with its mean RMS \
         T error there.\n{}",
        toml::to_string(&file).context("cannot encode the parameter file")?
    );
    crate::output::write_atomic(path, text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn proposals_stay_in_range_whole_where_read_whole_and_at_3_digits() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        for (entry, spec) in shadow::all_params() {
            if spec.default.is_none() {
                continue;
            }
            for _ in 0..200 {
                let x = draw(spec, &mut rng);
                let y = perturb(spec, x, 0.25, &mut rng);
                for v in [x, y] {
                    assert!(spec.check(v).is_ok(), "{}: {} {v}", entry.name, spec.key);
                    if let Some((lo, hi)) = log_range(spec) {
                        assert!((lo..=hi).contains(&v), "{} {v}", spec.key);
                    }
                    if spec.integer || !spec.choices.is_empty() {
                        assert_eq!(v.fract(), 0.0, "{} {v}", spec.key);
                    } else {
                        assert_eq!(round_sig(v), v, "{} {v}", spec.key);
                    }
                }
            }
        }
        assert_eq!(round_sig(0.0123456), 0.0123);
        assert_eq!(round_sig(123.456), 123.0);
    }

    #[test]
    fn an_error_that_rises_with_the_budget_is_caught() {
        // dom on a held-out scene with the defaults before this check: 8, 16, 24 channels.
        assert!(!falls_with_budget(&[
            (16, 0.0029),
            (32, 0.0009),
            (48, 0.0013)
        ]));
        // Falling, flat, or within the bound's rounding room: kept (in any order given).
        assert!(falls_with_budget(&[
            (48, 0.0010),
            (12, 0.0040),
            (24, 0.0020)
        ]));
        assert!(falls_with_budget(&[
            (12, 0.0040),
            (24, 0.0040),
            (48, 0.0040)
        ]));
        assert!(falls_with_budget(&[(12, 0.0020), (24, 0.00215)]));
        assert!(!falls_with_budget(&[(12, 0.0020), (24, 0.0023)]));
        assert!(falls_with_budget(&[(12, 0.0020)]));
    }

    #[test]
    fn the_paper_set_is_in_range_and_files_are_checked_against_the_registry() {
        let paper = param_set("paper").unwrap();
        assert_eq!(paper.len(), PAPER.len());
        for (key, value) in &paper {
            assert!(shadow::find_param(key).unwrap().resolve(value).is_ok());
        }
        let dir = std::env::temp_dir().join(format!("smokeshadow-params-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let good = dir.join("good.toml");
        std::fs::write(&good, "[params]\nosm_interp = \"cubic\"\nmsm_bias = 1e-4\n").unwrap();
        let set = param_set(good.to_str().unwrap()).unwrap();
        assert_eq!(
            set,
            [
                ("msm_bias".to_owned(), ParamValue::Number(1e-4)),
                ("osm_interp".to_owned(), ParamValue::Choice("cubic".into())),
            ]
        );
        for (text, says) in [
            ("[params]\nmsm_bias = 9.0\n", "out of range"),
            ("[params]\nfancy = 1\n", "unknown technique parameter"),
            ("[extra]\nx = 1\n", "unknown field"),
            ("params = 3", "invalid type"),
        ] {
            let bad = dir.join("bad.toml");
            std::fs::write(&bad, text).unwrap();
            let err = param_set(bad.to_str().unwrap()).unwrap_err();
            assert!(
                err.starts_with("--params ") && err.contains(says) && !err.contains('\n'),
                "{text}: {err}"
            );
        }
        let err = param_set("/nonexistent/p.toml").unwrap_err();
        assert!(err.contains("cannot read"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
