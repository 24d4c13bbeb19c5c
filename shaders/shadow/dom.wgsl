// `dom` lookup: deep opacity maps (Yuksel & Keyser 2008, thesis 3.3.3.4).
// One channel holds, per texel, the normalised light depth z0 where the smoke starts; the other
// B - 1 channels are layers that start there and follow the smoke's shape: boundary k sits at
// z0 + offset(k), with offsets uniform or growing geometrically over the layers' thickness:
// by default from z0 to the smoke's far bound (so every texel spends all its layers on the
// smoke behind its own start), or a fixed thickness, beyond which points map to the last layer
// (the paper's recommendation). Points in front of z0 see no smoke. Between boundaries Ω is
// linear in the layer coordinate, or (`dom_interp = cubic`) the monotone cubic in depth through
// the boundaries k - 1 ..= k + 2 around the point, on their own (geometric) spacing. The four
// surrounding texels are evaluated separately (each has its own z0) and blended bilinearly.
#import shadow/layered.wgsl

@group(1) @binding(4) var dom_depth: texture_2d<f32>;

// Normalised thickness covered by the layers of a texel starting at z0.
fn dom_thickness(z0: f32) -> f32 {
    if layered.dom_thickness_m <= 0.0 {
        return max(1.0 - z0, 1e-4);
    }
    return layered.dom_thickness_m * frame.light_depth.z;
}

// Normalised offset of boundary k (0..=L) from the texel's start depth.
fn dom_offset(k: f32, thickness: f32) -> f32 {
    let layers = f32(layered.count);
    let r = layered.dom_ratio;
    if r <= 1.0001 {
        return thickness * k / layers;
    }
    return thickness * (pow(r, k) - 1.0) / (pow(r, layers) - 1.0);
}

// Inverse of `dom_offset`: the fractional boundary coordinate of offset u >= 0.
fn dom_layer_coord(u: f32, thickness: f32) -> f32 {
    let layers = f32(layered.count);
    let r = layered.dom_ratio;
    if r <= 1.0001 {
        return u / thickness * layers;
    }
    return log(1.0 + u / thickness * (pow(r, layers) - 1.0)) / log(r);
}

// Optical depth in front of boundary k (0..=L) at one texel; channel k - 1 of the packed maps.
fn dom_boundary(k: u32, texel: vec2<i32>) -> f32 {
    if k == 0u {
        return 0.0;
    }
    return layered_texel((k - 1u) / 4u, texel)[(k - 1u) % 4u];
}

// Optical depth in front of normalised depth z along the ray of one texel.
fn dom_texel_omega(texel: vec2<i32>, z: f32) -> f32 {
    let z0 = textureLoad(dom_depth, texel, 0).r;
    if z <= z0 {
        return 0.0;
    }
    let layers = layered.count;
    let s = clamp(dom_layer_coord(z - z0, dom_thickness(z0)), 0.0, f32(layers));
    let k0 = min(u32(floor(s)), layers);
    let k1 = min(k0 + 1u, layers);
    if layered.cubic != 0u && k1 > k0 {
        let thickness = dom_thickness(z0);
        let km = max(k0, 1u) - 1u;
        let k2 = min(k1 + 1u, layers);
        let x = vec4<f32>(dom_offset(f32(km), thickness), dom_offset(f32(k0), thickness), dom_offset(f32(k1), thickness), dom_offset(f32(k2), thickness));
        let y = vec4<f32>(dom_boundary(km, texel), dom_boundary(k0, texel), dom_boundary(k1, texel), dom_boundary(k2, texel));
        return layered_monotone_cubic(x, y, k0 == 0u, k1 == layers, z - z0);
    }
    return mix(dom_boundary(k0, texel), dom_boundary(k1, texel), s - f32(k0));
}

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    let l = light_coords(p);
    if !l.inside {
        return 1.0;
    }
    var taps = bilinear_taps(l.uv, vec2<i32>(textureDimensions(dom_depth)));
    var omega = 0.0;
    for (var i = 0; i < 4; i++) {
        omega += taps.weights[i] * dom_texel_omega(taps.texels[i], l.depth01);
    }
    return exp(-omega);
}
