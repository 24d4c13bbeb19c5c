// `dsm` build: compresses each texel's captured optical depth (the nodes (z, Ω) of
// shaders/shadow/deep_capture.wgsl) to at most N = deep.nodes_per_texel nodes with Lokovic &
// Veach's error-bounded greedy fit (2000, section 4.2): every output segment starts at the last
// output vertex and extends over the input nodes while some slope passes within ±ε of all of
// them; the output vertices sit at input depths, so between them the fit, like the input, is
// linear and stays within ε everywhere. Per texel the smallest ε whose fit takes at most N nodes
// is found by bisection over [0, Ω_max] (a fit at ε = Ω_max is one flat segment: 2 nodes);
// lists that already fit are copied as they are (ε = 0). Since dT/dΩ = -T, |ΔT| <= |ΔΩ| <= ε.
// The tolerances are summed into `stats` for the report (src/shadow/dsm.rs reads them back).
// Keep `DeepParams` in sync with src/shadow/deep_nodes.rs. The CPU mirror of the fit is
// src/shadow/deep_compress.rs.
#import shadow/deep_capture_lists.wgsl
#import shadow/deep_params.wgsl

// The capture's resolved nodes (shaders/shadow/deep_capture_lists.wgsl), read-only here: nodes
// 2j and 2j + 1 in texel j.
@group(1) @binding(9) var resolved_nodes: texture_storage_2d<rgba32float, read>;

// The texel that holds node `i` of the resolved nodes (z, Ω(z)), and `i`'s own of its two.
fn node_pair(i: u32) -> vec4<f32> {
    return textureLoad(resolved_nodes, row_texel(i >> 1u));
}

fn pick_node(pair: vec4<f32>, i: u32) -> vec2<f32> {
    return select(pair.xy, pair.zw, (i & 1u) == 1u);
}

fn node_texel(i: u32) -> vec2<f32> {
    return pick_node(node_pair(i), i);
}

@group(2) @binding(0) var<uniform> deep: DeepParams;
@group(2) @binding(1) var<storage, read_write> out_nodes: array<vec2<f32>>;
@group(2) @binding(2) var<storage, read_write> stats: array<atomic<u32>>;

// Words of `stats` (src/shadow/dsm.rs names them).
// The largest ε, as its bits (non-negative floats order like their bits).
const STAT_MAX_TOLERANCE: u32 = 0u;
// Σ ε in millionths, 64 bits (low, high word).
const STAT_SUM_LO: u32 = 1u;
const STAT_SUM_HI: u32 = 2u;
// Texels with a non-empty list, and those of them fitted with ε > 0.
const STAT_TEXELS: u32 = 3u;
const STAT_LOSSY: u32 = 4u;

// An unbounded slope, for the feasible interval before it has met a node.
const ANY_SLOPE: f32 = 3.0e38;

// The vertex that closes a segment from `origin` over input nodes up to `last`, with a slope in
// the feasible interval [lo, hi]: its middle, raised to 0 when that is feasible so that the fit
// of a non-decreasing Ω does not decrease; the value clamped to last.y ± eps (float rounding),
// which makes an ε = 0 fit reproduce every vertex it keeps exactly.
fn close_segment(origin: vec2<f32>, last: vec2<f32>, lo: f32, hi: f32, eps: f32) -> vec2<f32> {
    let slope = clamp(max(0.5 * (lo + hi), 0.0), lo, hi);
    let value = origin.y + slope * (last.x - origin.x);
    return vec2<f32>(last.x, clamp(value, last.y - eps, last.y + eps));
}

// A greedy fit under way: the open segment from `origin` (its feasible slopes [lo, hi]) and the
// last input node it covers, if it covers any (`open`); the next input node `i`; the vertices
// so far.
struct Fit {
    origin: vec2<f32>,
    last: vec2<f32>,
    lo: f32,
    hi: f32,
    i: u32,
    count: u32,
    open: bool,
};

// One step of the fit at input node p (node `i`), or none where `live` is false: p fits and the
// open segment extends over it, or the segment closes at the last node it covers and p is
// looked at again from there; a step at the origin's own depth (never in a capture, where equal
// depths carry equal Ω) becomes a vertex of its own. With `write` it stores a new vertex at
// out_nodes[out ..] (at most `limit`). A step's two outcomes are selects, not branches:
// llvmpipe runs every side of one under its lanes' masks anyway.
fn fit_step(
    fit: ptr<function, Fit>,
    p: vec2<f32>,
    eps: f32,
    live: bool,
    limit: u32,
    write: bool,
    out: u32,
) {
    let origin = (*fit).origin;
    let lo = (*fit).lo;
    let hi = (*fit).hi;
    let dz = p.x - origin.x;
    var new_lo = lo;
    var new_hi = hi;
    if dz > 0.0 {
        // One division, not two: the search 134 -> 127 ms on the thesis frame.
        let r = 1.0 / dz;
        new_lo = max(lo, (p.y - eps - origin.y) * r);
        new_hi = min(hi, (p.y + eps - origin.y) * r);
    } else if abs(p.y - origin.y) > eps {
        new_lo = ANY_SLOPE;
        new_hi = -ANY_SLOPE;
    }
    let fits = new_lo <= new_hi;
    let closes = live && !fits;
    let vertex = select(p, close_segment(origin, (*fit).last, lo, hi, eps), (*fit).open);
    (*fit).i += u32(live && (fits || !(*fit).open));
    (*fit).count += u32(closes);
    if write && closes && (*fit).count <= limit {
        out_nodes[out + (*fit).count - 1u] = vertex;
    }
    (*fit).origin = select(origin, vertex, closes);
    (*fit).lo = select(lo, select(-ANY_SLOPE, new_lo, fits), live);
    (*fit).hi = select(hi, select(ANY_SLOPE, new_hi, fits), live);
    (*fit).last = select((*fit).last, p, live && fits);
    (*fit).open = select((*fit).open, fits, live);
}

// A greedy fit's start at node `base`: its first node, a vertex (stored at out_nodes[out] with
// `write`).
fn fit_start(base: u32, write: bool, out: u32) -> Fit {
    let first = node_texel(base);
    if write {
        out_nodes[out] = first;
    }
    return Fit(first, first, -ANY_SLOPE, ANY_SLOPE, 1u, 1u, false);
}

// One iteration of a greedy fit of nodes base .. base + n (base even) within ±eps, or none where
// `go` is false: it loads the texel of the next node and steps at it, then steps again where the
// node after that step is in the same texel (most steps move to the next node, so nearly two
// steps a load; one step a load: the search 69 -> 59 ms on the thesis frame). Stops counting
// past `limit` vertices; with `write` it stores them at out_nodes[out ..] (at most `limit`).
fn fit_iteration(
    fit: ptr<function, Fit>,
    base: u32,
    eps: f32,
    go: bool,
    limit: u32,
    write: bool,
    out: u32,
) {
    let at = (*fit).i;
    // A fit that goes no further loads its first texel (its next may be past the nodes' end).
    let pair = node_pair(base + select(0u, at, go));
    fit_step(fit, pick_node(pair, at), eps, go, limit, write, out);
    // Node fit.i is in this texel when it is `at` or its pair's second; past the list's end
    // never (n is even).
    let again = go && ((*fit).i >> 1u) == (at >> 1u) && (*fit).count <= limit;
    fit_step(fit, pick_node(pair, (*fit).i), eps, again, limit, write, out);
}

// Whether a fit over n nodes has steps left: nodes left, and no more than `limit` vertices.
fn fit_goes(fit: Fit, n: u32, limit: u32) -> bool {
    return fit.i < n && fit.count <= limit;
}

// A greedy fit's number of vertices once its loop has stopped: the open segment, unless it
// stopped past `limit`, closes at the last node, one vertex more (stored with `write`).
fn fit_end(fit: Fit, eps: f32, limit: u32, write: bool, out: u32) -> u32 {
    if fit.count > limit || !fit.open {
        return fit.count;
    }
    let count = fit.count + 1u;
    if write && count <= limit {
        out_nodes[out + count - 1u] = close_segment(fit.origin, fit.last, fit.lo, fit.hi, eps);
    }
    return count;
}

// The greedy fits of two texels' lists at once, `a`'s and `b`'s, within ±eps.x and ±eps.y, one loop
// for both: the vertex counts (each stops as soon as it passes `limit`); with `write` their
// vertices at out_nodes[out ..] (at most `limit` each). A texel whose `live` is false takes no step
// (it loads its partner's first node, a real one, where its own list may be empty). The stop at
// `limit` is in the loop's exit condition (the search 127 -> 115 ms on the thesis frame). Two fits
// a loop because a fit is a chain of dependent steps (each step's interval, division and vertex
// wait on the last one's), which leaves a core idle much of the time: a second fit over the same
// nodes, run beside the first in its loop for the measurement, cost the thesis frame's search 18%
// more; two texels' fits in one loop (their own loads and steps) took the search from 52 to 46 ms
// (docs/studies.md).
fn fit_pair(
    a: Texel,
    b: Texel,
    live: vec2<bool>,
    eps: vec2<f32>,
    limit: u32,
    write: bool,
) -> vec2<u32> {
    let base = vec2<u32>(select(b.base, a.base, live.x), select(a.base, b.base, live.y));
    let n = select(vec2<u32>(0u), vec2<u32>(a.n, b.n), live);
    let write_a = write && live.x;
    let write_b = write && live.y;
    var fit_a = fit_start(base.x, write_a, a.out);
    var fit_b = fit_start(base.y, write_b, b.out);
    loop {
        let go_a = fit_goes(fit_a, n.x, limit);
        let go_b = fit_goes(fit_b, n.y, limit);
        if !go_a && !go_b {
            break;
        }
        fit_iteration(&fit_a, base.x, eps.x, go_a, limit, write_a, a.out);
        fit_iteration(&fit_b, base.y, eps.y, go_b, limit, write_b, b.out);
    }
    return vec2<u32>(
        fit_end(fit_a, eps.x, limit, write_a, a.out),
        fit_end(fit_b, eps.y, limit, write_b, b.out),
    );
}

// The search for ε in steps of one greedy fit each, run in rounds (see src/shadow/deep_capture.rs),
// over the grid of multiples of the grain g = Ω_max / 2^S (S = deep.bisection_steps): the
// smallest multiple of g whose fit takes at most N nodes. The first step fits at ε = 0 (the
// texel is done when that fits). Then a search over the powers of two g·2^k, k in 0..S, finds
// the bracket [g·2^(k-1), g·2^k] (or [0, g]) whose bottom fails and top fits (`power_to_try`):
// g·2^S = Ω_max needs no fit to know it fits (Ω rises from 0 at the first node to Ω_max at the
// last, so every node's feasible slopes from the first, [(Ω - ε)/dz, (Ω + ε)/dz], hold 0 (Ω - ε
// <= 0 <= Ω + ε holds in floats too), and the fit is one segment, 2 nodes, within any budget the
// technique accepts (at least 4 channels: N >= 2)); two fits for most texels, at most 2 +
// log2(S) (a fit that fails stops after N vertices). Then bisection narrows the bracket to one
// grain (its width a power-of-two multiple of g, so every midpoint is a multiple of g, exact in
// floats), and the last step writes the fit at ε = hi. Twelve steps of bisection over [0,
// Ω_max], which this replaced, ran every fit above ε over the whole list. Between rounds the
// search's state lives in the texel's first two sort keys (nothing reads them after the
// resolve): (lo, hi) (while searching the powers, their exponents: k = -1 stands for ε = 0),
// then (mode, 0).
const MODE_START: f32 = 0.0;
const MODE_BISECT: f32 = 1.0;
const MODE_FINAL: f32 = 2.0;
const MODE_POWERS: f32 = 3.0;
const MODE_DONE: f32 = 4.0;

// The exponent of the powers' search to try next in the bracket (lo, hi) of exponents (lo fails, hi
// fits, hi - lo >= 2): first `first` (`first_power()`), the top of the bracket most texels end in;
// then its neighbour on the side its fit leaves open, which closes the bracket where the first was
// its top or bottom; then the middle of what is left. A binary search from the middle, which this
// replaced, took four fits to any bracket (the first, at g·2^5, ran over the whole list for most
// texels); llvmpipe runs a SIMD group's lanes in lockstep, so its fits run as long as its longest
// lane's: the search 59 -> 52 ms on the thesis frame.
fn power_to_try(lo: f32, hi: f32, first: f32) -> f32 {
    let top = f32(deep.bisection_steps);
    var k = floor(0.5 * (lo + hi));
    if lo == -1.0 && hi == top {
        k = first;
    } else if lo == -1.0 && hi == first {
        k = first - 1.0;
    } else if lo == first && hi == top {
        k = first + 1.0;
    }
    return clamp(k, lo + 1.0, hi - 1.0);
}

// The exponent of g·2^k nearest Ω_max / (2N²): a piecewise-linear fit's error falls as the
// square of its segments' length, and at every budget and scene measured (thesis at 4 to 32
// channels, `cloud`, `vdb_smoke`, `ground_fog`, dense thesis at 24) most texels' tolerance lies
// in the bracket just below it (S - 1 - round(log2 N²), with round(log2 N²) = (floor(log2 N⁴) +
// 1) / 2 in integers; src/shadow/deep_compress.rs, `first_power`, mirrors it).
fn first_power() -> f32 {
    let n = deep.nodes_per_texel;
    let rounded = (firstLeadingBit(n * n * n * n) + 1u) / 2u;
    let top = i32(deep.bisection_steps);
    return f32(clamp(top - 1 - i32(rounded), 0, top - 1));
}

// The tolerance g·2^k for exponent k of the powers' search (k = -1: 0).
fn power_eps(grain: f32, k: f32) -> f32 {
    return select(ldexp(grain, i32(k)), 0.0, k < 0.0);
}

// Greedy fits per round: over a list of n segments (2n nodes, two a texel) each loops at most
// n + N + 1 times, the final fit with its padding n + 2N + 1 (src/shadow/dsm.rs, `rounds`, says
// why), within n + 36 each (N <= 16), from the loop budget less LOOPS_BESIDE_FITS: the copy of
// the lists that fit as they are (an invocation's two in one loop of N, in lanes beside those
// that search) and the loops' exits. Keep in sync with `dsm::rounds` and
// `dsm::LOOPS_BESIDE_FITS`.
const LOOPS_BESIDE_FITS: u32 = 64u;
const FIT_LOOPS_BESIDE_LIST: u32 = 36u;

fn fits_per_round() -> u32 {
    let budget = capture.loop_budget - min(capture.loop_budget, LOOPS_BESIDE_FITS);
    return max(1u, budget / (capture.max_list + FIT_LOOPS_BESIDE_LIST));
}

// One texel's compression: its list (its first node `base`, n nodes, output from `out`) and
// the search for its tolerance (`compress`): the bracket (lo, hi) and the mode (the MODE_*
// constants; MODE_DONE for a texel with nothing (left) to search).
struct Texel {
    real: bool,
    base: u32,
    n: u32,
    out: u32,
    grain: f32,
    lo: f32,
    hi: f32,
    mode: f32,
};

// Texel `index`'s compression as it stands at this round (NO_TEXEL: none, done).
fn texel_at(index: u32, limit: u32) -> Texel {
    var t = Texel(index != NO_TEXEL, 0u, 0u, 0u, 0.0, 0.0, 0.0, MODE_DONE);
    if !t.real {
        return t;
    }
    let list = texel_list(index);
    t.base = 2u * list.first;
    t.n = 2u * list.count;
    t.out = index * limit;
    if t.n <= limit {
        // Nothing to search: copied (or zeroed) in the first round (`copy_short_lists`).
        return t;
    }
    let omega_max = node_texel(t.base + t.n - 1u).y;
    t.grain = ldexp(omega_max, -i32(deep.bisection_steps));
    t.mode = MODE_START;
    // Between rounds the search's state waits in the texel's first sort keys, which nothing
    // reads after the resolve: (lo, hi), then (mode, 0).
    if pass_round.index > 0u {
        let bounds = key_at(t.base);
        t.lo = bounds.x;
        t.hi = bounds.y;
        t.mode = key_at(t.base + 1u).x;
    }
    return t;
}

fn searching(t: Texel) -> bool {
    return t.mode != MODE_FINAL && t.mode != MODE_DONE;
}

// Whether the texel's list is longer than the nodes it keeps (it has a search, done or not).
fn searches(t: Texel, limit: u32) -> bool {
    return t.n > limit;
}

fn save_search(t: Texel) {
    set_key_at(t.base, vec2<f32>(t.lo, t.hi));
    set_key_at(t.base + 1u, vec2<f32>(t.mode, 0.0));
}

// The tolerance the search tries next, and what it bounds the bracket with: the exponent while
// searching the powers (lo < it < hi: hi - lo >= 2 there), else the tolerance itself.
fn search_try(t: Texel, first: f32) -> vec2<f32> {
    if t.mode == MODE_START {
        return vec2<f32>(0.0);
    }
    if t.mode == MODE_POWERS {
        let power = power_to_try(t.lo, t.hi, first);
        return vec2<f32>(power_eps(t.grain, power), power);
    }
    let mid = 0.5 * (t.lo + t.hi);
    return vec2<f32>(mid);
}

// The search after the fit at `tried` (search_try's), which fits or not.
fn search_advance(t: ptr<function, Texel>, tried: vec2<f32>, fits: bool) {
    if (*t).mode == MODE_START {
        // Exponents: -1 (ε = 0) fails, S (Ω_max) fits.
        (*t).lo = -1.0;
        (*t).hi = select(f32(deep.bisection_steps), 0.0, fits);
        (*t).mode = select(MODE_POWERS, MODE_FINAL, fits);
    } else {
        (*t).lo = select(tried.y, (*t).lo, fits);
        (*t).hi = select((*t).hi, tried.y, fits);
    }
    if (*t).mode == MODE_POWERS && (*t).hi - (*t).lo <= 1.0 {
        // The bracket between neighbouring powers, in ε.
        (*t).lo = power_eps((*t).grain, (*t).lo);
        (*t).hi = power_eps((*t).grain, (*t).hi);
        (*t).mode = MODE_BISECT;
    }
    if (*t).mode == MODE_BISECT && (*t).hi - (*t).lo <= (*t).grain {
        (*t).mode = MODE_FINAL;
    }
}

// The first round's copy of the lists that fit as they are (the last node repeated into the
// free slots; no smoke on the ray: Ω = 0 at every depth), both texels in one loop.
fn copy_short_lists(a: Texel, b: Texel, limit: u32) {
    let copy = vec2<bool>(a.real && a.n > 0u && a.n <= limit, b.real && b.n > 0u && b.n <= limit);
    let zero = vec2<bool>(a.real && a.n == 0u, b.real && b.n == 0u);
    for (var k = 0u; k < limit; k++) {
        if copy.x {
            out_nodes[a.out + k] = node_texel(a.base + min(k, a.n - 1u));
        } else if zero.x {
            out_nodes[a.out + k] = vec2<f32>(0.0);
        }
        if copy.y {
            out_nodes[b.out + k] = node_texel(b.base + min(k, b.n - 1u));
        } else if zero.y {
            out_nodes[b.out + k] = vec2<f32>(0.0);
        }
    }
    if copy.x {
        record_tolerance(0.0);
    }
    if copy.y {
        record_tolerance(0.0);
    }
}

// Writes the fits at the texels' tolerances (hi) where `live` (at most `limit` vertices each, the
// last repeated into the free slots; one loop for both) and adds them to the statistics.
fn finish_pair(a: Texel, b: Texel, live: vec2<bool>, limit: u32) {
    let eps = vec2<f32>(a.hi, b.hi);
    let written = min(fit_pair(a, b, live, eps, limit, true), vec2<u32>(limit));
    let tail_a = out_nodes[a.out + max(written.x, 1u) - 1u];
    let tail_b = out_nodes[b.out + max(written.y, 1u) - 1u];
    for (var k = min(written.x, written.y); k < limit; k++) {
        if live.x && k >= written.x {
            out_nodes[a.out + k] = tail_a;
        }
        if live.y && k >= written.y {
            out_nodes[b.out + k] = tail_b;
        }
    }
    if live.x {
        record_tolerance(a.hi);
    }
    if live.y {
        record_tolerance(b.hi);
    }
}

fn record_tolerance(eps: f32) {
    atomicMax(&stats[STAT_MAX_TOLERANCE], bitcast<u32>(eps));
    let millionths = u32(round(eps * 1e6));
    let before = atomicAdd(&stats[STAT_SUM_LO], millionths);
    if before > 0xffffffffu - millionths {
        atomicAdd(&stats[STAT_SUM_HI], 1u);
    }
    atomicAdd(&stats[STAT_TEXELS], 1u);
    if eps > 0.0 {
        atomicAdd(&stats[STAT_LOSSY], 1u);
    }
}

// Each invocation compresses two texels of its tile, the tile's places 2i and 2i + 1 in the
// order `order_texels` left (longest list first, so the two are about as long), searching both
// in the same loops (`fit_pair` says why).
@compute @workgroup_size(8, 4)
fn compress(
    @builtin(workgroup_id) tile: vec3<u32>,
    @builtin(local_invocation_index) place: u32,
) {
    let limit = deep.nodes_per_texel;
    var a = texel_at(tile_texel(tile.xy, 2u * place), limit);
    var b = texel_at(tile_texel(tile.xy, 2u * place + 1u), limit);
    if pass_round.index == 0u {
        copy_short_lists(a, b, limit);
    }
    if a.mode == MODE_DONE && b.mode == MODE_DONE {
        return;
    }
    let per_round = fits_per_round();
    let first = first_power();
    // The search's fits, then the final fit outside their loop: every lane of a SIMD group that
    // has its ε by then writes its fit in the same pass over the lists. (A final fit inside the
    // loop ran once for each step at which some lane of the group finished: the search 107 -> 94
    // ms on the thesis frame.) llvmpipe counts loop iterations per SIMD group, whichever lanes
    // run them, so a group's fits in one dispatch, the search's in lockstep and then the final
    // one, stay within `per_round`: at most per_round - 1 search fits, and with one fit a
    // round, search fits in even rounds and final fits in odd ones (`dsm::rounds`). A fit of
    // two texels at once is one fit here: one loop over the longer list.
    var search_fits = per_round - 1u;
    var may_finish = true;
    if per_round == 1u {
        search_fits = 1u - pass_round.index % 2u;
        may_finish = search_fits == 0u;
    }
    var steps = 0u;
    loop {
        let live = vec2<bool>(searching(a), searching(b));
        if steps >= search_fits || !any(live) {
            break;
        }
        steps++;
        let try_a = search_try(a, first);
        let try_b = search_try(b, first);
        let eps = vec2<f32>(try_a.x, try_b.x);
        let counts = fit_pair(a, b, live, eps, limit, false);
        if live.x {
            search_advance(&a, try_a, counts.x <= limit);
        }
        if live.y {
            search_advance(&b, try_b, counts.y <= limit);
        }
    }
    let finals = vec2<bool>(a.mode == MODE_FINAL, b.mode == MODE_FINAL) & vec2<bool>(may_finish);
    if any(finals) {
        finish_pair(a, b, finals, limit);
        a.mode = select(a.mode, MODE_DONE, finals.x);
        b.mode = select(b.mode, MODE_DONE, finals.y);
    }
    if searches(a, limit) {
        save_search(a);
    }
    if searches(b, limit) {
        save_search(b);
    }
}
