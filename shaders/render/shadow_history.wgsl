// The shadow's temporal history (`[shadow] history`, `smokeshadow sweep --shadow-history W`):
// each particle's T at its four lighting points blended with what the same particle's points
// had the frame before, T' = (1 - w) T + w T'_prev, as engines filter a flickering shadow.
// Kept per particle (by its index in the scene's particles, which the CPU maps each sorted
// instance to), so the camera may move; a particle the CPU marks fresh (the first frame, another
// count, a rebirth) takes its T as it is. With w = 0 nothing is read or written.
// Keep `HistoryParams` in sync with src/render/history.rs.

struct HistoryParams {
    // The history's weight w in [0, 1): 0 is off.
    weight: f32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
};

// What the history held after the last frame, per particle and lighting point.
@group(3) @binding(0) var<storage, read_write> history_t: array<vec4<f32>>;
// Per sorted instance: the particle it is (low 31 bits), and bit 31 set when it has no history.
@group(3) @binding(1) var<storage, read> history_ids: array<u32>;
@group(3) @binding(2) var<uniform> history: HistoryParams;

const HISTORY_FRESH: u32 = 0x80000000u;

// T at lighting point `k` of instance `index` as the frame uses it: `t` filtered by the history.
fn filtered_t(index: u32, k: u32, t: f32) -> f32 {
    if history.weight <= 0.0 {
        return t;
    }
    let tagged = history_ids[index];
    let id = tagged & ~HISTORY_FRESH;
    var out = t;
    if (tagged & HISTORY_FRESH) == 0u {
        out = mix(t, history_t[id][k], history.weight);
    }
    history_t[id][k] = out;
    return out;
}
