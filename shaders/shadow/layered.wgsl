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
    // osm, dom: 1 to interpolate between boundaries with the monotone cubic
    // (`layered_monotone_cubic`), 0 linearly.
    cubic: u32,
    // dom: factor on each particle's radius in the start-depth pass (1: the particles' own
    // spheres; more: a smoother proxy that starts in front of them).
    dom_start_dilation: f32,
    // msm, tmsm: β, the pull of the moments towards the bias target (`moment_bias_target`).
    moment_bias: f32,
    // msm, tmsm: η, the share of the weight at the receiver's depth counted in front of it.
    moment_overestimation: f32,
    // tmsm: θ, the wrapping zone between the far and the near end of the depth range, radians.
    wrapping_zone_rad: f32,
    _pad1: u32,
    _pad2: u32,
    _pad3: u32,
    // msm: what power moments 2, 4, 6 and 8 are pulled towards (the odd ones towards 0): the
    // uniform distribution's 1/(k + 1), or the moment-based OIT authors' bias vector.
    moment_bias_target: vec4<f32>,
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

// Bilinearly filtered packed channel `channel`.
fn layered_channel(channel: u32, uv: vec2<f32>) -> f32 {
    return layered_target(channel / 4u, uv)[channel % 4u];
}

// The monotone cubic between boundaries (`osm_interp` / `dom_interp` = cubic; the thesis' future
// work, chapter 5: "cubic spline interpolation ... to smooth slice artifacts"): the piecewise
// cubic Hermite interpolant through the boundaries' optical depths with Fritsch-Butland tangents
// (PCHIP; Brodlie's weights on unequal intervals). Each tangent is at most 3 times either
// neighbouring slope, inside Fritsch and Carlson's monotonicity region, so through
// non-decreasing Ω it never decreases: T never rises with depth. Where the four knots around an
// interval are collinear it is that line, the linear lookup. Local: an interval needs only its
// two knots and one on each side. CPU mirror: src/shadow/slice_interp.rs.

// Tangent at an interior knot between intervals of widths h0, h1 and slopes d0, d1: their
// weighted harmonic mean, 0 at a local extremum.
fn pchip_interior_tangent(h0: f32, h1: f32, d0: f32, d1: f32) -> f32 {
    if d0 * d1 <= 0.0 {
        return 0.0;
    }
    let w0 = 2.0 * h1 + h0;
    let w1 = h1 + 2.0 * h0;
    return (w0 + w1) / (w0 / d0 + w1 / d1);
}

// Tangent at an end knot, from its interval (width h0, slope d0) and the next (h1, d1): the
// one-sided three-point estimate, 0 when its sign differs from d0's, at most 3·d0 when the
// slopes change sign.
fn pchip_end_tangent(h0: f32, h1: f32, d0: f32, d1: f32) -> f32 {
    let m = ((2.0 * h0 + h1) * d0 - h0 * d1) / (h0 + h1);
    if m * d0 <= 0.0 {
        return 0.0;
    }
    if d0 * d1 <= 0.0 && abs(m) > 3.0 * abs(d0) {
        return 3.0 * d0;
    }
    return m;
}

// The monotone cubic through ascending knots `x` with values `y`, on the interval [x.y, x.z],
// at `at` (clamped into it). `first`: x.y is the first knot (x.x, y.x unused); `last`: x.z is the
// last (x.w, y.w unused); both: the line between the two.
fn layered_monotone_cubic(x: vec4<f32>, y: vec4<f32>, first: bool, last: bool, at: f32) -> f32 {
    let h = x.yzw - x.xyz;
    let d = select(vec3<f32>(0.0), (y.yzw - y.xyz) / h, h > vec3<f32>(0.0));
    if h.y <= 0.0 {
        return y.y;
    }
    var m1 = d.y;
    var m2 = d.y;
    if !first {
        m1 = pchip_interior_tangent(h.x, h.y, d.x, d.y);
    } else if !last {
        m1 = pchip_end_tangent(h.y, h.z, d.y, d.z);
    }
    if !last {
        m2 = pchip_interior_tangent(h.y, h.z, d.y, d.z);
    } else if !first {
        m2 = pchip_end_tangent(h.y, h.x, d.y, d.x);
    }
    let t = clamp((at - x.y) / h.y, 0.0, 1.0);
    let t2 = t * t;
    let t3 = t2 * t;
    let v = y.y + (y.z - y.y) * (3.0 * t2 - 2.0 * t3) + h.y * (m1 * (t3 - 2.0 * t2 + t) + m2 * (t3 - t2));
    // Rounding aside, the curve stays between its ends.
    return clamp(v, min(y.y, y.z), max(y.y, y.z));
}
