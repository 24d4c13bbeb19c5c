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
//! η (towards darkening) of each family, and `tmsm`'s wrapping zone θ.
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
    default: Some(2.6e-6),
    choices: &[],
    integer: false,
    tuned: true,
};

/// `msm_overestimation`: η for power moments.
pub const OVERESTIMATION: ParamSpec = ParamSpec {
    key: "msm_overestimation",
    unit: "-",
    doc: "share of the weight at the receiver's own depth counted as in front of it: 0 is the \
          lower bound of the optical depth (light leaks), 1 the upper bound (too dark)",
    min: 0.0,
    max: 1.0,
    // chosen by `smokeshadow tune` on the training scenes (docs/tuned_params.toml) (the papers: 0.25).
    default: Some(0.428),
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
    build_shader: "shadow/msm_build.wgsl",
    plan: power_plan,
    depth_channel: false,
    layer_thickness: None,
    layer_ratio: None,
    interp: None,
    start_dilation: None,
    sigma: false,
    moments: Some(MomentParams {
        bias: &BIAS,
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
    build_shader: "shadow/tmsm_build.wgsl",
    plan: trig_plan,
    moments: Some(MomentParams {
        bias: &TRIG_BIAS,
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
    in_default_sweep: true,
    in_default_compare: true,
    build_reads_back: false,
    params: &[BIAS, OVERESTIMATION],
    // Additive, so independent of the draw order up to the f32 sums' rounding; but the
    // Hankel matrix of 8 power moments amplifies that rounding past the shared 5e-3 bound at a
    // few ill-conditioned texels (measured: T moved by 0.53 at 1 of 10,249 points when the order
    // reversed, point splats). tests/moments.rs holds it to its own, measured bound instead.
    order_independent: false,
    // The bound brackets T rather than converging to it (a uniform chord stays a few steps).
    converges_with_budget: false,
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
    params: &[TRIG_BIAS, TRIG_OVERESTIMATION, WRAPPING_ZONE],
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
