//! CPU mirrors of the deep shadow map passes, in the same f32 arithmetic and order as the
//! shaders, so that a test can tell a compression bug from a build or lookup bug:
//! - [`sort_segments`] and [`optical_depth_nodes`]: the deep capture's resolve
//!   (shaders/shadow/deep_capture.wgsl): segments by (z0, z1, optical depth) (`avsm`'s), and
//!   their starts and ends by depth, turned into the nodes (z, Ω(z)) of the piecewise-linear
//!   optical depth (`dsm`'s);
//! - [`greedy_fit`] and [`dsm_compress`]: `dsm`'s error-bounded greedy fit (Lokovic & Veach
//!   2000) and the per-texel search for its tolerance (shaders/shadow/dsm_build.wgsl);
//! - [`AvsmCurve`] and [`avsm_compress`]: `avsm`'s insertion (in draw order or sorted, as its
//!   list comes) and least-area removal (Salvi et al. 2010; shaders/shadow/avsm_build.wgsl);
//! - [`evaluate`]: one texel's lookup (shaders/shadow/deep_nodes.wgsl).

/// A node of a texel's function: a light depth (m) and the value there (Ω or T).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node {
    pub z: f32,
    pub value: f32,
}

impl Node {
    pub const fn new(z: f32, value: f32) -> Self {
        Self { z, value }
    }
}

/// A captured chord: entered at `z0`, left at `z1` (m), `optical_depth` spread uniformly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    pub z0: f32,
    pub z1: f32,
    pub optical_depth: f32,
}

impl Segment {
    pub const fn new(z0: f32, z1: f32, optical_depth: f32) -> Self {
        Self {
            z0,
            z1,
            optical_depth,
        }
    }

    fn slope(&self) -> f32 {
        self.optical_depth / (self.z1 - self.z0)
    }
}

/// Sorts by the capture's total key: z0, then z1, then optical depth.
pub fn sort_segments(segments: &mut [Segment]) {
    segments.sort_by(|a, b| {
        a.z0.total_cmp(&b.z0)
            .then(a.z1.total_cmp(&b.z1))
            .then(a.optical_depth.total_cmp(&b.optical_depth))
    });
}

/// The nodes (z, Ω(z)) of segments' optical depth, two per segment, in any order: every start
/// and end is an event where the sum of the open segments' slopes changes. The events are taken
/// in the resolve's order (`key_less` in shaders/shadow/deep_capture.wgsl): by depth, and at one
/// depth the larger change of slope first, so starts before ends.
pub fn optical_depth_nodes(segments: &[Segment]) -> Vec<Node> {
    let mut events: Vec<(f32, f32)> = segments
        .iter()
        .flat_map(|s| [(s.z0, s.slope()), (s.z1, -s.slope())])
        .collect();
    let before = |a: f32, b: f32| a.partial_cmp(&b).unwrap_or(std::cmp::Ordering::Equal);
    events.sort_by(|a, b| before(a.0, b.0).then(before(b.1, a.1)));
    let (mut omega, mut slope, mut z_prev) = (0.0f32, 0.0f32, 0.0f32);
    events
        .into_iter()
        .map(|(z, delta)| {
            omega += slope * (z - z_prev);
            slope = (slope + delta).max(0.0);
            z_prev = z;
            Node::new(z, omega)
        })
        .collect()
}

/// An unbounded slope, for the feasible interval before it has met a node.
const ANY_SLOPE: f32 = 3.0e38;

/// The vertex closing a segment from `origin` over nodes up to `last` with a slope in [lo, hi]
/// (its middle, raised to 0 when feasible), its value clamped to `last` ± eps.
fn close_segment(origin: Node, last: Node, lo: f32, hi: f32, eps: f32) -> Node {
    let slope = (0.5 * (lo + hi)).max(0.0).clamp(lo, hi);
    let value = origin.value + slope * (last.z - origin.z);
    Node::new(last.z, value.clamp(last.value - eps, last.value + eps))
}

/// Lokovic & Veach's greedy fit of `nodes` within ±`eps`: each output segment starts at the
/// previous output vertex (the first input node to begin with) and extends over the input nodes
/// while some slope passes within eps of all of them, ending at the last one it covers. Stops
/// once it has more than `limit` vertices (and returns `limit` + 1 of them).
pub fn greedy_fit(nodes: &[Node], eps: f32, limit: usize) -> Vec<Node> {
    let Some(mut fit) = Fit::new(nodes) else {
        return Vec::new();
    };
    while fit.i < nodes.len() && fit.out.len() <= limit {
        fit.step(nodes[fit.i], eps);
    }
    fit.finish(eps, limit)
}

/// A greedy fit under way (`Fit` in shaders/shadow/dsm_build.wgsl): the open segment from
/// `origin` (its feasible slopes [lo, hi]) and the last input node it covers, if it covers any
/// (`open`); the next input node `i`; the vertices so far.
struct Fit {
    origin: Node,
    last: Node,
    lo: f32,
    hi: f32,
    i: usize,
    open: bool,
    out: Vec<Node>,
}

impl Fit {
    fn new(nodes: &[Node]) -> Option<Self> {
        let &first = nodes.first()?;
        Some(Self {
            origin: first,
            last: first,
            lo: -ANY_SLOPE,
            hi: ANY_SLOPE,
            i: 1,
            open: false,
            out: vec![first],
        })
    }

    /// One step at input node p (node `i`): p fits and the open segment extends over it, or the
    /// segment closes at the last node it covers (a vertex) and p is looked at again from
    /// there; with no segment open p becomes a vertex itself.
    fn step(&mut self, p: Node, eps: f32) {
        let dz = p.z - self.origin.z;
        let (mut new_lo, mut new_hi) = (self.lo, self.hi);
        if dz > 0.0 {
            let r = 1.0 / dz;
            new_lo = self.lo.max((p.value - eps - self.origin.value) * r);
            new_hi = self.hi.min((p.value + eps - self.origin.value) * r);
        } else if (p.value - self.origin.value).abs() > eps {
            (new_lo, new_hi) = (ANY_SLOPE, -ANY_SLOPE);
        }
        if new_lo <= new_hi {
            (self.lo, self.hi, self.last, self.open) = (new_lo, new_hi, p, true);
            self.i += 1;
            return;
        }
        let vertex = if self.open {
            close_segment(self.origin, self.last, self.lo, self.hi, eps)
        } else {
            self.i += 1;
            p
        };
        self.out.push(vertex);
        (self.origin, self.lo, self.hi, self.open) = (vertex, -ANY_SLOPE, ANY_SLOPE, false);
    }

    /// The vertices: the open segment closed, unless the fit stopped past `limit`.
    fn finish(mut self, eps: f32, limit: usize) -> Vec<Node> {
        if self.open && self.out.len() <= limit {
            self.out
                .push(close_segment(self.origin, self.last, self.lo, self.hi, eps));
        }
        self.out
    }
}

/// A texel's `dsm` nodes and the tolerance they were fitted with.
#[derive(Clone, Debug, PartialEq)]
pub struct DsmFit {
    pub nodes: Vec<Node>,
    pub tolerance: f32,
}

/// `dsm`'s compression of one texel's optical depth nodes to at most `limit` (≥ 2): the list
/// itself when it fits, else the fit at ε = 0 when that fits, else the fit at the smallest
/// multiple of the grain g = Ω_max / 2^`steps` that fits, searched as the GPU does: a search
/// over the powers g·2^k (k = -1 standing for ε = 0, k = `steps` for Ω_max, where the fit is one
/// flat segment) for neighbouring ones that fail and fit, first at [`first_power`] and its
/// neighbour, then by bisection of the exponents left, then bisection between the two powers to
/// one grain.
pub fn dsm_compress(nodes: &[Node], limit: usize, steps: u32) -> DsmFit {
    if nodes.len() <= limit {
        return DsmFit {
            nodes: nodes.to_vec(),
            tolerance: 0.0,
        };
    }
    let fits = |eps: f32| greedy_fit(nodes, eps, limit).len() <= limit;
    let mut eps = 0.0;
    if !fits(0.0) {
        // Ω_max fits without trying: one flat segment (shaders/shadow/dsm_build.wgsl says why).
        let omega_max = nodes[nodes.len() - 1].value;
        debug_assert!(
            limit < 2 || fits(omega_max),
            "a fit within Ω_max is one segment"
        );
        let grain = omega_max / (1u64 << steps) as f32;
        let power = |k: i32| {
            if k < 0 {
                0.0
            } else {
                grain * (1u64 << k) as f32
            }
        };
        let (k_lo, k_hi) = power_bracket(first_power(limit, steps), steps, |k| fits(power(k)));
        let (mut lo, mut hi) = (power(k_lo), power(k_hi));
        while hi - lo > grain {
            let mid = 0.5 * (lo + hi);
            if fits(mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        eps = hi;
    }
    let mut fitted = greedy_fit(nodes, eps, limit);
    fitted.truncate(limit);
    DsmFit {
        nodes: fitted,
        tolerance: eps,
    }
}

/// The powers' search (`power_to_try` in shaders/shadow/dsm_build.wgsl): the neighbouring
/// exponents (lo, hi) in -1..=`steps` with `fits(lo)` false and `fits(hi)` true, given that
/// `fits(-1)` is false and `fits(steps)` true, trying `first` and its neighbour before bisecting
/// what is left.
pub fn power_bracket(first: i32, steps: u32, mut fits: impl FnMut(i32) -> bool) -> (i32, i32) {
    let top = steps as i32;
    let (mut lo, mut hi) = (-1i32, top);
    while hi - lo > 1 {
        let k = match (lo, hi) {
            (-1, h) if h == top => first,
            (-1, h) if h == first => first - 1,
            (l, h) if l == first && h == top => first + 1,
            (l, h) => (l + h).div_euclid(2),
        }
        .clamp(lo + 1, hi - 1);
        if fits(k) {
            hi = k;
        } else {
            lo = k;
        }
    }
    (lo, hi)
}

/// The exponent k of the powers' search's first fit, at g·2^k nearest Ω_max / (2N²) for N =
/// `limit` nodes: `steps` - 1 - round(log2 N²), in integers as the shader computes it
/// (`first_power` in shaders/shadow/dsm_build.wgsl, which says why), within 0..`steps`.
pub fn first_power(limit: usize, steps: u32) -> i32 {
    let n = limit as u64;
    let rounded = (n * n * n * n).max(1).ilog2().div_ceil(2);
    (steps as i32 - 1 - rounded as i32).clamp(0, steps as i32 - 1)
}

/// One texel's value at `z`: `before` in front of the first node (or with none), the last
/// node's value behind the last, linear between.
pub fn evaluate(nodes: &[Node], z: f32, before: f32) -> f32 {
    let (Some(first), Some(last)) = (nodes.first(), nodes.last()) else {
        return before;
    };
    if z <= first.z {
        return before;
    }
    if z >= last.z {
        return last.value;
    }
    let hi = nodes.partition_point(|n| n.z <= z);
    let (a, b) = (nodes[hi - 1], nodes[hi]);
    let t = ((z - a.z) / (b.z - a.z).max(1e-12)).clamp(0.0, 1.0);
    a.value + (b.value - a.value) * t
}

/// A texel's `avsm` transmittance curve while it is built: nodes (z, T) sorted by z.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AvsmCurve {
    pub nodes: Vec<Node>,
}

impl AvsmCurve {
    /// T at z: 1 in front of the first node, the last node's T behind the last, linear between.
    pub fn at(&self, z: f32) -> f32 {
        evaluate(&self.nodes, z, 1.0)
    }

    /// Inserts a segment as `pieces` linear pieces: an entry node at z0 with the curve's T
    /// there, an exit node at z1 with the curve's T there times e^−optical_depth, and every node
    /// behind z0 multiplied by the segment's ramp (1 at z0, e^−optical_depth at z1 and beyond).
    /// One piece is the paper's chord, its ramp linear; more put the pieces' interior ends at
    /// the curve's T times the chord's own exponential T, and ramp exponentially
    /// (`avsm_chord = pieces`).
    pub fn insert_segment(&mut self, s: Segment, pieces: u32) {
        let t_exit = (-s.optical_depth).exp();
        let t_entry = self.at(s.z0);
        let t_behind = self.at(s.z1) * t_exit;
        let share = |j: u32| j as f32 / pieces as f32;
        let depth = |j: u32| s.z0 + (s.z1 - s.z0) * share(j);
        let inner: Vec<Node> = (1..pieces)
            .map(|j| {
                let z = depth(j);
                Node::new(z, self.at(z) * (-s.optical_depth * share(j)).exp())
            })
            .collect();
        let width = (s.z1 - s.z0).max(1e-12);
        for n in &mut self.nodes {
            if n.z > s.z0 {
                let u = ((n.z - s.z0) / width).min(1.0);
                n.value *= match pieces {
                    1 => 1.0 + (t_exit - 1.0) * u,
                    _ => (-s.optical_depth * u).exp(),
                };
            }
        }
        self.insert_node(Node::new(s.z0, t_entry));
        for node in inner {
            self.insert_node(node);
        }
        self.insert_node(Node::new(s.z1, t_behind));
    }

    /// Inserts after every node at depth <= z.
    fn insert_node(&mut self, node: Node) {
        let at = self.nodes.partition_point(|n| n.z <= node.z);
        self.nodes.insert(at, node);
    }

    /// Removes the interior node whose removal changes the area under the curve least (twice
    /// the triangle it forms with its neighbours; the first of equals). Needs 3 nodes or more.
    pub fn remove_least_area(&mut self) {
        let n = &self.nodes;
        let area = |k: usize| {
            let (a, b, c) = (n[k - 1], n[k], n[k + 1]);
            ((b.z - a.z) * (c.value - a.value) - (c.z - a.z) * (b.value - a.value)).abs()
        };
        let mut best = 1;
        for k in 2..n.len() - 1 {
            if area(k) < area(best) {
                best = k;
            }
        }
        self.nodes.remove(best);
    }
}

/// `avsm`'s curve of one texel under `limit` (≥ 2) nodes: `segments` inserted in the order
/// given (draw order, or sorted by depth), each as `pieces` linear pieces, the least-area
/// interior node removed after each while there are more than `limit`.
pub fn avsm_compress(segments: &[Segment], limit: usize, pieces: u32) -> Vec<Node> {
    let mut curve = AvsmCurve::default();
    for &s in segments {
        curve.insert_segment(s, pieces);
        while curve.nodes.len() > limit {
            curve.remove_least_area();
        }
    }
    curve.nodes
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nodes(pairs: &[(f32, f32)]) -> Vec<Node> {
        pairs.iter().map(|&(z, v)| Node::new(z, v)).collect()
    }

    /// A ramp of slope 1 to (2, 2), then flat to (4, 2).
    fn ramp_then_flat() -> Vec<Node> {
        nodes(&[(0.0, 0.0), (1.0, 1.0), (2.0, 2.0), (3.0, 2.0), (4.0, 2.0)])
    }

    #[test]
    fn the_merge_adds_the_slopes_of_open_segments() {
        // Slopes 0.5 on [0, 2] and 1 on [1, 3]: Ω(1) = 0.5, Ω(2) = 0.5 + 1.5, Ω(3) = 2 + 1.
        let mut segments = vec![Segment::new(1.0, 3.0, 2.0), Segment::new(0.0, 2.0, 1.0)];
        sort_segments(&mut segments);
        assert_eq!(
            optical_depth_nodes(&segments),
            nodes(&[(0.0, 0.0), (1.0, 0.5), (2.0, 2.0), (3.0, 3.0)])
        );
    }

    #[test]
    fn the_sort_key_is_total() {
        let mut a = vec![
            Segment::new(1.0, 2.0, 0.5),
            Segment::new(1.0, 2.0, 0.25),
            Segment::new(1.0, 1.5, 0.75),
        ];
        let mut b = a.clone();
        b.reverse();
        sort_segments(&mut a);
        sort_segments(&mut b);
        assert_eq!(a, b);
        assert_eq!(a[0], Segment::new(1.0, 1.5, 0.75));
        assert_eq!(a[1], Segment::new(1.0, 2.0, 0.25));
    }

    #[test]
    fn a_lossless_fit_keeps_the_corners_and_drops_collinear_nodes() {
        // Slope 1 up to z = 2, then 0: (1, 1) and (3, 2) lie on the segments.
        assert_eq!(
            greedy_fit(&ramp_then_flat(), 0.0, usize::MAX),
            nodes(&[(0.0, 0.0), (2.0, 2.0), (4.0, 2.0)])
        );
    }

    #[test]
    fn a_tolerant_fit_extends_each_segment_while_a_slope_fits() {
        // eps = 0.5 from (0, 0): the slope intervals narrow to [0.75, 0.833] after (3, 2) and
        // empty at (4, 2) ([0.75, 0.625]), so the first segment ends at z = 3 with the middle
        // slope 0.7917: value 2.375. From there the interval is [-0.875, 0.125]; slope 0.
        let fit = greedy_fit(&ramp_then_flat(), 0.5, usize::MAX);
        assert_eq!(fit.len(), 3);
        assert_eq!(
            (fit[0], fit[1].z, fit[2].z),
            (Node::new(0.0, 0.0), 3.0, 4.0)
        );
        assert!((fit[1].value - 2.375).abs() < 1e-6, "{fit:?}");
        assert!((fit[2].value - 2.375).abs() < 1e-6, "{fit:?}");
        // Within the tolerance at every input node (and so, both being linear between input
        // depths, everywhere).
        for n in ramp_then_flat() {
            assert!((evaluate(&fit, n.z, 0.0) - n.value).abs() <= 0.5 + 1e-6);
        }
        // Within Ω_max = 2 the whole list is one segment.
        assert_eq!(greedy_fit(&ramp_then_flat(), 2.0, usize::MAX).len(), 2);
        // A limit stops the count early.
        assert_eq!(greedy_fit(&ramp_then_flat(), 0.0, 1).len(), 2);
    }

    #[test]
    fn the_search_finds_the_smallest_tolerance_for_the_budget() {
        // Two nodes: one line from (0, 0) to z = 4 with slope m, off by |m - 1|, |2m - 2|,
        // |3m - 2| and |4m - 2| at the inner nodes; the largest is smallest at m = 2/3, where
        // 2|m - 1| = |4m - 2| = 2/3.
        let fit = dsm_compress(&ramp_then_flat(), 2, 20);
        assert!((fit.tolerance - 2.0 / 3.0).abs() < 1e-5, "{fit:?}");
        assert_eq!(fit.nodes.len(), 2);
        assert!((fit.nodes[1].value - 8.0 / 3.0).abs() < 1e-4, "{fit:?}");
        // On a coarse grain (Ω_max / 2^4 = 0.125) it is the smallest multiple that fits.
        let coarse = dsm_compress(&ramp_then_flat(), 2, 4);
        assert_eq!(coarse.tolerance, 0.75, "{coarse:?}");
        assert!(greedy_fit(&ramp_then_flat(), 0.625, 2).len() > 2);
        // Three nodes hold it exactly; five hold the list as it is.
        let three = dsm_compress(&ramp_then_flat(), 3, 20);
        assert_eq!((three.tolerance, three.nodes.len()), (0.0, 3));
        assert_eq!(
            dsm_compress(&ramp_then_flat(), 5, 20).nodes,
            ramp_then_flat()
        );
    }

    #[test]
    fn the_first_power_is_the_nearest_to_half_omega_max_over_n_squared() {
        // g·2^k = Ω_max·2^(k - S) nearest Ω_max / (2N²): k = S - 1 - 2·log2(N), rounded.
        for steps in [8u32, 12, 16] {
            for n in 2..=64usize {
                let exact = f64::from(steps) - 1.0 - 2.0 * (n as f64).log2();
                let want = (exact.round() as i32).clamp(0, steps as i32 - 1);
                assert_eq!(first_power(n, steps), want, "N {n}, S {steps}");
            }
        }
        // The brackets most texels of the thesis frame end in (docs/studies.md): [3, 4] at 12
        // nodes (24 channels), [6, 7] at 4.
        assert_eq!(first_power(12, 12), 4);
        assert_eq!(first_power(4, 12), 7);
    }

    #[test]
    fn the_powers_search_finds_the_bracket_within_its_bound_from_any_first_power() {
        // For every place the boundary can be (fits(k) for k >= boundary) and every first
        // power, the search ends at (boundary - 1, boundary), in at most 2 + bit length of S
        // fits (`SEARCH_STEPS` in src/shadow/dsm.rs counts on it), and in two where the
        // boundary is the first power or the one after it.
        for steps in [1u32, 2, 5, 12, 16] {
            let bound = 2 + (u32::BITS - steps.leading_zeros());
            for first in 0..steps as i32 {
                for boundary in 0..=steps as i32 {
                    let mut tries = Vec::new();
                    let bracket = power_bracket(first, steps, |k| {
                        tries.push(k);
                        k >= boundary
                    });
                    assert_eq!(
                        bracket,
                        (boundary - 1, boundary),
                        "S {steps}, first {first}"
                    );
                    assert!(
                        tries.iter().all(|&k| (0..steps as i32).contains(&k)),
                        "{tries:?}"
                    );
                    assert!(tries.len() as u32 <= bound, "S {steps}: {tries:?}");
                    if (boundary == first || boundary == first + 1) && steps > 1 {
                        assert!(tries.len() <= 2, "S {steps}, first {first}: {tries:?}");
                    }
                }
            }
        }
    }

    /// A deterministic list of overlapping segments (a 32-bit LCG).
    fn random_segments(seed: u32, count: usize) -> Vec<Segment> {
        let mut state = seed;
        let mut next = || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1u32 << 24) as f32
        };
        let mut segments: Vec<_> = (0..count)
            .map(|_| {
                let z0 = 10.0 + 4.0 * next();
                Segment::new(z0, z0 + 0.05 + next(), 0.5 * next())
            })
            .collect();
        sort_segments(&mut segments);
        segments
    }

    #[test]
    fn two_steps_a_loaded_texel_loop_within_the_rounds_allowance() {
        // The shader's fit (`fit_iteration` in shaders/shadow/dsm_build.wgsl) loads the texel of
        // node i (nodes 2j and 2j + 1 in texel j), steps at i, and steps again where the next
        // node is in that texel and the fit has not stopped. Replayed here: the same vertices as
        // one step a loop, in at most n + N + 1 loop iterations (with the exit's) for n
        // segments and N nodes, the allowance `dsm::rounds` gives a search fit.
        for seed in 0..40 {
            for count in [1, 2, 3, 9, 40, 200] {
                let nodes = optical_depth_nodes(&random_segments(seed, count));
                let top = nodes.last().unwrap().value;
                for limit in [2, 3, 6, 12, 16] {
                    for eps in [0.0, 1e-4 * top, 1e-3 * top, 1e-2 * top, 0.1 * top, top] {
                        let mut fit = Fit::new(&nodes).unwrap();
                        let mut iterations = 0;
                        loop {
                            iterations += 1;
                            if fit.i >= nodes.len() || fit.out.len() > limit {
                                break;
                            }
                            let at = fit.i;
                            fit.step(nodes[at], eps);
                            if fit.i / 2 == at / 2 && fit.out.len() <= limit {
                                fit.step(nodes[fit.i], eps);
                            }
                        }
                        assert_eq!(
                            fit.finish(eps, limit),
                            greedy_fit(&nodes, eps, limit),
                            "seed {seed}, {count} segments, N {limit}, eps {eps}"
                        );
                        assert!(
                            iterations <= count + limit + 1,
                            "seed {seed}, {count} segments, N {limit}: {iterations}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn fits_of_random_lists_stay_within_their_tolerance_and_budget() {
        for seed in 0..20 {
            let input = optical_depth_nodes(&random_segments(seed, 40));
            for limit in [2, 3, 5, 8, 16] {
                let fit = dsm_compress(&input, limit, 20);
                assert!(fit.nodes.len() <= limit && fit.nodes.len() >= 2);
                assert_eq!(fit.nodes[0], input[0], "the first node is kept");
                assert!(fit.nodes.windows(2).all(|w| w[0].z <= w[1].z));
                assert!(
                    fit.nodes.windows(2).all(|w| w[0].value <= w[1].value),
                    "a fit of a non-decreasing Ω does not decrease"
                );
                let slack = 1e-5 * input.last().unwrap().value;
                for n in &input {
                    let off = (evaluate(&fit.nodes, n.z, 0.0) - n.value).abs();
                    assert!(off <= fit.tolerance + slack, "seed {seed}, {limit} nodes");
                }
            }
        }
    }

    #[test]
    fn avsm_multiplies_the_nodes_behind_an_entry_by_its_ramp() {
        // A: T from 1 at 0 to 1/2 at 2. B (T 1 -> 1/2 over [1, 3]) enters where A's T is 3/4,
        // scales A's exit by its ramp at the middle (3/4): 3/8, and leaves at 1/2 · 1/2.
        let half = std::f32::consts::LN_2;
        let mut curve = AvsmCurve::default();
        curve.insert_segment(Segment::new(0.0, 2.0, half), 1);
        assert_eq!(curve.nodes, nodes(&[(0.0, 1.0), (2.0, 0.5)]));
        curve.insert_segment(Segment::new(1.0, 3.0, half), 1);
        let expected = [(0.0, 1.0), (1.0, 0.75), (2.0, 0.375), (3.0, 0.25)];
        assert_eq!(curve.nodes.len(), 4);
        for (n, (z, t)) in curve.nodes.iter().zip(expected) {
            assert_eq!(n.z, z);
            assert!((n.value - t).abs() < 1e-6, "{:?}", curve.nodes);
        }
        // Twice the triangle areas: 0.125 at z = 1, 0.25 at z = 2: the node at 1 goes.
        curve.remove_least_area();
        assert_eq!(curve.nodes.len(), 3);
        assert_eq!((curve.nodes[1].z, curve.nodes[2].z), (2.0, 3.0));
        let sorted = [Segment::new(0.0, 2.0, half), Segment::new(1.0, 3.0, half)];
        assert_eq!(avsm_compress(&sorted, 3, 1), curve.nodes);
        assert_eq!(avsm_compress(&sorted, 4, 1).len(), 4);
    }

    /// T through overlapping chords, each of uniform extinction along the ray: the product of
    /// every chord's exp(−optical depth × the share of it in front of z).
    fn closed_form_t(segments: &[Segment], z: f32) -> f32 {
        let omega: f32 = segments
            .iter()
            .map(|s| s.optical_depth * ((z - s.z0) / (s.z1 - s.z0)).clamp(0.0, 1.0))
            .sum();
        (-omega).exp()
    }

    /// RMS of a curve's T against the closed form at 400 depths over the segments' span.
    fn rms_against_closed_form(nodes: &[Node], segments: &[Segment]) -> f32 {
        let (lo, hi) = (
            segments[0].z0,
            segments.iter().map(|s| s.z1).fold(0.0, f32::max),
        );
        let sum: f32 = (0..400)
            .map(|i| {
                let z = lo + (hi - lo) * i as f32 / 399.0;
                (evaluate(nodes, z, 1.0) - closed_form_t(segments, z)).powi(2)
            })
            .sum();
        (sum / 400.0).sqrt()
    }

    #[test]
    fn a_chord_in_pieces_converges_to_its_exponential_where_the_linear_chord_cannot() {
        // One thick chord (optical depth 3): linear T inside it is off exp(−3u) by up to 0.3
        // at any budget; in P pieces the error falls like 1/P².
        let one = [Segment::new(0.0, 1.0, 3.0)];
        let max_off = |pieces| {
            let nodes = avsm_compress(&one, 64, pieces);
            (0..=100)
                .map(|i| {
                    let z = i as f32 / 100.0;
                    (evaluate(&nodes, z, 1.0) - (-3.0 * z).exp()).abs()
                })
                .fold(0.0f32, f32::max)
        };
        assert!(max_off(1) > 0.25, "{}", max_off(1));
        let offs: Vec<f32> = [2, 4, 8].into_iter().map(max_off).collect();
        assert!(
            offs[0] < 0.5 * max_off(1) && offs[1] < 0.35 * offs[0],
            "{offs:?}"
        );
        assert!(offs[2] < 0.35 * offs[1], "{offs:?}");
        // Eight overlapping chords (a column of spheres along the ray), inserted in a draw
        // order unrelated to depth: the linear chord stops gaining from 8 nodes on, the pieces
        // (ceil(N/4) a chord, as `avsm_chord = pieces` inserts them) keep gaining.
        let column: Vec<Segment> = (0..8)
            .map(|i| Segment::new(i as f32 * 0.5, i as f32 * 0.5 + 1.0, 1.2))
            .collect();
        let shuffled = &insertion_orders(&column, 7)[2];
        let error = |limit: usize, pieces: u32| {
            rms_against_closed_form(&avsm_compress(shuffled, limit, pieces), &column)
        };
        let limits = [4, 8, 12, 16];
        let linear: Vec<f32> = limits.iter().map(|&n| error(n, 1)).collect();
        let pieces: Vec<f32> = limits
            .iter()
            .map(|&n| error(n, (n as u32).div_ceil(4)))
            .collect();
        println!("linear chord {linear:?}, in pieces {pieces:?}");
        assert!(
            pieces.windows(2).all(|w| w[1] < w[0]),
            "pieces must converge: {pieces:?}"
        );
        assert!(pieces[3] < 0.5 * linear[3], "{pieces:?} against {linear:?}");
    }

    /// The insertion orders `avsm` may see: sorted by depth, reversed, and a deterministic
    /// shuffle (a draw order unrelated to depth).
    fn insertion_orders(sorted: &[Segment], seed: u32) -> [Vec<Segment>; 3] {
        let reversed: Vec<_> = sorted.iter().rev().copied().collect();
        let mut shuffled = sorted.to_vec();
        let mut state = seed ^ 0x9e37_79b9;
        for i in (1..shuffled.len()).rev() {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            shuffled.swap(i, (state >> 8) as usize % (i + 1));
        }
        [sorted.to_vec(), reversed, shuffled]
    }

    #[test]
    fn avsm_keeps_its_ends_and_the_budget_in_any_insertion_order() {
        for seed in 0..20 {
            let sorted = random_segments(seed, 40);
            let total: f32 = sorted.iter().map(|s| s.optical_depth).sum();
            let last_exit = sorted.iter().map(|s| s.z1).fold(f32::MIN, f32::max);
            let cases = [(2, 1), (3, 1), (8, 1), (16, 1), (8, 2), (16, 4)];
            for (order, segments) in insertion_orders(&sorted, seed).iter().enumerate() {
                for (limit, pieces) in cases {
                    let curve = avsm_compress(segments, limit, pieces);
                    assert_eq!(curve.len(), limit);
                    // The first node is the nearest entry, where T is still 1.
                    assert_eq!(curve[0], Node::new(sorted[0].z0, 1.0), "order {order}");
                    let last = curve[limit - 1];
                    // The last node is the deepest exit, with the whole ray's transmittance.
                    assert_eq!(last.z, last_exit);
                    assert!(
                        (last.value - (-total).exp()).abs() < 1e-4,
                        "seed {seed}, order {order}"
                    );
                    assert!(curve.windows(2).all(|w| w[0].z <= w[1].z));
                    assert!(curve.windows(2).all(|w| w[0].value >= w[1].value - 1e-6));
                }
            }
        }
    }

    #[test]
    fn avsm_without_removals_does_not_depend_on_the_order_of_disjoint_segments() {
        // Disjoint segments: every entry and exit lands on a flat part of the curve (or beyond
        // it), where the linear T is exact, so with room for every node the order of insertion
        // changes nothing but rounding. Streaming `avsm` differs from sorted only through what
        // its removals drop, and through overlaps.
        let sorted: Vec<_> = (0..12)
            .map(|i| {
                let z0 = 1.0 + i as f32;
                Segment::new(z0, z0 + 0.5, 0.1 + 0.05 * i as f32)
            })
            .collect();
        let reference = avsm_compress(&sorted, 2 * sorted.len(), 1);
        assert_eq!(reference.len(), 2 * sorted.len());
        for segments in insertion_orders(&sorted, 7) {
            let curve = avsm_compress(&segments, 2 * sorted.len(), 1);
            for (a, b) in curve.iter().zip(&reference) {
                assert_eq!(a.z, b.z);
                assert!((a.value - b.value).abs() < 1e-6, "{curve:?}");
            }
        }
        // Under a budget the order matters: the removals see different curves.
        let compressed: Vec<_> = insertion_orders(&sorted, 7)
            .iter()
            .map(|segments| avsm_compress(segments, 6, 1))
            .collect();
        assert!(compressed.iter().any(|c| c != &compressed[0]));
    }
}
