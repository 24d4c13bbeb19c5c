// `dsm` lookup: the deep shadow map of Lokovic & Veach (2000) under a channel budget. Each texel
// keeps N = floor(B / 2) nodes (z, Ω(z)) of its optical depth, fitted within a per-texel
// tolerance ε by the build (shaders/shadow/dsm_build.wgsl); Ω is linear between nodes, 0 in
// front of the first and the last node's value behind the last. Like `exact`, the four texels
// around a point are evaluated separately, their Ω blended bilinearly, T = exp(-Ω).
#import shadow/deep_nodes.wgsl

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    let l = light_coords(p);
    if !l.inside {
        return 1.0;
    }
    var taps = bilinear_taps(l.uv, vec2<i32>(i32(deep.resolution)));
    var omega = 0.0;
    for (var i = 0; i < 4; i++) {
        omega += taps.weights[i] * deep_texel_value(taps.texels[i], l.dist_m, 0.0);
    }
    return exp(-omega);
}
