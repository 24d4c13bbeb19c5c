//! `dsm`: the deep shadow map (Lokovic & Veach 2000; thesis 3.3.3.1) under a channel budget.
//!
//! The deep capture (`deep_capture.rs`) gives every texel its exact piecewise-linear optical
//! depth Ω(z) as sorted nodes; the compression (shaders/shadow/dsm_build.wgsl) refits it with
//! Lokovic & Veach's error-bounded greedy fit to at most N = floor(B / 2) nodes (depth, Ω) of
//! 32-bit floats, choosing per texel the smallest tolerance ε (a multiple of Ω_max / 2^12) that
//! fits in N. The fit stays within ±ε of Ω at every depth, and since dT/dΩ = −T, within ε of T
//! too. With enough nodes for a texel's whole list it is copied as is (ε = 0): the uncompressed
//! deep shadow map.
//!
//! The lookup (shaders/shadow/dsm.wgsl) evaluates Ω in each of the four texels around a point,
//! blends them bilinearly and returns exp(−Ω).
//!
//! **Why Ω and not visibility.** Lokovic & Veach store and fit the visibility function V(z) = T
//! and interpolate it linearly between nodes; this fits optical depth and returns exp(−Ω). The
//! paper's guarantee is what matters, and it carries over: the fit is the same greedy
//! piecewise-linear fit with a tolerance, and since |ΔT| = T·|ΔΩ| ≤ |ΔΩ| an ε-fit of Ω is within
//! ε of T everywhere, so the error bound L&V give in visibility holds as stated. What differs is
//! inside the smoke: for the particle model the exact Ω(z) of a texel *is* piecewise linear (a
//! constant extinction along each chord), so the Ω fit reproduces an uncompressed texel exactly,
//! where a piecewise-linear V would be off by up to 0.3 inside one thick particle (the error
//! `avsm`, which keeps T linear, shows: docs/studies.md, "The families side by side"). Fitting visibility
//! would measure the representation's error, not the compression's. (L&V's hair and fur are
//! opaque surfaces, where V is a step and the distinction vanishes.)
//!
//! **Cost.** The capture-and-resolve passes (every fragment appended to its texel's list, then a
//! sort and a fit per texel in compute) emulate what hardware with fragment-shader interlock
//! (Intel's PixelSync, Vulkan's `VK_EXT_fragment_shader_interlock`) does in one pass, inserting
//! and compressing as fragments arrive; WebGPU has no interlock, so the timings of `dsm` and
//! `avsm` are those of the emulation, an upper bound on an engine's.
//!
//! The tolerances are reported honestly: the compression accumulates them and the build reads
//! them back ([`super::ShadowTechnique::counters`]): `max_tolerance_e6` and
//! `mean_tolerance_e6` (over the texels with smoke) in millionths of optical depth, `fitted_texels`
//! and `lossy_texels` (those with ε > 0). The CPU mirror of the fit is `deep_compress.rs`.
//!
//! Memory: the nodes (texels × N × 8 bytes) and a 16-byte uniform; the capture's lists and the
//! statistics are transient (allocated, counted, and reported apart).

use super::deep_capture::Resolve;
use super::deep_nodes::{DeepNodes, DeepNodesSpec, nodes_per_texel};
use super::{Role, TechniqueEntry, TechniqueParams};

/// The grain of the per-texel tolerance: ε is the smallest multiple of Ω_max / 2^12 whose fit
/// takes at most N nodes (0.1% of the ray's optical depth; the mean ε is a few percent of it at
/// 24 channels), searched over the powers of two first, then by bisection between two of them
/// (shaders/shadow/dsm_build.wgsl). Twelve steps of bisection over [0, Ω_max] found it before,
/// with every fit above it run over the whole list. The search's pass on the thesis frame
/// (lavapipe, ms, before -> after): 24 channels 164 -> 134, 16: 160 -> 134, 12: 157 -> 144, 8:
/// 170 -> 162, 6: 153 -> 181 (at 3 nodes a texel ε is a large part of Ω_max, and the
/// bisection between powers takes nearly as many steps as it did over [0, Ω_max]). Where a
/// texel's count of nodes is not monotone in ε it can stop at a smaller ε (mean 32.0e-3 against
/// 31.7e-3 at 24 channels, images within FLIP 0.0003). 20 steps, as before that, cost the
/// frame 18% more (2.29 s against 1.89 s then) for images within FLIP 0.0006.
pub const BISECTION_STEPS: u32 = 12;

pub const SPEC: DeepNodesSpec = DeepNodesSpec {
    name: "dsm",
    build_shader: "shadow/dsm_build.wgsl",
    bisection_steps: BISECTION_STEPS,
    stats_words: 5,
    stats_counters: tolerance_counters,
    rounds: |max_list, loop_budget, _| rounds(max_list, loop_budget),
    resolve: |_| Resolve::Nodes,
    compress_constants: |_, _| Vec::new(),
    shader_variants: |channels| vec![TechniqueParams::new(channels, 512)],
};

/// Steps of the per-texel search, one greedy fit each (shaders/shadow/dsm_build.wgsl), at most:
/// the fit at ε = 0, the search over the exponents -1..=`BISECTION_STEPS` of the powers of two
/// (two fits, at the first power and a neighbour, then a binary search over at most
/// `BISECTION_STEPS` - 1 exponents left: at most the bit length of `BISECTION_STEPS` fits), the
/// bisection of the bracket it leaves (at most `BISECTION_STEPS` - 1), the final fit.
const SEARCH_STEPS: u32 = BISECTION_STEPS + 3 + (u32::BITS - BISECTION_STEPS.leading_zeros());

/// Rounds of the compression: a greedy fit over the 2n nodes of n segments steps at most
/// 2n + N - 1 times: each node after the first once, and a look again after each closed
/// segment, at most N of them before it stops (N <= 16). It takes two steps a loop iteration
/// where the second node is in the first one's texel (`fit_iteration` in the shader); an
/// iteration of one step starts at the second node of a texel, which the first iteration and at
/// most one after each closed segment do, and the one that stops the fit may take one too: at
/// most N + 2 of them. So at most (2n + N - 1 + N + 2) / 2 iterations, n + N + 1 with the
/// loop's exit; the final fit adds its padding of the unused nodes, at most N. Within
/// n + `FIT_LOOPS_BESIDE_LIST` each, a round has room for `per_round` = `(loop_budget -
/// LOOPS_BESIDE_FITS) / (max_list + 36)` fits (`fits_per_round` in the shader; two steps an
/// iteration doubled it). llvmpipe counts a SIMD group's loop iterations, whichever of its
/// lanes run them, so a round's fits are the group's: at most per_round - 1 search fits in
/// lockstep, then the final fit of every lane that has its ε. (Each lane fits two texels in
/// one loop, `fit_pair`: that loop runs as long as the longer fit, within the same allowance.)
/// The search fits (`SEARCH_STEPS` - 1) take ceil((SEARCH_STEPS - 1) / (per_round - 1))
/// rounds, the final fit in the round of the last; with room for one fit a round, search fits
/// run in even rounds and final fits in odd ones.
fn rounds(max_list: u32, loop_budget: u32) -> u32 {
    let search_fits = SEARCH_STEPS - 1;
    match fits_per_round(max_list, loop_budget) {
        1 => 2 * search_fits,
        per_round => search_fits.div_ceil(per_round - 1),
    }
}

/// The greedy fits a round has room for (`fits_per_round` in the shader; [`rounds`] says why).
fn fits_per_round(max_list: u32, loop_budget: u32) -> u32 {
    (loop_budget.saturating_sub(LOOPS_BESIDE_FITS) / (max_list + FIT_LOOPS_BESIDE_LIST)).max(1)
}

/// Loop iterations a round spends beside its fits' allowances of 2n + 20, taken from the budget
/// first (`LOOPS_BESIDE_FITS` in the shader): the copy of a list that fits as it is (N + 1
/// iterations, N <= 16, in lanes of a SIMD group beside those that search), the search loop's
/// exit and the final fit's padding beyond its allowance. 64 holds them with room to spare.
const LOOPS_BESIDE_FITS: u32 = 64;

/// A greedy fit's loop iterations beyond one a segment of its list, at most: N + 1 for a search
/// fit, 2N + 1 for the final one with its padding, N <= 16 ([`rounds`]).
const FIT_LOOPS_BESIDE_LIST: u32 = 36;

/// The counters from the compression's statistics words (see `STAT_*` in dsm_build.wgsl): the
/// largest ε as its bits, Σ ε in millionths (low, high word), the texels with smoke, the lossy
/// ones.
fn tolerance_counters(words: &[u32]) -> Vec<(&'static str, u64)> {
    let [max_bits, sum_lo, sum_hi, texels, lossy] = words[..] else {
        return Vec::new();
    };
    let max_e6 = (f64::from(f32::from_bits(max_bits)) * 1e6).round() as u64;
    let sum_e6 = (u64::from(sum_hi) << 32) | u64::from(sum_lo);
    vec![
        ("max_tolerance_e6", max_e6),
        (
            "mean_tolerance_e6",
            sum_e6.checked_div(u64::from(texels)).unwrap_or(0),
        ),
        ("fitted_texels", u64::from(texels)),
        ("lossy_texels", u64::from(lossy)),
    ]
}

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: SPEC.name,
    description: "deep shadow map: each texel's exact optical depth refitted to B/2 nodes within \
                  the smallest tolerance (Lokovic & Veach)",
    role: Role::Contender,
    budget_caption: |b| format!("{} nodes per texel", nodes_per_texel(b)),
    min_channels: 4,
    max_channels: super::MAX_CHANNELS,
    // Not in the default sweep: on lavapipe the 10 cells of dsm and avsm on thesis_plume take
    // about 17 s together (`sweep --techniques dsm,avsm`: 17.8 s with `none` and the reference;
    // 36.8 s two changes before, 240 s for 8 cells before their resolve and search got faster:
    // docs/studies.md), a quarter of `sweep --techniques all`.
    in_default_sweep: false,
    in_default_compare: true,
    build_reads_back: true,
    params: &[],
    order_independent: true,
    converges_with_budget: true,
    converges_from: 1,
    compresses_captured_lists: true,
    memory: |c| SPEC.memory(c),
    lookup_shader: "shadow/dsm.wgsl",
    lookup_constants: super::no_lookup_constants,
    extra_shaders: || SPEC.build_shaders(),
    create: |ctx, params| Ok(Box::new(DeepNodes::new(ctx, &SPEC, params)?)),
    uses_splat: false,
    uses_budget: true,
    owns_particle_pass: false,
    volume: super::VolumeSupport::Shadows,
    shadows_particles: true,
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tolerance_counters_read_the_statistics_words() {
        let words = [0.25f32.to_bits(), u32::MAX, 1, 4, 3];
        let counters = tolerance_counters(&words);
        // Σ = 2^32 + 2^32 - 1 millionths over 4 texels.
        assert_eq!(
            counters,
            vec![
                ("max_tolerance_e6", 250_000),
                ("mean_tolerance_e6", ((1u64 << 33) - 1) / 4),
                ("fitted_texels", 4),
                ("lossy_texels", 3),
            ]
        );
        assert_eq!(tolerance_counters(&[0; 5])[1], ("mean_tolerance_e6", 0));
    }

    /// The rounds give every texel its search and its final fit, with no SIMD group running more
    /// than `per_round` fits in one round: the shader's schedule (dsm_build.wgsl, `compress`)
    /// replayed for a group of texels needing 0 to `SEARCH_STEPS` - 1 search fits.
    #[test]
    fn rounds_hold_every_search_and_final_fit_within_the_loop_budget() {
        let budget = 60_000;
        for max_list in [10, 500, 2_000, 5_325, 9_000, 14_990, 15_000, 28_234] {
            let per_round = fits_per_round(max_list, budget);
            let rounds = rounds(max_list, budget);
            // (search fits still needed, finished) per lane.
            let mut lanes: Vec<(u32, bool)> = (0..SEARCH_STEPS).map(|s| (s, false)).collect();
            for round in 0..rounds {
                let (search_fits, may_finish) = match per_round {
                    1 => (1 - round % 2, round % 2 == 1),
                    _ => (per_round - 1, true),
                };
                let mut group_searched = 0;
                let mut group_finished = false;
                for lane in lanes.iter_mut().filter(|l| !l.1) {
                    let fits = lane.0.min(search_fits);
                    lane.0 -= fits;
                    group_searched = group_searched.max(fits);
                    if lane.0 == 0 && may_finish {
                        lane.1 = true;
                        group_finished = true;
                    }
                }
                let group_fits = group_searched + u32::from(group_finished);
                assert!(
                    group_fits <= per_round,
                    "max_list {max_list}, round {round}"
                );
            }
            assert!(
                lanes.iter().all(|l| l.1),
                "max_list {max_list}: {rounds} rounds leave {lanes:?}"
            );
        }
    }
}
