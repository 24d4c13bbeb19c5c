// `exact` lookup: a deep shadow map with unbounded memory (Lokovic & Veach 2000, thesis 3.3.3.1).
// Every shadow-map texel holds the visibility function of its light ray as a sorted list of
// nodes (z, Ω(z)), z the radial distance from the light in metres: the optical depth in front of
// z is piecewise linear between nodes, exact for the particles' density model (each particle
// adds τ(1 - d/r)·2w spread uniformly over its chord [t - w, t + w]). Texel i's nodes are
// exact_nodes[2·offsets[i] .. 2·offsets[i + 1]). The four texels around a point are evaluated
// separately and blended bilinearly. Keep `ExactParams` in sync with src/shadow/exact.rs.
#import common/lighting.wgsl

struct ExactParams {
    // Shadow-map resolution (texels per side).
    resolution: u32,
    // Segments the list buffers can hold.
    capacity: u32,
    _pad0: u32,
    _pad1: u32,
};

@group(1) @binding(0) var<uniform> exact: ExactParams;
@group(1) @binding(1) var<storage, read> exact_offsets: array<u32>;
@group(1) @binding(2) var<storage, read> exact_nodes: array<vec2<f32>>;

// Optical depth in front of distance z (m) along the ray of one texel.
fn exact_texel_omega(texel: vec2<i32>, z: f32) -> f32 {
    let index = u32(texel.y) * exact.resolution + u32(texel.x);
    let first = 2u * exact_offsets[index];
    let count = 2u * exact_offsets[index + 1u] - first;
    if count == 0u || z <= exact_nodes[first].x {
        return 0.0;
    }
    let last = exact_nodes[first + count - 1u];
    if z >= last.x {
        return last.y;
    }
    // The last node at or before z, by bisection: nodes[lo].x <= z < nodes[hi].x.
    var lo = 0u;
    var hi = count - 1u;
    while hi - lo > 1u {
        let mid = (lo + hi) / 2u;
        if exact_nodes[first + mid].x <= z {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let a = exact_nodes[first + lo];
    let b = exact_nodes[first + hi];
    return mix(a.y, b.y, clamp((z - a.x) / max(b.x - a.x, 1e-12), 0.0, 1.0));
}

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    let l = light_coords(p);
    if !l.inside {
        return 1.0;
    }
    var taps = bilinear_taps(l.uv, vec2<i32>(i32(exact.resolution)));
    var omega = 0.0;
    for (var i = 0; i < 4; i++) {
        omega += taps.weights[i] * exact_texel_omega(taps.texels[i], l.dist_m);
    }
    return exp(-omega);
}
