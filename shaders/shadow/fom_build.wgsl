// `fom` build: each fragment adds its harmonics (additive blending, no sort). A point splat at
// depth d adds a_k = 2·od·cos(2πkd), b_k = 2·od·sin(2πkd); a segment splat over [z0, z1] adds the
// same averaged analytically over the segment (uniform density along the chord). Channels beyond
// 2n + 1 in the last target get 0.
#import shadow/layered_build.wgsl
#import shadow/fom.wgsl
#import shadow/channels_build.wgsl

// Every coefficient this fragment adds, in packed-channel order (a0, a1..an, b1..bn), with the
// sines and cosines of the harmonics by rotation (`rotate` in fom.wgsl).
fn prepare_values(splat: Splat, pixel: vec2<f32>) -> array<f32, 32> {
    var c: array<f32, 32>;
    let od2 = 2.0 * splat.optical_depth;
    c[0] = od2;
    let width = splat.z1 - splat.z0;
    if width <= 1e-6 {
        let z = 0.5 * (splat.z0 + splat.z1);
        let turn = vec2<f32>(cos(TAU * z), sin(TAU * z));
        var cs = turn;
        // Written out over the budget's LAYERED_COUNT harmonics (constant indices: registers).
        #unroll j 0..LAYERED_COUNT
            c[j + 1u] = od2 * cs.x;
            c[LAYERED_COUNT + j + 1u] = od2 * cs.y;
            cs = rotate(cs, turn);
        #end_unroll
        return c;
    }
    // Mean of cos / sin of 2πkz over [z0, z1]: (sin 2πkz1 - sin 2πkz0) / (2πk·width) and
    // (cos 2πkz0 - cos 2πkz1) / (2πk·width).
    let turn0 = vec2<f32>(cos(TAU * splat.z0), sin(TAU * splat.z0));
    let turn1 = vec2<f32>(cos(TAU * splat.z1), sin(TAU * splat.z1));
    var cs0 = turn0;
    var cs1 = turn1;
    #unroll j 0..LAYERED_COUNT
        let k = j + 1u;
        let scale = od2 / (TAU * f32(k) * width);
        c[k] = scale * (cs1.y - cs0.y);
        c[LAYERED_COUNT + k] = scale * (cs0.x - cs1.x);
        cs0 = rotate(cs0, turn0);
        cs1 = rotate(cs1, turn1);
    #end_unroll
    return c;
}

//{{BUILD_OUTPUTS}}
