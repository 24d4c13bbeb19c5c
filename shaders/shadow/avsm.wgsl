// `avsm` lookup: adaptive volumetric shadow maps (Salvi, Vidimče, Lauritzen & Lefohn 2010).
// Each texel keeps N = floor(B / 2) nodes (z, T(z)) of its transmittance, built by
// shaders/shadow/avsm_build.wgsl; T is linear between nodes, 1 in front of the first and the
// last node's value behind the last. The four texels around a point are blended bilinearly in T.
#import shadow/deep_nodes.wgsl

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    let l = light_coords(p);
    if !l.inside {
        return 1.0;
    }
    return clamp(deep_blended_value(l, 1.0), 0.0, 1.0);
}
