// `osm` lookup: opacity shadow maps (Kim & Neumann 2001, thesis 3.3.3.2).
// B slices split the light-space depth range [near, far] (radial distance from the light) into
// equal steps; slice k (1..=B) stores the optical depth Ω accumulated in front of boundary k.
// Ω(0) = 0; between boundaries Ω is interpolated linearly; T = exp(-Ω).
// Keep `OsmParams` in sync with src/shadow/osm.rs.
#import common/lighting.wgsl

struct OsmParams {
    // Number of slices B (= channels used).
    slices: u32,
    // 0: point splat, 1: segment splat (used by the build pass only).
    splat: u32,
    _pad0: u32,
    _pad1: u32,
};

@group(1) @binding(0) var<uniform> osm: OsmParams;
@group(1) @binding(1) var osm_sampler: sampler;
@group(1) @binding(2) var osm_map0: texture_2d<f32>;
@group(1) @binding(3) var osm_map1: texture_2d<f32>;
@group(1) @binding(4) var osm_map2: texture_2d<f32>;
@group(1) @binding(5) var osm_map3: texture_2d<f32>;
@group(1) @binding(6) var osm_map4: texture_2d<f32>;
@group(1) @binding(7) var osm_map5: texture_2d<f32>;
@group(1) @binding(8) var osm_map6: texture_2d<f32>;
@group(1) @binding(9) var osm_map7: texture_2d<f32>;

// Bilinearly filtered texel of render target `index` (4 slices each).
fn osm_target(index: u32, uv: vec2<f32>) -> vec4<f32> {
    switch index {
        case 0u: { return textureSampleLevel(osm_map0, osm_sampler, uv, 0.0); }
        case 1u: { return textureSampleLevel(osm_map1, osm_sampler, uv, 0.0); }
        case 2u: { return textureSampleLevel(osm_map2, osm_sampler, uv, 0.0); }
        case 3u: { return textureSampleLevel(osm_map3, osm_sampler, uv, 0.0); }
        case 4u: { return textureSampleLevel(osm_map4, osm_sampler, uv, 0.0); }
        case 5u: { return textureSampleLevel(osm_map5, osm_sampler, uv, 0.0); }
        case 6u: { return textureSampleLevel(osm_map6, osm_sampler, uv, 0.0); }
        default: { return textureSampleLevel(osm_map7, osm_sampler, uv, 0.0); }
    }
}

// Optical depth in front of slice boundary k (0..=B).
fn osm_opacity(k: u32, uv: vec2<f32>) -> f32 {
    if k == 0u {
        return 0.0;
    }
    let slice = k - 1u;
    return osm_target(slice / 4u, uv)[slice % 4u];
}

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    let l = light_coords(p);
    if !l.inside {
        return 1.0;
    }
    let b = f32(osm.slices);
    let s = clamp(l.depth01, 0.0, 1.0) * b;
    let k0 = min(u32(floor(s)), osm.slices);
    let k1 = min(k0 + 1u, osm.slices);
    let omega = mix(osm_opacity(k0, l.uv), osm_opacity(k1, l.uv), s - f32(k0));
    return exp(-omega);
}
