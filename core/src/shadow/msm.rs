//! `msm` and `tmsm`: moment-based transmittance maps (Münstermann, Krumpen, Klein & Peters,
//! "Moment-Based Order-Independent Transparency", I3D 2018; Peters, Münstermann, Wetzstein &
//! Klein, "Improved Moment Shadow Maps for Translucent Occluders, Soft Shadows and Single
//! Scattering", JCGT 6(1), 2017).
//!
//! One additive pass, order independent, in 32-bit floats (as `fom`): every light-space fragment
//! adds its optical depth a to b0 and a times its depth's basis functions to the moments, with
//! the depth normalised to the frame's smoke bounds. A point splat adds them at the particle
//! centre's depth; a segment splat adds their mean over its chord, in closed form (power:
//! Σ_j x0^j x1^(k−j) / (k + 1); trigonometric: e^{ikφm} sinc(kΔφ/2)).
//! - `msm`: power moments z^k, z ∈ [−1, 1], k = 1..N, N the largest of 4, 6, 8 that fits B − 1
//!   channels (5, 7 or 9 channels; a larger budget buys nothing more).
//! - `tmsm`: trigonometric moments e^{ikφ}, φ ∈ [0, 2π − θ], k = 1..M, M = floor((B − 1)/2)
//!   up to 4 (2M + 1 channels: b0, then the real and imaginary part of each).
//!
//! The lookup bounds the optical depth in front of the point from the moments (the Hamburger or
//! Toeplitz moment problem, [`super::moment_math`], its CPU mirror, has the derivation) and
//! returns T = clamp(exp(−b0·A), 0, 1). The kernel polynomial has degree N/2 or M, at most 4,
//! whose roots have a closed form; that is why neither family grows past 9 channels here, as in
//! the authors' own code. Parameters: the bias β (towards light leaking) and the overestimation
//! η (towards darkening) of each family, and `tmsm`'s wrapping zone θ. β pulls the moments
//! towards the uniform distribution's (`msm_bias`, `tmsm_bias`, tuned), or with
//! `msm_bias_table = paper` / `tmsm_bias_table = paper` (what `--params paper` sets) by the
//! authors' β per moment count towards their fixed bias vectors ([`PAPER_BIAS`]).
//! Shaders: `shaders/shadow/msm.wgsl`, `tmsm.wgsl` (lookups), `msm_build.wgsl`,
//! `tmsm_build.wgsl` and the shared `moments.wgsl`.

use super::layered::{
    ChannelPlan, Layered, LayeredSpec, MomentParams, PARAMS_BYTES, Precision, PrecisionSpec,
};
use super::{
    MapKind, MemoryCase, MemoryUse, ParamSpec, Role, TechniqueEntry, packed_bytes_per_texel,
};

/// `msm_bias`: β for power moments.
pub const BIAS: ParamSpec = ParamSpec {
    key: "msm_bias",
    unit: "-",
    doc: "how far the power moments are pulled towards those of a uniform distribution before \
          the reconstruction: more keeps the 32-bit arithmetic stable, and blurs the ray's \
          smoke over its whole depth range (less accurate)",
    min: 0.0,
    max: 0.5,
    // chosen by `smokeshadow tune` on the training scenes (docs/tuned_params.toml); the moment-based
    // OIT papers use 5e-7 to 5e-5 for 4 to 8 single-float moments (`--params paper`).
    default: Some(1.57e-6),
    choices: &[],
    integer: false,
    tuned: true,
};

/// `msm_bias_table`: one β towards the uniform distribution's moments, or the authors' table.
pub const BIAS_TABLE: ParamSpec = ParamSpec {
    key: "msm_bias_table",
    unit: "-",
    doc: "one: β = msm_bias for every moment count, pulling towards the uniform distribution's \
          moments; paper: the moment-based OIT authors' β per moment count and their fixed bias \
          vectors (single-float moments: `--params paper` chooses it)",
    min: 0.0,
    max: 1.0,
    default: Some(0.0),
    choices: &["one", "paper"],
    integer: false,
    tuned: false,
};

/// `tmsm_bias_table`: one β, or the authors' β per trigonometric moment count.
pub const TRIG_BIAS_TABLE: ParamSpec = ParamSpec {
    key: "tmsm_bias_table",
    doc: "one: β = tmsm_bias for every moment count; paper: the moment-based OIT authors' β per \
          moment count (single-float moments; trigonometric moments are scaled by 1 − β, \
          towards no vector: `--params paper` chooses it)",
    ..BIAS_TABLE
};

pub use super::moment_math::{PAPER_BIAS, PaperBias, paper_bias};

/// `msm_overestimation`: η for power moments.
pub const OVERESTIMATION: ParamSpec = ParamSpec {
    key: "msm_overestimation",
    unit: "-",
    doc: "share of the weight at the receiver's own depth counted as in front of it: 0 is the \
          lower bound of the optical depth (light leaks), 1 the upper bound (too dark)",
    min: 0.0,
    max: 1.0,
    // chosen by `smokeshadow tune` on the training scenes (docs/tuned_params.toml) (the papers: 0.25).
    default: Some(0.41),
    choices: &[],
    integer: false,
    tuned: true,
};

/// `tmsm_bias`: β for trigonometric moments.
pub const TRIG_BIAS: ParamSpec = ParamSpec {
    key: "tmsm_bias",
    doc: "how far the trigonometric moments are pulled towards those of a uniform distribution \
          (scaled by 1 − β) before the reconstruction: more keeps the 32-bit arithmetic \
          stable, and blurs the ray's smoke over its whole depth range (less accurate)",
    // chosen by `smokeshadow tune` on the training scenes (docs/tuned_params.toml).
    default: Some(4.11e-4),
    ..BIAS
};

/// `tmsm_overestimation`: η for trigonometric moments.
pub const TRIG_OVERESTIMATION: ParamSpec = ParamSpec {
    key: "tmsm_overestimation",
    // chosen by `smokeshadow tune` on the training scenes (docs/tuned_params.toml) (the papers: 0.25).
    default: Some(0.4),
    ..OVERESTIMATION
};

/// `tmsm_wrapping_zone_rad`: θ.
pub const WRAPPING_ZONE: ParamSpec = ParamSpec {
    key: "tmsm_wrapping_zone_rad",
    unit: "rad",
    doc: "the arc of the circle between the far and the near end of the depth range; a root \
          there counts as partly in front (a ramp across it)",
    min: 0.01,
    max: 3.0,
    // chosen by `smokeshadow tune` on the training scenes (docs/tuned_params.toml) (the papers: 0.1π).
    default: Some(0.257),
    choices: &[],
    integer: false,
    tuned: true,
};

/// Power moments: N = 4, 6 or 8, the largest that fits B − 1; b0, b1..bN.
fn power_plan(channels: u32) -> ChannelPlan {
    let moments = match channels {
        9.. => 8,
        7..=8 => 6,
        _ => 4,
    };
    ChannelPlan {
        count: moments,
        packed: moments + 1,
        used: moments + 1,
    }
}

/// Trigonometric moments: M = floor((B − 1)/2) up to 4; b0, then (Re, Im) of b1..bM.
fn trig_plan(channels: u32) -> ChannelPlan {
    let moments = ((channels - 1) / 2).min(4);
    ChannelPlan {
        count: moments,
        packed: 2 * moments + 1,
        used: 2 * moments + 1,
    }
}

/// The used channels in 32-bit floats and the parameter uniform.
fn memory(plan: fn(u32) -> ChannelPlan) -> impl Fn(&MemoryCase<'_>) -> MemoryUse {
    move |c| {
        let used = u64::from(plan(c.channels().max(5)).used);
        MemoryUse {
            channels: used,
            bytes: c.texels() * packed_bytes_per_texel(used, 4) + PARAMS_BYTES,
            transient_bytes: 0,
        }
    }
}

pub const MSM: LayeredSpec = LayeredSpec {
    name: "msm",
    max_channels: super::MAX_CHANNELS,
    build_shader: "shadow/msm_build.wgsl",
    plan: power_plan,
    depth_channel: false,
    layer_thickness: None,
    layer_growth: None,
    interp: None,
    start_dilation: None,
    sigma: false,
    moments: Some(MomentParams {
        bias: &BIAS,
        bias_table: &BIAS_TABLE,
        overestimation: &OVERESTIMATION,
        wrapping_zone: None,
    }),
    precision: PrecisionSpec::Fixed(Precision::Single),
    channel_name: |c, _| match c {
        0 => "b0 (the optical depth along the ray)".to_owned(),
        k => format!("b0·E[z^{k}] (power moment {k})"),
    },
    map_kind: MapKind::Signed,
};

pub const TMSM: LayeredSpec = LayeredSpec {
    name: "tmsm",
    max_channels: super::MAX_CHANNELS,
    build_shader: "shadow/tmsm_build.wgsl",
    plan: trig_plan,
    moments: Some(MomentParams {
        bias: &TRIG_BIAS,
        bias_table: &TRIG_BIAS_TABLE,
        overestimation: &TRIG_OVERESTIMATION,
        wrapping_zone: Some(&WRAPPING_ZONE),
    }),
    channel_name: |c: u32, _| match c {
        0 => "b0 (the optical depth along the ray)".to_owned(),
        c if c % 2 == 1 => {
            let k = c.div_ceil(2);
            format!("b0·E[cos {k}φ] (trigonometric moment {k}, real part)")
        }
        c => format!(
            "b0·E[sin {}φ] (trigonometric moment {}, imaginary part)",
            c / 2,
            c / 2
        ),
    },
    ..MSM
};

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: MSM.name,
    description: "moment shadow maps: b0 and 4, 6 or 8 power moments of the depth, bounded by \
                  the Hamburger moment problem",
    role: Role::Contender,
    budget_caption: |channels| {
        let plan = power_plan(channels.max(5));
        format!("{} power moments ({} channels)", plan.count, plan.used)
    },
    min_channels: 5,
    max_channels: MSM.max_channels,
    in_default_sweep: true,
    in_default_compare: true,
    build_reads_back: false,
    params: &[BIAS, OVERESTIMATION, BIAS_TABLE],
    // Additive, so independent of the draw order up to the f32 sums' rounding; but the
    // Hankel matrix of 8 power moments amplifies that rounding past the shared 5e-3 bound at a
    // few ill-conditioned texels (measured: T moved by 0.53 at 1 of 10,249 points when the order
    // reversed, point splats). tests/moments.rs holds it to its own, measured bound instead.
    order_independent: false,
    // The bound brackets T rather than converging to it (a uniform chord stays a few steps).
    converges_with_budget: false,
    converges_from: 1,
    compresses_captured_lists: false,
    memory: |c| memory(power_plan)(c),
    lookup_shader: "shadow/msm.wgsl",
    lookup_constants: |p| super::layered::lookup_constants(&MSM, p),
    extra_shaders: || MSM.all_build_shaders(),
    create: |ctx, params| Ok(Box::new(Layered::new(ctx, &MSM, params)?)),
    uses_splat: true,
    uses_budget: true,
    owns_particle_pass: false,
    volume: super::VolumeSupport::Shadows,
    shadows_particles: true,
};

pub const TRIG_ENTRY: TechniqueEntry = TechniqueEntry {
    name: TMSM.name,
    description: "trigonometric moment shadow maps: b0 and 2 to 4 trigonometric moments of the \
                  depth, bounded by the Toeplitz moment problem",
    budget_caption: |channels| {
        let plan = trig_plan(channels.max(5));
        format!(
            "{} trigonometric moments ({} channels)",
            plan.count, plan.used
        )
    },
    params: &[
        TRIG_BIAS,
        TRIG_OVERESTIMATION,
        WRAPPING_ZONE,
        TRIG_BIAS_TABLE,
    ],
    memory: |c| memory(trig_plan)(c),
    lookup_shader: "shadow/tmsm.wgsl",
    lookup_constants: |p| super::layered::lookup_constants(&TMSM, p),
    extra_shaders: || TMSM.all_build_shaders(),
    create: |ctx, params| Ok(Box::new(Layered::new(ctx, &TMSM, params)?)),
    // The Toeplitz matrix of trigonometric moments is well conditioned: the shared bound holds.
    order_independent: true,
    ..ENTRY
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_paper_table_is_the_authors_released_values() {
        // Typed in from the released code (MomentOIT.hlsli `resolveMoments`; the β per count
        // and precision of its demo's `updateMomentMode`): (trigonometric, moments, bits, β,
        // bias vector).
        let source: [(bool, u32, u32, f32, &[f64]); 12] = [
            (false, 4, 32, 5e-7, &[0.0, 0.375, 0.0, 0.375]),
            (false, 6, 32, 5e-6, &[0.0, 0.48, 0.0, 0.451, 0.0, 0.45]),
            (
                false,
                8,
                32,
                5e-5,
                &[
                    0.0,
                    0.75,
                    0.0,
                    0.676666666666666,
                    0.0,
                    0.63,
                    0.0,
                    0.600303030303030,
                ],
            ),
            (true, 2, 32, 4e-7, &[]),
            (true, 3, 32, 8e-7, &[]),
            (true, 4, 32, 1.5e-6, &[]),
            (false, 4, 16, 6e-5, &[0.0, 0.628, 0.0, 0.628]),
            (
                false,
                6,
                16,
                6e-4,
                &[0.0, 0.5566, 0.0, 0.489, 0.0, 0.47869382],
            ),
            (
                false,
                8,
                16,
                2.5e-3,
                &[
                    0.0,
                    0.424749163879598,
                    0.0,
                    0.224078026755852,
                    0.0,
                    0.153692307692307,
                    0.0,
                    0.129004405290891,
                ],
            ),
            (true, 2, 16, 4e-4, &[]),
            (true, 3, 16, 6.5e-4, &[]),
            (true, 4, 16, 8.5e-4, &[]),
        ];
        assert_eq!(PAPER_BIAS.len(), source.len());
        for (row, (trig, moments, bits, bias, vector)) in PAPER_BIAS.iter().zip(source) {
            assert_eq!(
                (row.trigonometric, row.moments, row.bits, row.bias),
                (trig, moments, bits, bias)
            );
            assert_eq!(row.vector.len(), vector.len());
            for (a, b) in row.vector.iter().zip(vector) {
                assert!((a - b).abs() < 1e-12, "{row:?}");
            }
        }
        // Every count either family uses has its single-float row.
        for m in [4, 6, 8] {
            assert_eq!(paper_bias(false, m).unwrap().vector.len(), m as usize);
        }
        for m in [2, 3, 4] {
            assert!(paper_bias(true, m).unwrap().vector.is_empty());
        }
    }

    #[test]
    fn the_paper_table_sets_each_counts_bias_and_vector() {
        use super::super::layered::moment_bias;
        use crate::shadow::{ParamValue, TechniqueParams, set_param};
        let mut params = TechniqueParams::new(24, 512);
        // By default: msm_bias towards the uniform distribution's moments.
        let (bias, target) = moment_bias(&MSM, &params, 8);
        assert_eq!(bias, BIAS.default.unwrap());
        assert_eq!(target, [1.0 / 3.0, 1.0 / 5.0, 1.0 / 7.0, 1.0 / 9.0]);
        for (key, value) in [("msm_bias_table", "paper"), ("tmsm_bias_table", "paper")] {
            set_param(&mut params, key, &ParamValue::Choice(value.to_owned())).unwrap();
        }
        let f = |v: f64| v as f32;
        assert_eq!(
            moment_bias(&MSM, &params, 4),
            (5e-7, [0.375, 0.375, 0.0, 0.0])
        );
        assert_eq!(
            moment_bias(&MSM, &params, 6),
            (5e-6, [0.48, 0.451, 0.45, 0.0])
        );
        assert_eq!(
            moment_bias(&MSM, &params, 8),
            (
                5e-5,
                [
                    0.75,
                    f(0.676_666_666_666_666_6),
                    0.63,
                    f(0.600_303_030_303_030_3)
                ]
            )
        );
        // Trigonometric moments: β per count, towards no vector.
        for (m, b) in [(2, 4e-7), (3, 8e-7), (4, 1.5e-6)] {
            assert_eq!(moment_bias(&TMSM, &params, m), (b, [0.0; 4]));
        }
    }

    #[test]
    fn budgets_buy_the_moments_the_issue_names() {
        let power = |b| power_plan(b).count;
        assert_eq!(
            [power(5), power(6), power(7), power(8), power(9), power(24)],
            [4, 4, 6, 6, 8, 8]
        );
        assert_eq!(power_plan(24).used, 9);
        let trig = |b| trig_plan(b).count;
        assert_eq!(
            [trig(5), trig(6), trig(7), trig(8), trig(9), trig(24)],
            [2, 2, 3, 3, 4, 4]
        );
        assert_eq!(trig_plan(8).used, 7);
    }
}
