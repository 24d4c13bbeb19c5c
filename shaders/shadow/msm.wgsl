// `msm` lookup: b0 and N power moments b0·E[z^k] of the depth z = 2d − 1 (channels 0..N); the
// optical depth in front of the point is bounded by the Hamburger moment problem
// (moments.wgsl), T = clamp(exp(−b0·A), 0, 1).
#import shadow/layered_channels.wgsl
#import shadow/moments.wgsl

fn msm_setting() -> MomentSetting {
    return MomentSetting(
        false,
        layered.moment_bias,
        layered.moment_overestimation,
        0.0,
        layered.moment_bias_target,
    );
}

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    return moment_map_transmittance(p, msm_setting());
}
