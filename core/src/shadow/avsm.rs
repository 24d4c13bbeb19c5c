//! `avsm`: adaptive volumetric shadow maps (Salvi, Vidimče, Lauritzen & Lefohn, EGSR 2010).
//!
//! Every texel keeps N = floor(B / 2) nodes (depth, T) of its transmittance curve. Each
//! particle's fragment (its chord through the texel's ray) inserts an entry and an exit node with
//! T linear between them (nodes behind the entry are multiplied by its ramp, 1 at entry to
//! e^−optical_depth at the exit and beyond); while the curve holds more than N nodes, the
//! interior node whose removal loses the least area under it goes (the first and last nodes
//! stay).
//!
//! **Insertion order** (`avsm_insert`). The paper streams: fragments are inserted as they are
//! rasterised, serialised per pixel in primitive order by a fragment shader interlock, so the
//! curve depends on the order the particles are drawn in (here the eye's back-to-front order,
//! which the renderer sorts before the light pass). That is the default, `draw`, and what an
//! engine ships. `sorted` inserts each texel's fragments front to back by depth instead, so the
//! result does not depend on the draw order; it reads like the ideal case but measures no
//! better: draw order is as close to `exact` or closer on every scene tried (docs/studies.md,
//! "Streaming avsm"), since inserted front to back every new node's T is read off the tail of an
//! already compressed curve. The registry holds `avsm` order dependent (`order_independent:
//! false`), as its default is.
//!
//! WebGPU has no interlock, so both are built as capture then resolve: the deep capture
//! (`deep_capture.rs`) stores every texel's segments with their particle's draw index, its
//! resolve sorts each list by draw index (or by depth), and one compute invocation per texel
//! (shaders/shadow/avsm_build.wgsl) inserts them in that order. The capture-and-resolve passes
//! emulate what hardware with fragment-shader interlock (Intel's PixelSync, Vulkan's
//! `VK_EXT_fragment_shader_interlock`) does in one pass as fragments arrive, so `avsm`'s timings
//! are those of the emulation, an upper bound on an engine's.
//!
//! The lookup (shaders/shadow/avsm.wgsl) is linear in T between the bracketing nodes, 1 in front
//! of the first, the last node's T behind the last, blended bilinearly over four texels. Linear T
//! inside a segment is the representation's own error: for one thick particle (optical depth 3)
//! it is off by up to 0.3 against exp(−Ω), whatever the budget. That, not the insertion order,
//! is why its error stops falling with nodes where chords overlap (measured on 8 overlapping
//! spheres: 0.051 RMS T from 8 to 32 channels in draw order, 0.063 sorted).
//!
//! **Chord** (`avsm_chord`). `linear` is the paper's. `pieces` is the convergent variant: each
//! chord enters as ceil(N/4) linear pieces whose ends hold the curve's T times the chord's own
//! exponential T, and the nodes behind its entry are ramped exponentially; the least-area
//! removal then spends the nodes where the curve bends. At 8 channels and below (one piece) it
//! is the paper's curve; on the thesis scene at 24 channels RMS T 0.0127 -> 0.0026, at 32
//! 0.0113 -> 0.0013, for a longer compression (frame 4.8x -> 8.6x `none`'s at 32 on lavapipe).
//! `tune` keeps `linear`: at its byte budgets the capture's lists leave `avsm` too few nodes for
//! a second piece. The CPU mirror is `deep_compress.rs`.
//!
//! Memory: the nodes (texels × N × 8 bytes) and a 16-byte uniform; the capture's lists are
//! transient (allocated, counted, and reported apart).

use super::deep_capture::Resolve;
use super::deep_nodes::{DeepNodes, DeepNodesSpec, nodes_per_texel};
use super::{ParamSpec, Role, TechniqueEntry, TechniqueParams};

/// `avsm_insert`'s choices, by index.
pub const INSERT_CHOICES: &[&str] = &["draw", "sorted"];

/// `avsm_insert`: the order each texel's fragments are inserted in.
pub const INSERT: ParamSpec = ParamSpec {
    key: "avsm_insert",
    unit: "-",
    doc: "the order each texel's fragments are inserted in: draw (the paper's streaming \
          insertion, in the order the particles are drawn: the eye's back-to-front order; T \
          depends on that order), or sorted (front to back by depth: independent of the draw \
          order, what engines cannot do in one pass, and no more accurate on any scene \
          measured)",
    min: 0.0,
    max: (INSERT_CHOICES.len() - 1) as f32,
    default: Some(0.0),
    choices: INSERT_CHOICES,
    integer: false,
    tuned: false,
};

/// `avsm_chord`'s choices, by index.
pub const CHORD_CHOICES: &[&str] = &["linear", "pieces"];

/// `avsm_chord`: how a segment's chord enters the curve.
pub const CHORD: ParamSpec = ParamSpec {
    key: "avsm_chord",
    unit: "-",
    doc: "how each particle's chord enters the curve: linear (the paper: an entry and an exit \
          node, T linear between them and the nodes behind the entry ramped linearly; for a \
          thick particle T is off exp(-optical depth) by up to 0.3 inside the chord whatever \
          the budget), or pieces: the chord as ceil(N/4) linear pieces whose ends hold its \
          exponential T (the nodes behind the entry ramped exponentially), so that more nodes \
          follow the curve more closely",
    min: 0.0,
    max: (CHORD_CHOICES.len() - 1) as f32,
    // linear, the paper's: `smokeshadow tune` leaves it (docs/tuned_params.toml).
    default: Some(0.0),
    choices: CHORD_CHOICES,
    integer: false,
    tuned: true,
};

/// The linear pieces each chord enters the curve as, with N nodes per texel under `params`:
/// 1 for the paper's linear chord; ceil(N / 4) for `avsm_chord = pieces` (2 at 16 channels,
/// 4 at 32), so that a budget's nodes stay about four chords' worth of pieces.
pub fn chord_pieces(nodes_per_texel: u32, params: &TechniqueParams) -> u32 {
    match params.choice_index(&CHORD) {
        0 => 1,
        _ => nodes_per_texel.div_ceil(4).max(1),
    }
}

/// The capture's resolve `avsm_insert` asks for.
fn resolve(params: &TechniqueParams) -> Resolve {
    match params.choice_index(&INSERT) {
        0 => Resolve::SegmentsByDraw,
        _ => Resolve::SegmentsByDepth,
    }
}

pub const SPEC: DeepNodesSpec = DeepNodesSpec {
    name: "avsm",
    build_shader: "shadow/avsm_build.wgsl",
    bisection_steps: 0,
    stats_words: 0,
    stats_counters: |_| Vec::new(),
    rounds: |max_list, loop_budget, params| {
        let pieces = chord_pieces(nodes_per_texel(params.channels), params);
        rounds(max_list, loop_budget, pieces)
    },
    resolve,
    // The curve's slots: N, and the P + 1 nodes a segment of P pieces inserts before its
    // removals; P itself.
    compress_constants: |n, params| {
        let pieces = chord_pieces(n, params);
        vec![("CURVE_NODES", n + pieces + 1), ("CHORD_PIECES", pieces)]
    },
    shader_variants: |channels| {
        (0..CHORD_CHOICES.len())
            .map(|choice| {
                let mut params = TechniqueParams::new(channels, 512);
                super::set_param(&mut params, CHORD.key, &(choice as f32).into())
                    .expect("a choice of avsm_chord");
                params
            })
            .collect()
    },
};

/// Loop iterations one segment of `pieces` pieces takes, with a margin
/// (`iterations_per_segment` in shaders/shadow/avsm_build.wgsl: the curve's steps are unrolled):
/// the loop over the segments, P - 1 interior nodes, P + 1 removals and the removals' exit,
/// doubled: 8 for the paper's linear chord.
fn iterations_per_segment(pieces: u32) -> u32 {
    2 * (2 * pieces + 2)
}

/// Rounds of the compression: `loop_budget / iterations_per_segment` segments each.
fn rounds(max_list: u32, loop_budget: u32, pieces: u32) -> u32 {
    let per_round = (loop_budget / iterations_per_segment(pieces)).max(1);
    max_list.div_ceil(per_round).max(1)
}

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: SPEC.name,
    description: "adaptive volumetric shadow map: B/2 nodes of T per texel, fragments \
                  inserted in draw order (or sorted), least-area node removed (Salvi et al.)",
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
    params: &[INSERT, CHORD],
    order_independent: false,
    converges_with_budget: true,
    converges_from: 1,
    compresses_captured_lists: true,
    memory: |c| SPEC.memory(c),
    lookup_shader: "shadow/avsm.wgsl",
    lookup_constants: super::no_lookup_constants,
    extra_shaders: || SPEC.build_shaders(),
    create: |ctx, params| Ok(Box::new(DeepNodes::new(ctx, &SPEC, params)?)),
    uses_splat: false,
    uses_budget: true,
    owns_particle_pass: false,
    volume: super::VolumeSupport::Shadows,
    shadows_particles: true,
};
