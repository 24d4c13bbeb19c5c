// `fom` build: each fragment adds its harmonics (additive blending, no sort). A point splat at
// depth d adds a_k = 2·od·cos(2πkd), b_k = 2·od·sin(2πkd); a segment splat over [z0, z1] adds the
// same integrated analytically over the segment (uniform density along the chord).
#import shadow/layered_build.wgsl
#import shadow/fom.wgsl

// Coefficient held in packed channel `channel`.
fn fom_coefficient(splat: Splat, channel: u32) -> f32 {
    let n = layered.count;
    if channel == 0u {
        return 2.0 * splat.optical_depth;
    }
    if channel > 2u * n {
        return 0.0;
    }
    let is_b = channel > n;
    let k = select(channel, channel - n, is_b);
    let w = TAU * f32(k);
    let width = splat.z1 - splat.z0;
    if width <= 1e-6 {
        let z = 0.5 * (splat.z0 + splat.z1);
        return 2.0 * splat.optical_depth * select(cos(w * z), sin(w * z), is_b);
    }
    // Mean of cos / sin over the segment.
    let mean_cos = (sin(w * splat.z1) - sin(w * splat.z0)) / (w * width);
    let mean_sin = (cos(w * splat.z0) - cos(w * splat.z1)) / (w * width);
    return 2.0 * splat.optical_depth * select(mean_cos, mean_sin, is_b);
}

fn target_values(splat: Splat, index: u32, pixel: vec2<f32>) -> vec4<f32> {
    let c = index * 4u;
    return vec4<f32>(
        fom_coefficient(splat, c),
        fom_coefficient(splat, c + 1u),
        fom_coefficient(splat, c + 2u),
        fom_coefficient(splat, c + 3u),
    );
}

//{{BUILD_OUTPUTS}}
