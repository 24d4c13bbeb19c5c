// Shared lookup side of the light-maps techniques (src/shadow/light_maps.rs): their parameters,
// a sampler, and the bilinear footprint through which each technique evaluates T per texel
// (a texel without smoke must read as T = 1, which filtering the stored depths would not give).
// Each technique declares its maps at bindings 2.. itself. Keep `LightMapsParams` in sync.
#import common/lighting.wgsl

struct LightMapsParams {
    // The technique's parameters, in the order of `LightMapsSpec::lookup_params`.
    values: vec4<f32>,
};

@group(1) @binding(0) var<uniform> light_maps: LightMapsParams;
@group(1) @binding(1) var light_maps_sampler: sampler;

// The four texels around `uv` in a `size` map and their bilinear weights.
struct Footprint {
    texels: array<vec2<i32>, 4>,
    weights: vec4<f32>,
};

fn footprint(uv: vec2<f32>, size: vec2<u32>) -> Footprint {
    var out: Footprint;
    let st = uv * vec2<f32>(size) - vec2<f32>(0.5);
    let base = floor(st);
    let f = st - base;
    let b = vec2<i32>(base);
    let last = vec2<i32>(size) - vec2<i32>(1);
    out.texels[0] = clamp(b, vec2<i32>(0), last);
    out.texels[1] = clamp(b + vec2<i32>(1, 0), vec2<i32>(0), last);
    out.texels[2] = clamp(b + vec2<i32>(0, 1), vec2<i32>(0), last);
    out.texels[3] = clamp(b + vec2<i32>(1, 1), vec2<i32>(0), last);
    out.weights = vec4<f32>((1.0 - f.x) * (1.0 - f.y), f.x * (1.0 - f.y), (1.0 - f.x) * f.y, f.x * f.y);
    return out;
}
