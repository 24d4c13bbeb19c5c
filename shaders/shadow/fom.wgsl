// `fom` and `fom_sigma` lookup: Fourier opacity maps (Jansen & Bavoil 2010, thesis 3.3.3.5).
// The extinction along each light ray, over normalised depth d in [0, 1], is stored as Fourier
// coefficients a0, a1..an, b1..bn (channels 0, 1..n, n+1..2n). The optical depth in front of d is
// Ω(d) = a0/2·d + Σ a_k/(2πk)·sin(2πkd) + Σ b_k/(2πk)·(1 - cos(2πkd)), T = clamp(exp(-Ω), 0, 1).
// With `sigma`, harmonic k is damped by the Lanczos factor sinc(k/(n+1)) against ringing.
#import shadow/layered.wgsl

const TAU: f32 = 6.28318530717959;

fn lanczos_sigma(k: u32) -> f32 {
    if layered.sigma == 0u {
        return 1.0;
    }
    let x = PI * f32(k) / f32(layered.count + 1u);
    return sin(x) / x;
}

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    let l = light_coords(p);
    if !l.inside {
        return 1.0;
    }
    var c: array<f32, 32>;
    let targets = (layered.packed + 3u) / 4u;
    for (var t = 0u; t < targets; t++) {
        let v = layered_target(t, l.uv);
        c[4u * t] = v.x;
        c[4u * t + 1u] = v.y;
        c[4u * t + 2u] = v.z;
        c[4u * t + 3u] = v.w;
    }
    let d = clamp(l.depth01, 0.0, 1.0);
    let n = layered.count;
    var omega = 0.5 * c[0] * d;
    for (var k = 1u; k <= n; k++) {
        let w = TAU * f32(k);
        omega += lanczos_sigma(k) * (c[k] * sin(w * d) + c[n + k] * (1.0 - cos(w * d))) / w;
    }
    return clamp(exp(-omega), 0.0, 1.0);
}
