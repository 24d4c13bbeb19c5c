// `fom` and `fom_sigma` lookup: Fourier opacity maps (Jansen & Bavoil 2010, thesis 3.3.3.5).
// The extinction along each light ray, over normalised depth d in [0, 1], is stored as Fourier
// coefficients a0, a1..an, b1..bn (channels 0, 1..n, n+1..2n). The optical depth in front of d is
// Ω(d) = a0/2·d + Σ a_k/(2πk)·sin(2πkd) + Σ b_k/(2πk)·(1 - cos(2πkd)), T = clamp(exp(-Ω), 0, 1).
// With `sigma`, harmonic k is damped by the Lanczos factor sinc(k/(n+1)) against ringing.
#import shadow/layered_channels.wgsl

const TAU: f32 = 6.28318530717959;

fn lanczos_sigma(k: u32) -> f32 {
    if layered.sigma == 0u {
        return 1.0;
    }
    let x = PI * f32(k) / f32(layered.count + 1u);
    return sin(x) / x;
}

// The angle-sum formula: (cos(a + b), sin(a + b)) from (cos a, sin a) and (cos b, sin b).
fn rotate(a: vec2<f32>, b: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(a.x * b.x - a.y * b.y, a.y * b.x + a.x * b.y);
}

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    let l = light_coords(p);
    if !l.inside {
        return 1.0;
    }
    var c = layered_channels(l.uv);
    let d = clamp(l.depth01, 0.0, 1.0);
    var omega = 0.5 * c[0] * d;
    // (cos 2πkd, sin 2πkd) by rotating through 2πd: one cos and one sin for all harmonics.
    let turn = vec2<f32>(cos(TAU * d), sin(TAU * d));
    var cs = turn;
    // Harmonic k = j + 1 of LAYERED_COUNT (n), written out so that every channel index is a
    // constant (on llvmpipe this halved the opaque pass's lookups at 24 channels).
    #unroll j 0..LAYERED_COUNT
        let k = j + 1u;
        omega += lanczos_sigma(k) * (c[k] * cs.y + c[LAYERED_COUNT + k] * (1.0 - cs.x)) / (TAU * f32(k));
        cs = rotate(cs, turn);
    #end_unroll
    return clamp(exp(-omega), 0.0, 1.0);
}
