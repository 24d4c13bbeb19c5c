// `esm` lookup: the exponential shadow map for volumes (Annen et al. 2008, as Bauer 2019 uses it
// for clouds; dissertation 000, chapter 3.2.4). One map holds the normalised light depth z where
// the smoke starts along each texel's ray; a point at depth d behind it sees
// V = clamp(exp(-c (d - z)), 0, 1), c in 1/m (`esm_exponent_per_m`, light_maps.values.x). A texel
// without smoke (z at the far bound) lets all light through. The four texels around the point
// are evaluated separately and blended bilinearly.
#import shadow/light_maps.wgsl

@group(1) @binding(2) var esm_start: texture_2d<f32>;

fn esm_texel(texel: vec2<i32>, depth01: f32) -> f32 {
    let z = textureLoad(esm_start, texel, 0).r;
    if z >= 0.9999 {
        return 1.0;
    }
    let behind_m = max(depth01 - z, 0.0) / frame.light_depth.z;
    return clamp(exp(-light_maps.values.x * behind_m), 0.0, 1.0);
}

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    let l = light_coords(p);
    if !l.inside {
        return 1.0;
    }
    let fp = bilinear_taps(l.uv, vec2<i32>(textureDimensions(esm_start)));
    return fp.weights.x * esm_texel(fp.texels[0], l.depth01)
        + fp.weights.y * esm_texel(fp.texels[1], l.depth01)
        + fp.weights.z * esm_texel(fp.texels[2], l.depth01)
        + fp.weights.w * esm_texel(fp.texels[3], l.depth01);
}
