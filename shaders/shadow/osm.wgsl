// `osm` lookup: opacity shadow maps (Kim & Neumann 2001, thesis 3.3.3.2).
// B slices split the normalised light depth [0, 1] (the smoke's radial bounds from the light)
// into equal steps; slice k (1..=B) stores the optical depth Ω in front of boundary k/B.
// Ω(0) = 0; between boundaries Ω is interpolated linearly, or with the monotone cubic
// (`osm_interp = cubic`, through the boundaries k - 1 ..= k + 2 around the point); T = exp(-Ω).
#import shadow/layered.wgsl

// Optical depth in front of boundary k (0..=B).
fn osm_boundary(k: u32, uv: vec2<f32>) -> f32 {
    if k == 0u {
        return 0.0;
    }
    return layered_channel(k - 1u, uv);
}

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    let l = light_coords(p);
    if !l.inside {
        return 1.0;
    }
    let s = clamp(l.depth01, 0.0, 1.0) * f32(layered.count);
    let k0 = min(u32(floor(s)), layered.count);
    let k1 = min(k0 + 1u, layered.count);
    if layered.cubic != 0u && k1 > k0 {
        let km = max(k0, 1u) - 1u;
        let k2 = min(k1 + 1u, layered.count);
        let x = vec4<f32>(f32(km), f32(k0), f32(k1), f32(k2));
        let y = vec4<f32>(osm_boundary(km, l.uv), osm_boundary(k0, l.uv), osm_boundary(k1, l.uv), osm_boundary(k2, l.uv));
        return exp(-layered_monotone_cubic(x, y, k0 == 0u, k1 == layered.count, s));
    }
    let omega = mix(osm_boundary(k0, l.uv), osm_boundary(k1, l.uv), s - f32(k0));
    return exp(-omega);
}
