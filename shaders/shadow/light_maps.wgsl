// Shared lookup side of the light-maps techniques (src/shadow/light_maps.rs): their parameters
// and a sampler. Each technique declares its maps at bindings 2.. itself and evaluates T per
// texel of `bilinear_taps` (common/lighting.wgsl) before blending: a texel without smoke must
// read as T = 1, which filtering the stored depths would not give. Keep `LightMapsParams` in
// sync.
#import common/lighting.wgsl

struct LightMapsParams {
    // The technique's parameters, in the order of `LightMapsSpec::lookup_params`.
    values: vec4<f32>,
};

@group(1) @binding(0) var<uniform> light_maps: LightMapsParams;
@group(1) @binding(1) var light_maps_sampler: sampler;
