//! `avsm`: adaptive volumetric shadow maps (Salvi, Vidimče, Lauritzen & Lefohn, EGSR 2010).
//!
//! Every texel keeps N = floor(B / 2) nodes (depth, T) of its transmittance curve. The paper
//! inserts fragments as they are rasterised, serialised per pixel by a fragment shader
//! interlock; WebGPU has none, so this builds it as capture then resolve: the deep capture
//! (`deep_capture.rs`) stores every texel's segments, and one compute invocation per texel
//! (shaders/shadow/avsm_build.wgsl) inserts them **in their sorted order** (z0, z1, optical
//! depth), so the result does not depend on the draw order, where the paper's does. Each
//! segment adds an entry and an exit node with T linear between them (nodes behind the entry
//! are multiplied by its ramp, 1 at entry to e^−optical_depth at the exit and beyond); while the
//! curve holds more than N nodes, the interior node whose removal loses the least area under it
//! goes (the first and last nodes stay).
//!
//! The lookup (shaders/shadow/avsm.wgsl) is linear in T between the bracketing nodes, 1 in front
//! of the first, the last node's T behind the last, blended bilinearly over four texels. Linear T
//! inside a segment is the representation's own error: for one thick particle (optical depth 3)
//! it is off by up to 0.3 against exp(−Ω), whatever the budget. The CPU mirror is
//! `deep_compress.rs`.
//!
//! Memory: the nodes (texels × N × 8 bytes) and a 16-byte uniform; the capture's lists are
//! transient (allocated, counted, and reported apart).

use super::deep_nodes::{DeepNodes, DeepNodesSpec, nodes_per_texel};
use super::{Role, TechniqueEntry};

pub const SPEC: DeepNodesSpec = DeepNodesSpec {
    name: "avsm",
    build_shader: "shadow/avsm_build.wgsl",
    bisection_steps: 0,
    stats_words: 0,
    stats_counters: |_| Vec::new(),
    rounds,
};

/// Loop iterations one segment's insertion and removals take at most (`ITERATIONS_PER_SEGMENT`
/// in shaders/shadow/avsm_build.wgsl).
const ITERATIONS_PER_SEGMENT: u32 = 200;

/// Rounds of the compression: `loop_budget / 200` segments each.
fn rounds(max_list: u32, loop_budget: u32) -> u32 {
    let per_round = (loop_budget / ITERATIONS_PER_SEGMENT).max(1);
    max_list.div_ceil(per_round).max(1)
}

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: SPEC.name,
    description: "adaptive volumetric shadow map: B/2 nodes of T per texel, sorted segments \
                  inserted, least-area node removed (Salvi et al.)",
    role: Role::Contender,
    budget_caption: |b| format!("{} nodes per texel", nodes_per_texel(b)),
    min_channels: 4,
    // Not in the default sweep: on lavapipe the 8 cells of dsm and avsm take 240 s together,
    // against 63 s for the whole default sweep without them (the capture alone costs what
    // `exact` does). The default comparison grows from 82 s to about 112 s with both.
    in_default_sweep: false,
    in_default_compare: true,
    build_reads_back: true,
    params: &[],
    order_independent: true,
    converges_with_budget: true,
    compresses_captured_lists: true,
    memory: |c| SPEC.memory(c),
    lookup_shader: "shadow/avsm.wgsl",
    extra_shaders: || SPEC.build_shaders(),
    create: |ctx, params| Ok(Box::new(DeepNodes::new(ctx, &SPEC, params)?)),
    uses_splat: false,
    uses_budget: true,
    owns_particle_pass: false,
};
