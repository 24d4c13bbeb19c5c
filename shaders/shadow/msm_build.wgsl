// `msm` build: each fragment adds its optical depth a to b0 and a·E[z^k] to power moment k
// (additive blending, no sort), z = 2d − 1 over the splat: z^k at a point, and over a segment
// [x0, x1] the mean Σ_j x0^j x1^(k−j) / (k + 1) (no cancellation for short chords).
#import shadow/layered_build.wgsl
#import shadow/msm.wgsl
#import shadow/channels_build.wgsl

fn prepare_values(splat: Splat, pixel: vec2<f32>) -> array<f32, 32> {
    var c: array<f32, 32>;
    let a = splat.optical_depth;
    c[0] = a;
    let x0 = 2.0 * clamp(splat.z0, 0.0, 1.0) - 1.0;
    let x1 = 2.0 * clamp(splat.z1, 0.0, 1.0) - 1.0;
    // h_k = Σ_j x0^j x1^(k−j) = x1·h_(k−1) + x0^k.
    var h = 1.0;
    var x0k = 1.0;
    // Written out over the budget's LAYERED_COUNT moments (constant indices: registers).
    #unroll j 0..LAYERED_COUNT
        let k = j + 1u;
        x0k *= x0;
        h = x1 * h + x0k;
        c[k] = a * h / f32(k + 1u);
    #end_unroll
    return c;
}

//{{BUILD_OUTPUTS}}
