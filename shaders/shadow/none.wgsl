// `none`: no self-shadowing, T = 1 everywhere. The frame-time baseline for overhead ratios.

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    return 1.0;
}
