// `bsm` lookup: the Beer shadow map (Hillaire 2016/2020; dissertation 000, chapter 3.2.5). Per
// texel: the normalised depths where the smoke starts (z_f) and ends (z_b) along the ray, and
// the ray's whole optical depth D_max. The extinction is taken as uniform between them,
// σ_mean = D_max / (z_b - z_f), so a point at depth d sees D = min(D_max, σ_mean max(0, d - z_f))
// and T = exp(-D). The four texels around the point are evaluated separately and blended
// bilinearly (a texel without smoke has D_max = 0: T = 1).
#import shadow/light_maps.wgsl

@group(1) @binding(2) var bsm_front: texture_2d<f32>;
@group(1) @binding(3) var bsm_back: texture_2d<f32>;
@group(1) @binding(4) var bsm_optical_depth: texture_2d<f32>;

fn bsm_texel(texel: vec2<i32>, depth01: f32) -> f32 {
    let d_max = textureLoad(bsm_optical_depth, texel, 0).r;
    if d_max <= 0.0 {
        return 1.0;
    }
    let front = textureLoad(bsm_front, texel, 0).r;
    let back = textureLoad(bsm_back, texel, 0).r;
    let sigma_mean = d_max / max(back - front, 1e-4);
    return exp(-min(d_max, sigma_mean * max(depth01 - front, 0.0)));
}

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    let l = light_coords(p);
    if !l.inside {
        return 1.0;
    }
    let fp = bilinear_taps(l.uv, vec2<i32>(textureDimensions(bsm_front)));
    return fp.weights.x * bsm_texel(fp.texels[0], l.depth01)
        + fp.weights.y * bsm_texel(fp.texels[1], l.depth01)
        + fp.weights.z * bsm_texel(fp.texels[2], l.depth01)
        + fp.weights.w * bsm_texel(fp.texels[3], l.depth01);
}
