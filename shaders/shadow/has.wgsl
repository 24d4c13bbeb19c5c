// `has` lookup: half-angle slicing (Kniss et al. 2003; Green 2008; thesis 3.3.3.3).
// The light buffer holds the optical depth accumulated, along each light ray, by the particle
// batches drawn so far (during the particle pass: the batches nearer the light along the
// half-angle axis; for the opaque pass: all of them). T = exp(-Ω) at the point's light texel;
// there is no depth: which batches are "in front" is decided by the slicing order.
// Keep `HasParams` in sync with src/shadow/half_angle.rs.
#import common/lighting.wgsl

struct HasParams {
    // Slices (batches) S.
    slices: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
};

@group(1) @binding(0) var<uniform> has: HasParams;
@group(1) @binding(1) var has_sampler: sampler;
@group(1) @binding(2) var has_light: texture_2d<f32>;

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    let l = light_coords(p);
    if !l.inside {
        return 1.0;
    }
    return exp(-textureSampleLevel(has_light, has_sampler, l.uv, 0.0).r);
}
