// `msm` lookup: b0 and N power moments b0·E[z^k] of the depth z = 2d − 1 (channels 0..N); the
// optical depth in front of the point is bounded by the Hamburger moment problem
// (moments.wgsl), T = clamp(exp(−b0·A), 0, 1).
#import shadow/layered.wgsl
#import shadow/moments.wgsl

fn msm_setting() -> MomentSetting {
    return MomentSetting(layered.count / 2u, false, layered.moment_bias, layered.moment_overestimation, 0.0);
}

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    let l = light_coords(p);
    if !l.inside {
        return 1.0;
    }
    var c = layered_channels(l.uv);
    var weighted: array<vec2<f32>, 9>;
    for (var k = 1u; k <= layered.count; k++) {
        weighted[k] = vec2<f32>(c[k], 0.0);
    }
    return moment_transmittance(msm_setting(), c[0], weighted, l.depth01);
}
