// `tmsm` build: each fragment adds its optical depth a to b0 and a·E[e^{ikφ}] to trigonometric
// moment k (additive blending, no sort), φ = d(2π − θ) over the splat: at a point e^{ikφ}, over
// a segment [φ0, φ1] the mean e^{ikφm}·sinc(kΔ/2) with φm its middle and Δ its length.
#import shadow/layered_build.wgsl
#import shadow/tmsm.wgsl
#import shadow/channels_build.wgsl

fn prepare_values(splat: Splat, pixel: vec2<f32>) -> array<f32, 32> {
    var c: array<f32, 32>;
    let a = splat.optical_depth;
    c[0] = a;
    let span = 2.0 * PI - layered.wrapping_zone_rad;
    let phi0 = clamp(splat.z0, 0.0, 1.0) * span;
    let phi1 = clamp(splat.z1, 0.0, 1.0) * span;
    let mid = 0.5 * (phi0 + phi1);
    let half = 0.5 * (phi1 - phi0);
    // e^{ik·mid} and sin(k·half) by rotating through e^{i·mid} and e^{i·half}: one cos and one
    // sin each for all moments.
    let turn_mid = c_polar(1.0, mid);
    let turn_half = c_polar(1.0, half);
    var at_mid = turn_mid;
    var at_half = turn_half;
    // Written out over the budget's LAYERED_COUNT moments (constant indices: registers).
    #unroll j 0..LAYERED_COUNT
        let k = j + 1u;
        let x = f32(k) * half;
        let sinc = select(at_half.y / x, 1.0, abs(x) < 1e-4);
        let v = a * sinc * at_mid;
        c[2u * k - 1u] = v.x;
        c[2u * k] = v.y;
        at_mid = c_mul(at_mid, turn_mid);
        at_half = c_mul(at_half, turn_half);
    #end_unroll
    return c;
}

//{{BUILD_OUTPUTS}}
