// Shared lookup side of the layered techniques (osm, dom, fom): their parameters and up to 8
// packed map targets, 4 channels each. Channel c lives in target c / 4, component c % 4.
// Keep `LayeredParams` in sync with src/shadow/layered.rs.
#import common/lighting.wgsl

struct LayeredParams {
    // osm: slices B; dom: layers B - 1; fom: harmonics n.
    count: u32,
    // Channels held in the packed targets.
    packed: u32,
    // 0: point splat, 1: segment splat (build pass only).
    splat: u32,
    // fom: 1 to damp harmonic k by the Lanczos σ-factor sinc(k / (n + 1)).
    sigma: u32,
    // dom: thickness covered by the layers, metres; 0: from each texel's start to the far bound.
    dom_thickness_m: f32,
    // dom: ratio between successive layer thicknesses (1 = uniform).
    dom_ratio: f32,
    _pad0: f32,
    _pad1: f32,
};

@group(1) @binding(0) var<uniform> layered: LayeredParams;
@group(1) @binding(1) var layered_sampler: sampler;
@group(1) @binding(2) var layered_map0: texture_2d<f32>;
@group(1) @binding(3) var layered_map1: texture_2d<f32>;
@group(1) @binding(4) var layered_map2: texture_2d<f32>;
@group(1) @binding(5) var layered_map3: texture_2d<f32>;
@group(1) @binding(6) var layered_map4: texture_2d<f32>;
@group(1) @binding(7) var layered_map5: texture_2d<f32>;
@group(1) @binding(8) var layered_map6: texture_2d<f32>;
@group(1) @binding(9) var layered_map7: texture_2d<f32>;

// One unfiltered texel of packed target `index`.
fn layered_texel(index: u32, texel: vec2<i32>) -> vec4<f32> {
    switch index {
        case 0u: { return textureLoad(layered_map0, texel, 0); }
        case 1u: { return textureLoad(layered_map1, texel, 0); }
        case 2u: { return textureLoad(layered_map2, texel, 0); }
        case 3u: { return textureLoad(layered_map3, texel, 0); }
        case 4u: { return textureLoad(layered_map4, texel, 0); }
        case 5u: { return textureLoad(layered_map5, texel, 0); }
        case 6u: { return textureLoad(layered_map6, texel, 0); }
        default: { return textureLoad(layered_map7, texel, 0); }
    }
}

// Bilinearly filtered texel of packed target `index`.
fn layered_target(index: u32, uv: vec2<f32>) -> vec4<f32> {
    switch index {
        case 0u: { return textureSampleLevel(layered_map0, layered_sampler, uv, 0.0); }
        case 1u: { return textureSampleLevel(layered_map1, layered_sampler, uv, 0.0); }
        case 2u: { return textureSampleLevel(layered_map2, layered_sampler, uv, 0.0); }
        case 3u: { return textureSampleLevel(layered_map3, layered_sampler, uv, 0.0); }
        case 4u: { return textureSampleLevel(layered_map4, layered_sampler, uv, 0.0); }
        case 5u: { return textureSampleLevel(layered_map5, layered_sampler, uv, 0.0); }
        case 6u: { return textureSampleLevel(layered_map6, layered_sampler, uv, 0.0); }
        default: { return textureSampleLevel(layered_map7, layered_sampler, uv, 0.0); }
    }
}

// Bilinearly filtered packed channel `channel`.
fn layered_channel(channel: u32, uv: vec2<f32>) -> f32 {
    return layered_target(channel / 4u, uv)[channel % 4u];
}
