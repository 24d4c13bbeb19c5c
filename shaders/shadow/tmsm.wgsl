// `tmsm` lookup: b0 and M trigonometric moments b0·E[e^{ikφ}] of the depth's angle
// φ = d(2π − θ) (channels 0, then the real and imaginary part of each); the optical depth in
// front of the point is bounded by the Toeplitz moment problem (moments.wgsl),
// T = clamp(exp(−b0·A), 0, 1).
#import shadow/layered_channels.wgsl
#import shadow/moments.wgsl

fn tmsm_setting() -> MomentSetting {
    return MomentSetting(
        true,
        layered.moment_bias,
        layered.moment_overestimation,
        layered.wrapping_zone_rad,
        layered.moment_bias_target,
    );
}

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    return moment_map_transmittance(p, tmsm_setting());
}
