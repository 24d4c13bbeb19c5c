// The moment problem behind `msm` and `tmsm` (Münstermann et al. 2018; Peters et al. 2017): the
// bound on the share of a light ray's optical depth in front of a depth, from its normalised
// moments. The CPU mirror, with the derivation, is src/shadow/moment_math.rs; keep the two in
// step. Complex numbers are vec2<f32> (re, im); power moments are complex with im = 0, so one
// code path serves both families.
//
// The budget's MOMENT_ROOTS (n) and LAYERED_COUNT (the moments) are constants composed before
// the lookup (src/shadow/layered.rs, `lookup_constants`): every loop over the small arrays below
// is written out over them (`#unroll`, src/shaders.rs), so that each index is a constant and the
// arrays stay in registers; where fewer roots are finite than n, the written-out steps past them
// are guarded off.
#import common/lighting.wgsl

// Most roots the closed-form root finding handles (a quartic).
const MOMENT_MAX_ROOTS: u32 = 4u;
// Below this total optical depth a texel holds no smoke.
const MOMENT_EMPTY_OPTICAL_DEPTH: f32 = 1e-6;

fn c_mul(a: vec2<f32>, b: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(a.x * b.x - a.y * b.y, a.x * b.y + a.y * b.x);
}

fn c_conj(a: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(a.x, -a.y);
}

fn c_div(a: vec2<f32>, b: vec2<f32>) -> vec2<f32> {
    return c_mul(a, c_conj(b)) / dot(b, b);
}

fn c_polar(r: f32, angle: f32) -> vec2<f32> {
    return r * vec2<f32>(cos(angle), sin(angle));
}

// The principal square root.
fn c_sqrt(a: vec2<f32>) -> vec2<f32> {
    let r = length(a);
    let im = sqrt(max(0.5 * (r - a.x), 0.0));
    return vec2<f32>(sqrt(max(0.5 * (r + a.x), 0.0)), select(im, -im, a.y < 0.0));
}

// The principal cube root.
fn c_cbrt(a: vec2<f32>) -> vec2<f32> {
    return c_polar(pow(length(a), 1.0 / 3.0), atan2(a.y, a.x) / 3.0);
}

// The angle of `a` in [0, 2π).
fn c_angle(a: vec2<f32>) -> f32 {
    let angle = atan2(a.y, a.x);
    return select(angle, angle + 2.0 * PI, angle < 0.0);
}

// Roots of x² + b x + c, without cancellation.
fn moment_quadratic(b: vec2<f32>, c: vec2<f32>) -> array<vec2<f32>, 2> {
    let s = c_sqrt(c_mul(b, b) - 4.0 * c);
    let q = select(-0.5 * (b - s), -0.5 * (b + s), dot(b, s) >= 0.0);
    if dot(q, q) == 0.0 {
        return array<vec2<f32>, 2>(vec2<f32>(0.0), vec2<f32>(0.0));
    }
    return array<vec2<f32>, 2>(q, c_div(c, q));
}

// Roots of x³ + a x² + b x + c (Cardano on the depressed cubic t³ + p t + q).
fn moment_cubic(a: vec2<f32>, b: vec2<f32>, c: vec2<f32>) -> array<vec2<f32>, 3> {
    let shift = a / 3.0;
    let a2 = c_mul(a, a);
    let p = b - a2 / 3.0;
    let q = 2.0 * c_mul(a2, a) / 27.0 - c_mul(a, b) / 3.0 + c;
    let s = c_sqrt(c_mul(q, q) / 4.0 + c_mul(c_mul(p, p), p) / 27.0);
    let u1 = -0.5 * q + s;
    let u2 = -0.5 * q - s;
    let u3 = select(u2, u1, dot(u1, u1) >= dot(u2, u2));
    if dot(u3, u3) == 0.0 {
        return array<vec2<f32>, 3>(-shift, -shift, -shift);
    }
    let u = c_cbrt(u3);
    let v = c_div(-p, 3.0 * u);
    let omega = vec2<f32>(-0.5, 0.86602540378);
    return array<vec2<f32>, 3>(
        u + v - shift,
        c_mul(omega, u) + c_mul(c_conj(omega), v) - shift,
        c_mul(c_conj(omega), u) + c_mul(omega, v) - shift,
    );
}

// Roots of x⁴ + a x³ + b x² + c x + d (Ferrari on the depressed quartic y⁴ + p y² + q y + r,
// with the resolvent's root of largest magnitude).
fn moment_quartic(a: vec2<f32>, b: vec2<f32>, c: vec2<f32>, d: vec2<f32>) -> array<vec2<f32>, 4> {
    let shift = a / 4.0;
    let a2 = c_mul(a, a);
    let p = b - 3.0 * a2 / 8.0;
    let q = c - c_mul(a, b) / 2.0 + c_mul(a2, a) / 8.0;
    let r = d - c_mul(a, c) / 4.0 + c_mul(a2, b) / 16.0 - 3.0 * c_mul(a2, a2) / 256.0;
    let resolvent = moment_cubic(p, (c_mul(p, p) - 4.0 * r) / 4.0, -c_mul(q, q) / 8.0);
    var m = resolvent[0];
    #unroll i 1..3
        if dot(resolvent[i], resolvent[i]) > dot(m, m) {
            m = resolvent[i];
        }
    #end_unroll
    let s = c_sqrt(2.0 * m);
    if dot(s, s) == 0.0 {
        return array<vec2<f32>, 4>(-shift, -shift, -shift, -shift);
    }
    let h = c_div(q, 2.0 * s);
    let y01 = moment_quadratic(-s, 0.5 * p + m + h);
    let y23 = moment_quadratic(s, 0.5 * p + m - h);
    return array<vec2<f32>, 4>(y01[0] - shift, y01[1] - shift, y23[0] - shift, y23[1] - shift);
}

// Below this share of its largest coefficient, a kernel polynomial's leading coefficient is
// taken as 0: a root has gone to infinity (a symmetric distribution probed at its middle makes
// the odd coefficients vanish), where it carries no weight.
const MOMENT_VANISHING_LEAD: f32 = 1e-4;

// The finite roots of a polynomial, `count` of them in `roots`.
struct MomentRoots {
    roots: array<vec2<f32>, 4>,
    count: u32,
};

// Roots of Σ coefficients[k] x^k of degree at most MOMENT_ROOTS (2..=4): leading coefficients
// that vanish lower the degree (roots at infinity are dropped); the rest in closed form, polished
// by two Newton steps.
fn moment_roots(coefficients: array<vec2<f32>, 5>) -> MomentRoots {
    var a = coefficients;
    var largest = 0.0;
    #unroll k 0..MOMENT_ROOTS+1
        largest = max(largest, length(a[k]));
    #end_unroll
    var n = MOMENT_ROOTS;
    #unroll m rev 2..MOMENT_ROOTS+1
        if n == m && length(a[m]) <= MOMENT_VANISHING_LEAD * largest {
            n = m - 1u;
        }
    #end_unroll
    var lead = a[1];
    #unroll m 2..MOMENT_ROOTS+1
        if n == m {
            lead = a[m];
        }
    #end_unroll
    #unroll k 0..MOMENT_ROOTS+1
        if k <= n {
            a[k] = c_div(a[k], lead);
        }
    #end_unroll
    var out: MomentRoots;
    out.count = n;
    if n == 1u {
        out.roots[0] = -a[0];
    } else if n == 2u {
        let r = moment_quadratic(a[1], a[0]);
        out.roots[0] = r[0];
        out.roots[1] = r[1];
    } else if n == 3u {
        let r = moment_cubic(a[2], a[1], a[0]);
        out.roots[0] = r[0];
        out.roots[1] = r[1];
        out.roots[2] = r[2];
    } else {
        out.roots = moment_quartic(a[3], a[2], a[1], a[0]);
    }
    #unroll i 0..MOMENT_ROOTS
        if i < n {
            var x = out.roots[i];
            #unroll step 0..2
                var value = vec2<f32>(0.0);
                var slope = vec2<f32>(0.0);
                // Horner from a[n] down to a[0].
                #unroll k rev 0..MOMENT_ROOTS+1
                    if k <= n {
                        slope = c_mul(slope, x) + value;
                        value = c_mul(value, x) + a[k];
                    }
                #end_unroll
                if dot(slope, slope) > 0.0 {
                    x -= c_div(value, slope);
                }
            #end_unroll
            out.roots[i] = x;
        }
    #end_unroll
    return out;
}

// How a reconstruction is set (from the technique's parameters).
struct MomentSetting {
    // Trigonometric moments (else power).
    trigonometric: bool,
    // β: the pull towards the bias target.
    bias: f32,
    // η: the share of the weight at the receiver's depth counted in front of it.
    overestimation: f32,
    // θ: the wrapping zone, radians (trigonometric moments).
    wrapping_zone_rad: f32,
    // Power moments: the target of moments 2, 4, 6, 8 (the odd ones' is 0); trigonometric
    // moments are pulled towards 0 (scaled by 1 − β).
    bias_target: vec4<f32>,
};

// The node a normalised depth maps to: z = 2d − 1 on the real line, or e^{iφ}, φ = d(2π − θ).
fn moment_node(s: MomentSetting, depth01: f32) -> vec2<f32> {
    let d = clamp(depth01, 0.0, 1.0);
    if s.trigonometric {
        return c_polar(1.0, d * (2.0 * PI - s.wrapping_zone_rad));
    }
    return vec2<f32>(2.0 * d - 1.0, 0.0);
}

// The bias target's moment k: 0 for trigonometric and odd power moments, else the setting's
// (the uniform distribution's 1/(k + 1), or the authors' vector).
fn moment_bias_target(s: MomentSetting, k: u32) -> f32 {
    if s.trigonometric || (k % 2u) == 1u {
        return 0.0;
    }
    return s.bias_target[min(k / 2u, 4u) - 1u];
}

// How much of a root's weight lies in front of the node z0: 1 in front, 0 behind, and for
// trigonometric moments a ramp over the wrapping zone.
fn moment_root_weight(s: MomentSetting, root: vec2<f32>, z0: vec2<f32>) -> f32 {
    if !s.trigonometric {
        return select(0.0, 1.0, root.x < z0.x);
    }
    let psi = c_angle(root);
    let front = select(0.0, 1.0, psi < c_angle(z0));
    let ramp = clamp((psi - (2.0 * PI - s.wrapping_zone_rad)) / s.wrapping_zone_rad, 0.0, 1.0);
    return front + ramp;
}

// T at normalised depth `depth01` from a texel's total optical depth `b0` and its unnormalised
// moments b0·b_k in `weighted[k]`, k = 1..(2n power, n trigonometric).
fn moment_transmittance(s: MomentSetting, b0: f32, weighted: array<vec2<f32>, 9>, depth01: f32) -> f32 {
    if b0 <= MOMENT_EMPTY_OPTICAL_DEPTH || depth01 <= 0.0 {
        return 1.0;
    }
    // The depth range is fitted to enclose every particle: beyond its far end the whole ray's
    // optical depth lies in front, which the bound would count only partly (the receiver's
    // node would sit on the smoke's last depths).
    if depth01 >= 1.0 {
        return clamp(exp(-b0), 0.0, 1.0);
    }
    // Biased normalised moments, b[0] = 1 (power maps hold 2n moments, trigonometric ones n:
    // LAYERED_COUNT either way).
    var b: array<vec2<f32>, 9>;
    b[0] = vec2<f32>(1.0, 0.0);
    #unroll k 1..LAYERED_COUNT+1
        b[k] = (1.0 - s.bias) * weighted[k] / b0 + vec2<f32>(s.bias * moment_bias_target(s, k), 0.0);
    #end_unroll
    // A = L D Lᴴ of the (n + 1)² Hankel (power: A_ij = b[i + j]) or Toeplitz (A_ij = b[i − j],
    // conjugated above the diagonal) matrix.
    var l: array<vec2<f32>, 25>;
    var d: array<f32, 5>;
    #unroll j 0..MOMENT_ROOTS+1
        var dj = select(b[2u * j].x, 1.0, s.trigonometric);
        #unroll k 0..j
            dj -= dot(l[j * 5u + k], l[j * 5u + k]) * d[k];
        #end_unroll
        d[j] = dj;
        #unroll i j+1..MOMENT_ROOTS+1
            var sum = select(b[i + j], b[i - j], s.trigonometric);
            #unroll k 0..j
                sum -= c_mul(l[i * 5u + k], c_conj(l[j * 5u + k])) * d[k];
            #end_unroll
            l[i * 5u + j] = sum / dj;
        #end_unroll
    #end_unroll
    // Solve A c = (1, z0, …, z0ⁿ).
    let z0 = moment_node(s, depth01);
    var c: array<vec2<f32>, 5>;
    c[0] = vec2<f32>(1.0, 0.0);
    #unroll k 1..MOMENT_ROOTS+1
        c[k] = c_mul(c[k - 1u], z0);
    #end_unroll
    #unroll i 1..MOMENT_ROOTS+1
        #unroll k 0..i
            c[i] -= c_mul(l[i * 5u + k], c[k]);
        #end_unroll
    #end_unroll
    #unroll i 0..MOMENT_ROOTS+1
        c[i] /= d[i];
    #end_unroll
    #unroll i rev 0..MOMENT_ROOTS+1
        #unroll k i+1..MOMENT_ROOTS+1
            c[i] -= c_mul(c_conj(l[k * 5u + i]), c[k]);
        #end_unroll
    #end_unroll
    // The kernel polynomial (conjugated coefficients for trigonometric moments) and its roots.
    if s.trigonometric {
        #unroll k 0..MOMENT_ROOTS+1
            c[k] = c_conj(c[k]);
        #end_unroll
    }
    let roots = moment_roots(c);
    // The polynomial through (z0, η) and (each finite root, its weight), of degree one less than
    // the nodes: Newton's divided differences.
    let finite = roots.count;
    let nodes_count = finite + 1u;
    var nodes: array<vec2<f32>, 5>;
    var dd: array<vec2<f32>, 5>;
    nodes[0] = z0;
    dd[0] = vec2<f32>(s.overestimation, 0.0);
    #unroll i 0..MOMENT_ROOTS
        if i < finite {
            nodes[i + 1u] = roots.roots[i];
            dd[i + 1u] = vec2<f32>(moment_root_weight(s, roots.roots[i], z0), 0.0);
        }
    #end_unroll
    #unroll level 1..MOMENT_ROOTS+1
        #unroll i rev level..MOMENT_ROOTS+1
            if i < nodes_count {
                dd[i] = c_div(dd[i] - dd[i - 1u], nodes[i] - nodes[i - level]);
            }
        #end_unroll
    #end_unroll
    // Its monomial coefficients (Horner on the Newton form, from node finite − 1 down to node
    // 0), integrated against the moments.
    var poly: array<vec2<f32>, 5>;
    poly[0] = dd[0];
    #unroll m 1..MOMENT_ROOTS+1
        if m == finite {
            poly[0] = dd[m];
        }
    #end_unroll
    #unroll kk 0..MOMENT_ROOTS
        if kk < finite {
            // Node k = finite − 1 − kk and its difference.
            var node = nodes[0];
            var difference = dd[0];
            #unroll m 1..MOMENT_ROOTS
                if m + kk + 1u == finite {
                    node = nodes[m];
                    difference = dd[m];
                }
            #end_unroll
            var next: array<vec2<f32>, 5>;
            #unroll i 0..kk+1
                next[i + 1u] += poly[i];
                next[i] -= c_mul(poly[i], node);
            #end_unroll
            next[0] += difference;
            poly = next;
        }
    #end_unroll
    var share = 0.0;
    #unroll k 0..MOMENT_ROOTS+1
        if k < nodes_count {
            share += c_mul(poly[k], b[k]).x;
        }
    #end_unroll
    // A reconstruction that broke down (NaN from a singular matrix) counts nothing in front.
    share = select(0.0, clamp(share, 0.0, 1.0), share == share);
    return clamp(exp(-b0 * share), 0.0, 1.0);
}

// The lookup both map families share (shaders/shadow/msm.wgsl and tmsm.wgsl import
// shadow/layered.wgsl first): the texel's channels at p's light coordinates, b0 first, then the
// moments, a power moment one channel each, a trigonometric one its real and imaginary part;
// T bounded by `setting`.
fn moment_map_transmittance(p: vec3<f32>, setting: MomentSetting) -> f32 {
    let l = light_coords(p);
    if !l.inside {
        return 1.0;
    }
    var c = layered_channels(l.uv);
    var weighted: array<vec2<f32>, 9>;
    #unroll k 1..LAYERED_COUNT+1
        if setting.trigonometric {
            weighted[k] = vec2<f32>(c[2u * k - 1u], c[2u * k]);
        } else {
            weighted[k] = vec2<f32>(c[k], 0.0);
        }
    #end_unroll
    return moment_transmittance(setting, c[0], weighted, l.depth01);
}
