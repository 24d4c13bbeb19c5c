// Lookup side of a compressed deep shadow map (`dsm`, `avsm`): group 1 holds the parameters and
// the nodes; `deep_texel_value` evaluates one texel's piecewise-linear function at a light
// depth; `deep_blended_value` blends the four texels around a point bilinearly (`bilinear_taps`),
// each evaluated on its own, which is what each technique's lookup returns T from.
#import common/lighting.wgsl
#import shadow/deep_params.wgsl

@group(1) @binding(0) var<uniform> deep: DeepParams;
@group(1) @binding(1) var<storage, read> deep_nodes: array<vec2<f32>>;

// The value at distance z (m) of one texel's nodes, linear between the bracketing nodes:
// `before` in front of the first node, the last node's value behind the last.
fn deep_texel_value(texel: vec2<i32>, z: f32, before: f32) -> f32 {
    let n = deep.nodes_per_texel;
    let first = (u32(texel.y) * deep.resolution + u32(texel.x)) * n;
    if z <= deep_nodes[first].x {
        return before;
    }
    let last = deep_nodes[first + n - 1u];
    if z >= last.x {
        return last.y;
    }
    // The last node at or before z, by bisection: nodes[lo].x <= z < nodes[hi].x.
    var lo = 0u;
    var hi = n - 1u;
    while hi - lo > 1u {
        let mid = (lo + hi) / 2u;
        if deep_nodes[first + mid].x <= z {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let a = deep_nodes[first + lo];
    let b = deep_nodes[first + hi];
    return mix(a.y, b.y, clamp((z - a.x) / max(b.x - a.x, 1e-12), 0.0, 1.0));
}

// The four texels around `l` (a point inside the map), each evaluated at l's depth, blended
// bilinearly. Written out four times (`#unroll`; llvmpipe does not unroll loops itself), so
// that the four texels' bisections, each a chain of loads that wait on the last, overlap: the
// thesis frame's opaque pass, `dsm`'s lookups on the ground, 10-11 -> 8-9 ms.
fn deep_blended_value(l: LightCoords, before: f32) -> f32 {
    var taps = bilinear_taps(l.uv, vec2<i32>(i32(deep.resolution)));
    var value = 0.0;
    #unroll i 0..4
        value += taps.weights[i] * deep_texel_value(taps.texels[i], l.dist_m, before);
    #end_unroll
    return value;
}
