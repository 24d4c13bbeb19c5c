// Parameters of a compressed deep shadow map (`dsm`, `avsm`; src/shadow/deep_nodes.rs): every
// texel keeps `nodes_per_texel` nodes (depth in metres, value), texel i's at
// [i·nodes_per_texel, (i + 1)·nodes_per_texel), sorted by depth; a texel with fewer nodes repeats
// its last one. Keep `DeepParams` in sync with src/shadow/deep_nodes.rs.

struct DeepParams {
    // Shadow-map resolution (texels per side).
    resolution: u32,
    // N = floor(B / 2) nodes per texel.
    nodes_per_texel: u32,
    // Bisection steps of the error tolerance (`dsm`; 0 for techniques without one).
    bisection_steps: u32,
    _pad0: u32,
};
