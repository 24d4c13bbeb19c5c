//! The monotone cubic between slice boundaries, on the CPU: the mirror of
//! `layered_monotone_cubic` in `shaders/shadow/layered.wgsl`, which `osm` and `dom` evaluate with
//! `osm_interp = cubic` / `dom_interp = cubic` (the thesis' future work, chapter 5: "cubic spline
//! interpolation for sampling opacity from slice-based techniques ... to smooth slice
//! artifacts").
//!
//! Piecewise cubic Hermite interpolation (PCHIP) through knots x_0 < ... < x_n with values y_k:
//! on each interval the cubic with the knots' values and tangents m_k. At an interior knot the
//! tangent is the weighted harmonic mean of the two neighbouring slopes δ (Fritsch & Butland
//! 1984, with Brodlie's weights for unequal intervals), 0 where they differ in sign; at an end
//! knot the one-sided three-point estimate, limited as SciPy's `PchipInterpolator` limits it.
//! Every tangent then lies between 0 and 3 times each neighbouring slope, so on every interval
//! (α, β) = (m_k / δ_k, m_{k+1} / δ_k) lies in [0, 3]², inside Fritsch & Carlson's (1980)
//! monotonicity region: through non-decreasing optical depths the curve never decreases, so
//! T = exp(-Ω) never rises with depth. Each interval needs only its own two knots and one on
//! each side (the lookup reads four boundaries); where those four are collinear, the cubic is
//! their line, the linear lookup.

/// Tangent at an interior knot between intervals of widths `h0`, `h1` and slopes `d0`, `d1`:
/// their weighted harmonic mean (weights 2·h1 + h0 on d0 and h1 + 2·h0 on d1), 0 when the
/// slopes differ in sign or one is 0.
pub fn interior_tangent(h0: f32, h1: f32, d0: f32, d1: f32) -> f32 {
    if d0 * d1 <= 0.0 {
        return 0.0;
    }
    let w0 = 2.0 * h1 + h0;
    let w1 = h1 + 2.0 * h0;
    (w0 + w1) / (w0 / d0 + w1 / d1)
}

/// Tangent at an end knot, from its interval (width `h0`, slope `d0`) and the next one (`h1`,
/// `d1`): the one-sided three-point estimate, 0 when its sign differs from `d0`'s, and at most
/// 3·`d0` when the slopes change sign.
pub fn end_tangent(h0: f32, h1: f32, d0: f32, d1: f32) -> f32 {
    let m = ((2.0 * h0 + h1) * d0 - h0 * d1) / (h0 + h1);
    if m * d0 <= 0.0 {
        return 0.0;
    }
    if d0 * d1 <= 0.0 && m.abs() > 3.0 * d0.abs() {
        return 3.0 * d0;
    }
    m
}

/// The cubic on the interval [x\[1\], x\[2\]] of ascending knots `x` with values `y`, at `at`
/// (clamped into the interval): exactly what the lookup shader computes. `first`: x\[1\] is the
/// first knot (x\[0\], y\[0\] unused); `last`: x\[2\] is the last (x\[3\], y\[3\] unused); both: the
/// line between the two.
pub fn interval(x: [f32; 4], y: [f32; 4], first: bool, last: bool, at: f32) -> f32 {
    let h = [x[1] - x[0], x[2] - x[1], x[3] - x[2]];
    let slope = |i: usize| {
        if h[i] > 0.0 {
            (y[i + 1] - y[i]) / h[i]
        } else {
            0.0
        }
    };
    let d = [slope(0), slope(1), slope(2)];
    if h[1] <= 0.0 {
        return y[1];
    }
    let (mut m1, mut m2) = (d[1], d[1]);
    if !first {
        m1 = interior_tangent(h[0], h[1], d[0], d[1]);
    } else if !last {
        m1 = end_tangent(h[1], h[2], d[1], d[2]);
    }
    if !last {
        m2 = interior_tangent(h[1], h[2], d[1], d[2]);
    } else if !first {
        m2 = end_tangent(h[1], h[0], d[1], d[0]);
    }
    let t = ((at - x[1]) / h[1]).clamp(0.0, 1.0);
    let (t2, t3) = (t * t, t * t * t);
    let v = y[1]
        + (y[2] - y[1]) * (3.0 * t2 - 2.0 * t3)
        + h[1] * (m1 * (t3 - 2.0 * t2 + t) + m2 * (t3 - t2));
    // Rounding aside, the curve stays between its ends.
    v.clamp(y[1].min(y[2]), y[1].max(y[2]))
}

/// The monotone cubic through `knots` (ascending, at least 2) with `values`, at `at`: the
/// values beyond the ends, and on each interval [`interval`] with the knots around it, as the
/// lookup picks them.
pub fn monotone_cubic(knots: &[f32], values: &[f32], at: f32) -> f32 {
    assert!(knots.len() >= 2 && knots.len() == values.len());
    let n = knots.len() - 1;
    if at <= knots[0] {
        return values[0];
    }
    if at >= knots[n] {
        return values[n];
    }
    let k = knots.partition_point(|&x| x <= at).clamp(1, n) - 1;
    let pick = |i: usize| (knots[i], values[i]);
    let around = [k.max(1) - 1, k, k + 1, (k + 2).min(n)].map(pick);
    interval(
        around.map(|(x, _)| x),
        around.map(|(_, y)| y),
        k == 0,
        k + 1 == n,
        at,
    )
}

/// The tangent [`monotone_cubic`] gives each knot (for checking the Fritsch-Carlson condition).
pub fn tangents(knots: &[f32], values: &[f32]) -> Vec<f32> {
    let n = knots.len() - 1;
    let h: Vec<f32> = knots.windows(2).map(|w| w[1] - w[0]).collect();
    let d: Vec<f32> = (0..n).map(|i| (values[i + 1] - values[i]) / h[i]).collect();
    (0..=n)
        .map(|k| match k {
            _ if n == 1 => d[0],
            0 => end_tangent(h[0], h[1], d[0], d[1]),
            k if k == n => end_tangent(h[n - 1], h[n - 2], d[n - 1], d[n - 2]),
            k => interior_tangent(h[k - 1], h[k], d[k - 1], d[k]),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `count` + 1 evenly spaced points over [knots[0], knots[last]].
    fn sweep(knots: &[f32], count: usize) -> Vec<f32> {
        let (a, b) = (knots[0], knots[knots.len() - 1]);
        (0..=count)
            .map(|i| a + (b - a) * i as f32 / count as f32)
            .collect()
    }

    #[test]
    fn linear_data_is_reproduced_exactly() {
        // Uniform knots (osm's slices), and unequal ones (dom's geometric layers, ratio 1.5).
        let uniform: Vec<f32> = (0..=8).map(|k| k as f32 / 8.0).collect();
        let geometric: Vec<f32> = (0..=6)
            .map(|k| (1.5f32.powi(k) - 1.0) / (1.5f32.powi(6) - 1.0))
            .collect();
        for knots in [&uniform, &geometric] {
            let line = |x: f32| 0.25 + 3.5 * x;
            let values: Vec<f32> = knots.iter().map(|&x| line(x)).collect();
            for x in sweep(knots, 97) {
                let v = monotone_cubic(knots, &values, x);
                assert!((v - line(x)).abs() < 1e-5, "at {x}: {v}, line {}", line(x));
            }
            // Every tangent is the line's slope (within rounding).
            for m in tangents(knots, &values) {
                assert!((m - 3.5).abs() < 1e-4, "{m}");
            }
        }
        // Linear only across the four knots around an interval is enough: Ω flat, then rising
        // linearly (a slab entered at knot 2); on [3, 4] and beyond the cubic is the line.
        let knots = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let values = [0.0, 0.0, 0.0, 0.5, 1.0, 1.5, 2.0];
        for i in 0..=30 {
            let x = 3.0 + i as f32 / 10.0;
            let v = monotone_cubic(&knots, &values, x);
            assert!((v - 0.5 * (x - 2.0)).abs() < 1e-6, "at {x}: {v}");
        }
    }

    #[test]
    fn monotone_data_stays_monotone_and_between_its_knots() {
        // Optical depths with flat stretches, a jump and slopes of very different sizes: the
        // overshoot a natural spline would show at a step does not happen.
        let knots = [0.0, 0.1, 0.2, 0.5, 0.6, 0.65, 0.9, 1.0];
        let values = [0.0, 0.0, 0.02, 3.0, 3.0, 3.01, 7.5, 7.5];
        let xs = sweep(&knots, 2000);
        let curve: Vec<f32> = xs
            .iter()
            .map(|&x| monotone_cubic(&knots, &values, x))
            .collect();
        for (w, x) in curve.windows(2).zip(&xs) {
            assert!(w[1] >= w[0], "falls after {x}: {} -> {}", w[0], w[1]);
        }
        for (x, v) in xs.iter().zip(&curve) {
            let k = knots.partition_point(|k| k <= x).clamp(1, knots.len() - 1) - 1;
            let (lo, hi) = (values[k], values[(k + 1).min(knots.len() - 1)]);
            assert!((lo..=hi).contains(v), "at {x}: {v} outside [{lo}, {hi}]");
        }
        // Flat stretches stay flat.
        assert_eq!(monotone_cubic(&knots, &values, 0.05), 0.0);
        assert_eq!(monotone_cubic(&knots, &values, 0.55), 3.0);
        assert_eq!(monotone_cubic(&knots, &values, 0.95), 7.5);
    }

    #[test]
    fn tangents_meet_the_fritsch_carlson_condition() {
        // On every interval with slope δ > 0, α = m_k/δ and β = m_{k+1}/δ lie in [0, 3]
        // (inside α² + β² <= 9 or the box, Fritsch & Carlson's sufficient conditions); with
        // δ = 0 both tangents are 0.
        let knots = [0.0, 0.05, 0.3, 0.35, 0.8, 1.0, 1.7, 1.9, 2.0];
        let values = [0.0, 0.4, 0.45, 2.0, 2.0, 2.1, 6.0, 6.0, 6.3];
        let m = tangents(&knots, &values);
        for k in 0..knots.len() - 1 {
            let delta = (values[k + 1] - values[k]) / (knots[k + 1] - knots[k]);
            if delta == 0.0 {
                assert_eq!((m[k], m[k + 1]), (0.0, 0.0), "interval {k}");
            } else {
                let (alpha, beta) = (m[k] / delta, m[k + 1] / delta);
                assert!(
                    (0.0..=3.0).contains(&alpha) && (0.0..=3.0).contains(&beta),
                    "interval {k}: α {alpha}, β {beta}"
                );
            }
        }
    }

    #[test]
    fn values_worked_out_by_hand() {
        // A step between two flat stretches: every tangent is 0, so the middle interval is the
        // smoothstep 3t² - 2t³: 0.15625 at t = 1/4, 0.5 at t = 1/2.
        let knots = [0.0, 1.0, 2.0, 3.0];
        let step = [0.0, 0.0, 1.0, 1.0];
        assert_eq!(monotone_cubic(&knots, &step, 1.25), 0.15625);
        assert_eq!(monotone_cubic(&knots, &step, 1.5), 0.5);
        // Unequal intervals: knots 0, 1, 3 with values 0, 1, 2 (slopes 1 and 1/2). End tangent
        // ((2·1 + 2)·1 - 1·0.5)/3 = 7/6; interior (weights 5 and 4) 9/(5/1 + 4/0.5) = 9/13. At
        // x = 1/2: 1/2 + (7/6 - 9/13)/8 = 1/2 + 37/624.
        let (knots, values) = ([0.0, 1.0, 3.0], [0.0, 1.0, 2.0]);
        let m = tangents(&knots, &values);
        assert!((m[0] - 7.0 / 6.0).abs() < 1e-6 && (m[1] - 9.0 / 13.0).abs() < 1e-6);
        let v = monotone_cubic(&knots, &values, 0.5);
        assert!((v - (0.5 + 37.0 / 624.0)).abs() < 1e-6, "{v}");
        // Two knots: the line.
        assert_eq!(monotone_cubic(&[0.0, 2.0], &[1.0, 2.0], 0.5), 1.25);
    }
}
