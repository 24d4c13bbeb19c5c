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
    return exp(-deep_blended_value(l, 0.0));
}
