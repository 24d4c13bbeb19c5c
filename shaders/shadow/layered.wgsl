// Shared lookup side of the layered techniques (osm, dom, fom): their parameters and the packed
// maps, 4 channels a target. Channel c lives in target c / 4, component c % 4; the full targets
// are layers of one array texture and the remainder (1-3 channels) a texture of its own, so a
// lookup picks a layer by index rather than switching between textures (divergent per fragment).
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
    // Full 4-channel targets in `layered_full`; target `full_targets` is `layered_rest`.
    full_targets: u32,
    _pad0: u32,
    // msm, tmsm: β, the pull of the moments towards the uniform distribution's.
    moment_bias: f32,
    // msm, tmsm: η, the share of the weight at the receiver's depth counted in front of it.
    moment_overestimation: f32,
    // tmsm: θ, the wrapping zone between the far and the near end of the depth range, radians.
    wrapping_zone_rad: f32,
    _pad1: u32,
};

@group(1) @binding(0) var<uniform> layered: LayeredParams;
@group(1) @binding(1) var layered_sampler: sampler;
@group(1) @binding(2) var layered_full: texture_2d_array<f32>;
@group(1) @binding(3) var layered_rest: texture_2d<f32>;

// One unfiltered texel of packed target `index`.
fn layered_texel(index: u32, texel: vec2<i32>) -> vec4<f32> {
    if index < layered.full_targets {
        return textureLoad(layered_full, texel, index, 0);
    }
    return textureLoad(layered_rest, texel, 0);
}

// Bilinearly filtered texel of packed target `index`.
fn layered_target(index: u32, uv: vec2<f32>) -> vec4<f32> {
    if index < layered.full_targets {
        return textureSampleLevel(layered_full, layered_sampler, uv, index, 0.0);
    }
    return textureSampleLevel(layered_rest, layered_sampler, uv, 0.0);
}

// Every packed channel, bilinearly filtered (channels beyond `packed` in the last target are 0).
fn layered_channels(uv: vec2<f32>) -> array<f32, 32> {
    var c: array<f32, 32>;
    let targets = (layered.packed + 3u) / 4u;
    for (var t = 0u; t < targets; t++) {
        let v = layered_target(t, uv);
        c[4u * t] = v.x;
        c[4u * t + 1u] = v.y;
        c[4u * t + 2u] = v.z;
        c[4u * t + 3u] = v.w;
    }
    return c;
}

// Bilinearly filtered packed channel `channel`.
fn layered_channel(channel: u32, uv: vec2<f32>) -> f32 {
    return layered_target(channel / 4u, uv)[channel % 4u];
}
