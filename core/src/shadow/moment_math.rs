//! The moment problem behind `msm` and `tmsm`, on the CPU in f64: the mirror of
//! `shaders/shadow/moments.wgsl` (Münstermann, Krumpen, Klein & Peters, "Moment-Based
//! Order-Independent Transparency", I3D 2018; Peters, Münstermann, Wetzstein & Klein, "Improved
//! Moment Shadow Maps for Translucent Occluders, Soft Shadows and Single Scattering", JCGT 2017).
//!
//! Along one light ray the smoke's optical depth is a measure over depth. A map stores its total
//! `b0` and its first moments, normalised by `b0`:
//! - **power** moments `b_k = E[z^k]`, k = 1..2n, of the depth mapped to z ∈ [−1, 1]
//!   (a Hamburger moment problem);
//! - **trigonometric** moments `b_k = E[e^{ikφ}]`, k = 1..n, of the depth mapped to the angle
//!   φ ∈ [0, 2π − θ] (a Toeplitz moment problem; the arc (2π − θ, 2π), the *wrapping zone*,
//!   separates the far end of the depth range from its near end).
//!
//! The optical depth in front of a depth z0 is not determined by n moments, but it is bounded:
//! of all the distributions with these moments, the one with the least mass in front of z0 (the
//! lower bound) is the *canonical representation* that puts one support point at z0 itself and
//! n more at the roots of the kernel polynomial c(x) = (1, x, …, xⁿ) A⁻¹ (1, z0, …, z0ⁿ)ᵀ, A
//! the moments' Hankel (power) or Toeplitz (trigonometric) matrix. The mass in front of z0 is the
//! sum of the weights of the roots in front of it; the weight at z0 itself is counted with the
//! *overestimation* factor η (0: the lower bound, light leaks; 1: the upper bound, too dark). The
//! weights need not be computed one by one: the polynomial p of degree n through (z0, η) and
//! (root, 0 or 1) integrates against the canonical measure as against any measure with these
//! moments, so the mass is Σ p_k b_k.
//!
//! Before that, the moments are *biased* towards those of the uniform distribution (power:
//! E[z^k] = 1/(k+1) for even k, 0 for odd; trigonometric: 0): b ← (1 − β) b + β b_uniform. A
//! measured moment vector lies on the boundary of the moment space whenever the ray crosses
//! fewer than n + 1 distinct depths (one particle, point splats), where A is singular; mixing in
//! a continuous distribution puts it strictly inside, so A is positive definite, at the price of
//! a little light leaking (β > 0 spreads mass over the whole range).
//!
//! The roots of a polynomial of degree n ≤ 4 are found in closed form (quadratic, Cardano,
//! Ferrari), as the authors do, here in complex arithmetic for both families (power moments give
//! real roots; trigonometric ones roots on the unit circle), each polished by Newton steps.

use num_complex::Complex64 as C;

/// Most roots (n) the closed-form root finding handles: a polynomial of degree 4.
pub const MAX_ROOTS: usize = 4;

/// Which moments a map stores.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Basis {
    /// z^k with z ∈ [−1, 1]: 2n moments for n roots.
    Power,
    /// e^{ikφ} with φ ∈ [0, 2π − θ], θ the wrapping zone (radians): n moments for n roots.
    Trigonometric { wrapping_zone_rad: f64 },
}

impl Basis {
    /// The node a normalised depth `depth01` ∈ [0, 1] maps to: z on the real line, or e^{iφ}.
    pub fn node(self, depth01: f64) -> C {
        let d = depth01.clamp(0.0, 1.0);
        match self {
            Self::Power => C::new(2.0 * d - 1.0, 0.0),
            Self::Trigonometric { wrapping_zone_rad } => {
                C::from_polar(1.0, d * (std::f64::consts::TAU - wrapping_zone_rad))
            }
        }
    }

    /// Moments the map stores for `roots` roots (besides b0).
    pub fn moment_count(self, roots: usize) -> usize {
        match self {
            Self::Power => 2 * roots,
            Self::Trigonometric { .. } => roots,
        }
    }

    /// The mean of the basis functions k = 1..=count over normalised depths [z0, z1] (a segment
    /// splat spreads its optical depth uniformly over them; z0 == z1 is a point).
    pub fn segment_mean(self, count: usize, z0: f64, z1: f64) -> Vec<C> {
        match self {
            Self::Power => {
                // The mean of x^k over [x0, x1] is Σ_j x0^j x1^(k−j) / (k + 1): no cancellation.
                let (x0, x1) = (2.0 * z0 - 1.0, 2.0 * z1 - 1.0);
                let (mut h, mut x0k) = (1.0, 1.0);
                (1..=count)
                    .map(|k| {
                        x0k *= x0;
                        h = x1 * h + x0k;
                        C::new(h / (k as f64 + 1.0), 0.0)
                    })
                    .collect()
            }
            Self::Trigonometric { .. } => {
                // The mean of e^{ikφ} over [φ0, φ1] is e^{ikφm} sinc(kΔ/2).
                let (a, b) = (self.node(z0).arg(), self.node(z1).arg());
                let to_angle = |x: f64| x.rem_euclid(std::f64::consts::TAU);
                let (a, b) = (to_angle(a), to_angle(b));
                let (mid, half) = (0.5 * (a + b), 0.5 * (b - a));
                (1..=count)
                    .map(|k| {
                        let x = k as f64 * half;
                        let sinc = if x.abs() < 1e-12 { 1.0 } else { x.sin() / x };
                        C::from_polar(sinc, k as f64 * mid)
                    })
                    .collect()
            }
        }
    }

    /// How much of a root's weight lies in front of the node `z0`: 1 in front, 0 behind, and
    /// for trigonometric moments a linear ramp over the wrapping zone (a root there lies past
    /// the far end or before the near end; the ramp goes from behind to in front across it).
    fn weight(self, root: C, z0: C) -> f64 {
        match self {
            Self::Power => f64::from(u8::from(root.re < z0.re)),
            Self::Trigonometric { wrapping_zone_rad } => {
                let tau = std::f64::consts::TAU;
                let angle = |c: C| c.arg().rem_euclid(tau);
                let (psi, phi) = (angle(root), angle(z0));
                let front = f64::from(u8::from(psi < phi));
                let ramp = ((psi - (tau - wrapping_zone_rad)) / wrapping_zone_rad).clamp(0.0, 1.0);
                front + ramp
            }
        }
    }

    /// The uniform distribution's moment k (the bias target).
    fn uniform_moment(self, k: usize) -> f64 {
        match self {
            Self::Power if k.is_multiple_of(2) => 1.0 / (k as f64 + 1.0),
            _ => 0.0,
        }
    }
}

/// A map texel: the total optical depth b0 and the unnormalised moments b0·b_k, k = 1..count.
#[derive(Clone, Debug, PartialEq)]
pub struct Moments {
    pub b0: f64,
    pub weighted: Vec<C>,
}

impl Moments {
    /// No smoke.
    pub fn empty(basis: Basis, roots: usize) -> Self {
        Self {
            b0: 0.0,
            weighted: vec![C::new(0.0, 0.0); basis.moment_count(roots)],
        }
    }

    /// Adds `optical_depth` spread uniformly over normalised depths [z0, z1].
    pub fn add(&mut self, basis: Basis, optical_depth: f64, z0: f64, z1: f64) {
        self.b0 += optical_depth;
        let mean = basis.segment_mean(self.weighted.len(), z0, z1);
        for (w, m) in self.weighted.iter_mut().zip(mean) {
            *w += optical_depth * m;
        }
    }
}

/// How a reconstruction is set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reconstruction {
    pub basis: Basis,
    /// Roots n (2 ..= 4): power maps store 2n moments, trigonometric ones n.
    pub roots: usize,
    /// β: how far the moments are pulled towards the uniform distribution's.
    pub bias: f64,
    /// η: the share of the weight at the receiver's own depth counted in front of it.
    pub overestimation: f64,
}

/// Below this total optical depth a texel holds no smoke (T = 1).
pub const EMPTY_OPTICAL_DEPTH: f64 = 1e-6;

impl Reconstruction {
    /// T at normalised depth `depth01` from a texel's moments.
    pub fn transmittance(&self, moments: &Moments, depth01: f64) -> f64 {
        if moments.b0 <= EMPTY_OPTICAL_DEPTH || depth01 <= 0.0 {
            return 1.0;
        }
        // The depth range encloses every particle: beyond it, the whole optical depth is in
        // front (the bound would put the receiver's own node on the smoke's last depths).
        if depth01 >= 1.0 {
            return (-moments.b0).exp();
        }
        let share = self.share_in_front(moments, depth01);
        (-moments.b0 * share).exp().clamp(0.0, 1.0)
    }

    /// The bound on the share of the ray's optical depth in front of `depth01`, in [0, 1].
    pub fn share_in_front(&self, moments: &Moments, depth01: f64) -> f64 {
        let n = self.roots;
        assert!((1..=MAX_ROOTS).contains(&n), "{n} roots");
        // b[0] = 1, then the biased normalised moments.
        let mut b = vec![C::new(1.0, 0.0)];
        b.extend(moments.weighted.iter().enumerate().map(|(i, w)| {
            let target = self.basis.uniform_moment(i + 1);
            (1.0 - self.bias) * (w / moments.b0) + self.bias * target
        }));
        let entry = |i: usize, j: usize| match self.basis {
            Basis::Power => b[i + j],
            Basis::Trigonometric { .. } if i >= j => b[i - j],
            Basis::Trigonometric { .. } => b[j - i].conj(),
        };
        let z0 = self.basis.node(depth01);
        let rhs: Vec<C> = (0..=n).map(|k| z0.powu(k as u32)).collect();
        let c = solve_ldlh(n + 1, entry, &rhs);
        let poly: Vec<C> = match self.basis {
            Basis::Power => c,
            Basis::Trigonometric { .. } => c.iter().map(|x| x.conj()).collect(),
        };
        let roots = polynomial_roots(&poly);
        let mut nodes = vec![z0];
        nodes.extend(&roots);
        let mut values = vec![self.overestimation];
        values.extend(roots.iter().map(|&r| self.basis.weight(r, z0)));
        let p = interpolating_polynomial(&nodes, &values);
        let share: C = p.iter().zip(&b).map(|(pk, bk)| pk * bk).sum();
        if share.re.is_finite() {
            share.re.clamp(0.0, 1.0)
        } else {
            0.0
        }
    }
}

/// Solves A x = rhs for the Hermitian positive definite `size`² matrix A given by `entry(i, j)`
/// through its factorisation A = L D Lᴴ (L unit lower triangular, D real diagonal).
fn solve_ldlh(size: usize, entry: impl Fn(usize, usize) -> C, rhs: &[C]) -> Vec<C> {
    let mut l = vec![vec![C::new(0.0, 0.0); size]; size];
    let mut d = vec![0.0; size];
    for j in 0..size {
        let dj = entry(j, j).re - (0..j).map(|k| l[j][k].norm_sqr() * d[k]).sum::<f64>();
        d[j] = dj;
        for i in j + 1..size {
            let s: C = (0..j).map(|k| l[i][k] * l[j][k].conj() * d[k]).sum();
            l[i][j] = (entry(i, j) - s) / dj;
        }
    }
    let mut x = rhs.to_vec();
    for i in 0..size {
        for k in 0..i {
            let lx = l[i][k] * x[k];
            x[i] -= lx;
        }
    }
    for i in 0..size {
        x[i] /= d[i];
    }
    for i in (0..size).rev() {
        for k in i + 1..size {
            let lx = l[k][i].conj() * x[k];
            x[i] -= lx;
        }
    }
    x
}

/// Below this share of its largest coefficient, a kernel polynomial's leading coefficient is
/// taken as 0: a root has gone to infinity (a symmetric distribution probed at its middle makes
/// the odd coefficients vanish), where it carries no weight. In f32 (the GPU) the closed forms
/// overflow on such a polynomial.
pub const VANISHING_LEAD: f64 = 1e-4;

/// The finite roots of Σ `coefficients[k]` x^k (degree 1..=4): leading coefficients that vanish
/// ([`VANISHING_LEAD`]) lower the degree; the rest in closed form, each polished by two Newton
/// steps on the polynomial itself.
pub fn polynomial_roots(coefficients: &[C]) -> Vec<C> {
    let largest = coefficients.iter().map(|c| c.norm()).fold(0.0, f64::max);
    let mut degree = coefficients.len() - 1;
    while degree > 1 && coefficients[degree].norm() <= VANISHING_LEAD * largest {
        degree -= 1;
    }
    let coefficients = &coefficients[..=degree];
    let lead = coefficients[degree];
    // Monic: x^n + a[n-1] x^(n-1) + … + a[0].
    let a: Vec<C> = coefficients.iter().map(|c| c / lead).collect();
    let mut roots = match degree {
        1 => vec![-a[0]],
        2 => quadratic(a[1], a[0]).to_vec(),
        3 => cubic(a[2], a[1], a[0]).to_vec(),
        4 => quartic(a[3], a[2], a[1], a[0]).to_vec(),
        _ => panic!("degree {degree} has no closed form here"),
    };
    for r in &mut roots {
        for _ in 0..2 {
            let (mut value, mut slope) = (C::new(0.0, 0.0), C::new(0.0, 0.0));
            for c in a.iter().rev() {
                slope = slope * *r + value;
                value = value * *r + c;
            }
            if slope.norm() > 0.0 {
                *r -= value / slope;
            }
        }
    }
    roots
}

/// Roots of x² + b x + c, without cancellation.
fn quadratic(b: C, c: C) -> [C; 2] {
    let s = (b * b - 4.0 * c).sqrt();
    // q = −(b ± s)/2 with the sign that adds magnitudes.
    let q = if (b.conj() * s).re >= 0.0 {
        -0.5 * (b + s)
    } else {
        -0.5 * (b - s)
    };
    if q.norm() == 0.0 {
        return [C::new(0.0, 0.0); 2];
    }
    [q, c / q]
}

/// Roots of x³ + a x² + b x + c (Cardano on the depressed cubic t³ + p t + q).
fn cubic(a: C, b: C, c: C) -> [C; 3] {
    let shift = a / 3.0;
    let p = b - a * a / 3.0;
    let q = 2.0 * a * a * a / 27.0 - a * b / 3.0 + c;
    let s = (q * q / 4.0 + p * p * p / 27.0).sqrt();
    let (u1, u2) = (-q / 2.0 + s, -q / 2.0 - s);
    let u3 = if u1.norm() >= u2.norm() { u1 } else { u2 };
    let omega = C::from_polar(1.0, std::f64::consts::TAU / 3.0);
    if u3.norm() == 0.0 {
        return [-shift; 3];
    }
    let u = u3.cbrt();
    let v = -p / (3.0 * u);
    [
        u + v - shift,
        omega * u + omega.conj() * v - shift,
        omega.conj() * u + omega * v - shift,
    ]
}

/// Roots of x⁴ + a x³ + b x² + c x + d (Ferrari on the depressed quartic y⁴ + p y² + q y + r).
fn quartic(a: C, b: C, c: C, d: C) -> [C; 4] {
    let shift = a / 4.0;
    let a2 = a * a;
    let p = b - 3.0 * a2 / 8.0;
    let q = c - a * b / 2.0 + a2 * a / 8.0;
    let r = d - a * c / 4.0 + a2 * b / 16.0 - 3.0 * a2 * a2 / 256.0;
    // (y² + p/2 + m)² = 2m (y − q/(4m))² when 8m³ + 8p m² + (2p² − 8r) m − q² = 0: the root of
    // largest magnitude keeps 2m away from zero.
    let m = cubic(p, (p * p - 4.0 * r) / 4.0, -q * q / 8.0)
        .into_iter()
        .fold(C::new(0.0, 0.0), |best, m| {
            if m.norm() > best.norm() { m } else { best }
        });
    let s = (2.0 * m).sqrt();
    if s.norm() == 0.0 {
        // m = 0 only when p = q = r = 0: y⁴ = 0.
        return [-shift; 4];
    }
    let [y0, y1] = quadratic(-s, p / 2.0 + m + q / (2.0 * s));
    let [y2, y3] = quadratic(s, p / 2.0 + m - q / (2.0 * s));
    [y0 - shift, y1 - shift, y2 - shift, y3 - shift]
}

/// Coefficients (lowest first) of the polynomial through (nodes[i], values[i]), by Newton's
/// divided differences.
fn interpolating_polynomial(nodes: &[C], values: &[f64]) -> Vec<C> {
    let n = nodes.len();
    let mut dd: Vec<C> = values.iter().map(|&v| C::new(v, 0.0)).collect();
    for level in 1..n {
        for i in (level..n).rev() {
            dd[i] = (dd[i] - dd[i - 1]) / (nodes[i] - nodes[i - level]);
        }
    }
    // Horner on the Newton form: p = dd[n-1], then p = p·(x − nodes[k]) + dd[k].
    let mut p = vec![dd[n - 1]];
    for k in (0..n - 1).rev() {
        let mut next = vec![C::new(0.0, 0.0); p.len() + 1];
        for (i, &pi) in p.iter().enumerate() {
            next[i + 1] += pi;
            next[i] -= pi * nodes[k];
        }
        next[0] += dd[k];
        p = next;
    }
    p
}

/// The bias the moment-based OIT authors use, per moment count and precision: Münstermann,
/// Krumpen, Klein & Peters, "Moment-Based Order-Independent Transparency", Proc. ACM Comput.
/// Graph. Interact. Tech. 1(1), article 7, 2018 (doi:10.1145/3203206), and the code they
/// released with it (`MomentOIT.hlsli`, `resolveMoments`: the bias vectors; the β per count and
/// precision as its OIT demo sets them, e.g. PixelSyncOIT's `OIT_MBOIT.cpp`,
/// `updateMomentMode`). Power moments are lerped towards the vector by β; trigonometric moments
/// are scaled by 1 − β (no vector). This tool stores its moments in 32-bit floats, so the
/// lookup uses the single-float rows; the 16-bit rows are kept for the record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PaperBias {
    pub trigonometric: bool,
    /// Power moments (4, 6, 8) or trigonometric moments (2, 3, 4).
    pub moments: u32,
    /// Bits per moment: 32 or 16.
    pub bits: u32,
    pub bias: f32,
    /// The bias vector's moments 1..=N (power moments only; empty for trigonometric ones).
    pub vector: &'static [f64],
}

pub const PAPER_BIAS: &[PaperBias] = &[
    PaperBias {
        trigonometric: false,
        moments: 4,
        bits: 32,
        bias: 5e-7,
        vector: &[0.0, 0.375, 0.0, 0.375],
    },
    PaperBias {
        trigonometric: false,
        moments: 6,
        bits: 32,
        bias: 5e-6,
        vector: &[0.0, 0.48, 0.0, 0.451, 0.0, 0.45],
    },
    PaperBias {
        trigonometric: false,
        moments: 8,
        bits: 32,
        bias: 5e-5,
        vector: &[
            0.0,
            0.75,
            0.0,
            0.676_666_666_666_666_6,
            0.0,
            0.63,
            0.0,
            0.600_303_030_303_030_3,
        ],
    },
    PaperBias {
        trigonometric: true,
        moments: 2,
        bits: 32,
        bias: 4e-7,
        vector: &[],
    },
    PaperBias {
        trigonometric: true,
        moments: 3,
        bits: 32,
        bias: 8e-7,
        vector: &[],
    },
    PaperBias {
        trigonometric: true,
        moments: 4,
        bits: 32,
        bias: 1.5e-6,
        vector: &[],
    },
    PaperBias {
        trigonometric: false,
        moments: 4,
        bits: 16,
        bias: 6e-5,
        vector: &[0.0, 0.628, 0.0, 0.628],
    },
    PaperBias {
        trigonometric: false,
        moments: 6,
        bits: 16,
        bias: 6e-4,
        vector: &[0.0, 0.5566, 0.0, 0.489, 0.0, 0.478_693_82],
    },
    PaperBias {
        trigonometric: false,
        moments: 8,
        bits: 16,
        bias: 2.5e-3,
        vector: &[
            0.0,
            0.424_749_163_879_598_66,
            0.0,
            0.224_078_026_755_852_84,
            0.0,
            0.153_692_307_692_307_68,
            0.0,
            0.129_004_405_290_891_2,
        ],
    },
    PaperBias {
        trigonometric: true,
        moments: 2,
        bits: 16,
        bias: 4e-4,
        vector: &[],
    },
    PaperBias {
        trigonometric: true,
        moments: 3,
        bits: 16,
        bias: 6.5e-4,
        vector: &[],
    },
    PaperBias {
        trigonometric: true,
        moments: 4,
        bits: 16,
        bias: 8.5e-4,
        vector: &[],
    },
];

/// The authors' row for `moments` moments of this family in 32-bit floats (this tool's).
pub fn paper_bias(trigonometric: bool, moments: u32) -> Option<&'static PaperBias> {
    PAPER_BIAS
        .iter()
        .find(|b| b.trigonometric == trigonometric && b.moments == moments && b.bits == 32)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: C, b: C, tol: f64) -> bool {
        (a - b).norm() < tol
    }

    /// Every root in `expected` is found (in any order).
    fn assert_roots(found: &[C], expected: &[C], tol: f64) {
        for e in expected {
            assert!(
                found.iter().any(|f| close(*f, *e, tol)),
                "root {e} not among {found:?}"
            );
        }
    }

    /// Coefficients (lowest first) of Π (x − r).
    fn from_roots(roots: &[C]) -> Vec<C> {
        let mut p = vec![C::new(1.0, 0.0)];
        for &r in roots {
            let mut next = vec![C::new(0.0, 0.0); p.len() + 1];
            for (i, &pi) in p.iter().enumerate() {
                next[i + 1] += pi;
                next[i] -= pi * r;
            }
            p = next;
        }
        p
    }

    #[test]
    fn closed_form_roots_match_the_roots_a_polynomial_was_built_from() {
        let sets: [&[C]; 5] = [
            &[C::new(-0.5, 0.0), C::new(0.7, 0.0)],
            &[C::new(-0.9, 0.0), C::new(0.1, 0.0), C::new(0.8, 0.0)],
            &[
                C::new(-0.95, 0.0),
                C::new(-0.2, 0.0),
                C::new(0.3, 0.0),
                C::new(0.99, 0.0),
            ],
            // Roots on the unit circle (trigonometric moments), complex coefficients.
            &[
                C::from_polar(1.0, 0.3),
                C::from_polar(1.0, 2.0),
                C::from_polar(1.0, 4.4),
            ],
            &[
                C::from_polar(1.0, 0.1),
                C::from_polar(1.0, 1.6),
                C::from_polar(1.0, 3.3),
                C::from_polar(1.0, 5.9),
            ],
        ];
        for roots in sets {
            let poly: Vec<C> = from_roots(roots).iter().map(|c| c * 2.5).collect();
            assert_roots(&polynomial_roots(&poly), roots, 1e-9);
        }
        // A double root and a biquadratic (q = 0, Ferrari's m must avoid 0).
        let double = [C::new(0.4, 0.0), C::new(0.4, 0.0), C::new(-0.3, 0.0)];
        assert_roots(&polynomial_roots(&from_roots(&double)), &double, 1e-6);
        let biquadratic = [
            C::new(0.5, 0.0),
            C::new(-0.5, 0.0),
            C::new(0.9, 0.0),
            C::new(-0.9, 0.0),
        ];
        assert_roots(
            &polynomial_roots(&from_roots(&biquadratic)),
            &biquadratic,
            1e-9,
        );
    }

    #[test]
    fn the_interpolating_polynomial_passes_through_its_points() {
        let nodes = [
            C::new(-0.3, 0.0),
            C::new(0.5, 0.0),
            C::new(0.9, 0.1),
            C::new(-0.8, -0.2),
        ];
        let values = [0.25, 1.0, 0.0, 1.0];
        let p = interpolating_polynomial(&nodes, &values);
        for (x, v) in nodes.iter().zip(values) {
            let at: C = p.iter().rev().fold(C::new(0.0, 0.0), |acc, c| acc * x + c);
            assert!(close(at, C::new(v, 0.0), 1e-12), "p({x}) = {at}, not {v}");
        }
    }

    /// A texel with optical depth `od` at each of `depths` (point splats).
    fn texel(basis: Basis, roots: usize, splats: &[(f64, f64)]) -> Moments {
        let mut m = Moments::empty(basis, roots);
        for &(od, z) in splats {
            m.add(basis, od, z, z);
        }
        m
    }

    const TRIG: Basis = Basis::Trigonometric {
        wrapping_zone_rad: 0.1 * std::f64::consts::PI,
    };

    #[test]
    fn few_occluders_are_recovered_exactly_without_bias() {
        // When the ray crosses at most n distinct depths, the moments determine the
        // distribution (it is the canonical one): T is exact away from the occluders, without
        // bias (tiny bias: the matrix is singular at β = 0) and at η = 0 or 1 alike.
        let splats = [(0.8, 0.25), (1.5, 0.6)];
        for basis in [Basis::Power, TRIG] {
            for roots in 2..=4 {
                let m = texel(basis, roots, &splats);
                for eta in [0.0, 1.0] {
                    let r = Reconstruction {
                        basis,
                        roots,
                        bias: 1e-9,
                        overestimation: eta,
                    };
                    for (d, expected) in [(0.1, 0.0f64), (0.4, 0.8), (0.9, 2.3)] {
                        let t = r.transmittance(&m, d);
                        let want = (-expected).exp();
                        assert!(
                            (t - want).abs() < 1e-4,
                            "{basis:?}, n = {roots}, η = {eta}: T({d}) = {t}, want {want}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn the_bounds_bracket_a_continuous_distribution_and_tighten_with_more_roots() {
        // Optical depth 3 spread uniformly over depths [0.2, 0.8]: in front of d lies
        // 3·clamp((d − 0.2)/0.6, 0, 1). η = 0 gives a lower bound of the optical depth (T above
        // the truth), η = 1 an upper bound (T below); more roots, a tighter bracket.
        let omega = |d: f64| 3.0 * ((d - 0.2) / 0.6).clamp(0.0, 1.0);
        for basis in [Basis::Power, TRIG] {
            let mut widths = Vec::new();
            for roots in 2..=4 {
                let mut m = Moments::empty(basis, roots);
                m.add(basis, 3.0, 0.2, 0.8);
                let at = |eta, d| {
                    Reconstruction {
                        basis,
                        roots,
                        bias: 1e-7,
                        overestimation: eta,
                    }
                    .transmittance(&m, d)
                };
                let mut width = 0.0;
                for i in 0..=20 {
                    let d = f64::from(i) / 20.0;
                    let truth = (-omega(d)).exp();
                    let (upper, lower) = (at(0.0, d), at(1.0, d));
                    assert!(
                        upper >= truth - 1e-6 && lower <= truth + 1e-6,
                        "{basis:?}, n = {roots}: T({d}) = {truth} outside [{lower}, {upper}]"
                    );
                    width += upper - lower;
                }
                widths.push(width);
            }
            assert!(
                widths.windows(2).all(|w| w[1] < w[0]),
                "{basis:?}: the bracket must narrow with more roots: {widths:?}"
            );
        }
    }

    #[test]
    fn segment_means_match_the_point_moments_in_the_limit_and_by_quadrature() {
        for basis in [Basis::Power, TRIG] {
            let (z0, z1) = (0.3, 0.55);
            let mean = basis.segment_mean(8, z0, z1);
            // Midpoint quadrature over 10,000 points.
            let steps = 10_000;
            for (k, m) in mean.iter().enumerate() {
                let q: C = (0..steps)
                    .map(|i| {
                        let z = z0 + (z1 - z0) * (f64::from(i) + 0.5) / f64::from(steps);
                        basis.node(z).powu(k as u32 + 1)
                    })
                    .sum::<C>()
                    / f64::from(steps);
                assert!(close(*m, q, 1e-7), "{basis:?} k = {}: {m} vs {q}", k + 1);
            }
            let point = basis.segment_mean(8, 0.4, 0.4);
            for (k, m) in point.iter().enumerate() {
                assert!(close(*m, basis.node(0.4).powu(k as u32 + 1), 1e-12));
            }
        }
    }

    #[test]
    fn empty_and_degenerate_texels_give_finite_transmittance() {
        for basis in [Basis::Power, TRIG] {
            for roots in 2..=4 {
                let r = Reconstruction {
                    basis,
                    roots,
                    bias: 5e-5,
                    overestimation: 0.25,
                };
                let cases = [
                    texel(basis, roots, &[]),
                    texel(basis, roots, &[(1e-9, 0.5)]),
                    texel(basis, roots, &[(4.0, 0.5)]),
                    texel(basis, roots, &[(2.0, 0.0), (2.0, 1.0)]),
                    texel(basis, roots, &[(30.0, 0.999)]),
                ];
                for m in &cases {
                    for i in 0..=10 {
                        let t = r.transmittance(m, f64::from(i) / 10.0);
                        assert!(
                            t.is_finite() && (0.0..=1.0).contains(&t),
                            "{basis:?} n = {roots}: T = {t} for {m:?}"
                        );
                    }
                }
            }
        }
    }
}
