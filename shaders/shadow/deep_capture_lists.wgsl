// The per-texel segment lists of a deep capture (src/shadow/deep_capture.rs), as its own passes
// and the compression passes that read them declare them in group 1. Texel i's segments are
// segment_at(offsets[i] .. offsets[i + 1]). After the resolve, for `dsm`, its nodes (z, Ω(z)) of
// the piecewise-linear optical depth are nodes 2·offsets[i] .. 2·offsets[i + 1] of
// `resolved_nodes`; for `avsm` the segments are sorted by (z0, z1, optical depth), or by draw
// index alone for its default insertion in draw order (the resolve's `SORT_BY_DRAW`). The lists
// hold one band of rows at a time (rows [row_begin, row_end), whose first segment is offsets'
// band_base), so every index into them is relative to band_base, and the per-texel passes cover
// the band's rows only. Every storage binding is read_write because the capture's bind group
// layouts are the same but for the resolved nodes' access.
// Keep `CaptureParams` in sync with src/shadow/deep_capture.rs.

#import common/rows.wgsl

struct CaptureParams {
    // Shadow-map resolution (texels per side).
    resolution: u32,
    // Segments the list buffers can hold.
    capacity: u32,
    // The band of rows the lists hold now, and the offset of its first segment.
    row_begin: u32,
    row_end: u32,
    band_base: u32,
    // The longest texel list this frame, and the loop iterations one invocation group may run
    // in one dispatch (llvmpipe's limit, with a margin; effectively unbounded elsewhere): the
    // per-texel passes split their work into rounds that stay within it.
    max_list: u32,
    loop_budget: u32,
    _pad0: u32,
};

// Which round of a per-texel pass this dispatch is (group 3, bound at a dynamic offset).
struct Round {
    index: u32,
};

struct Segment {
    // Radial distances from the light where the chord enters and leaves the sphere (m).
    z0: f32,
    z1: f32,
    // Optical depth of the whole chord: τ(1 - d/r)·2w.
    optical_depth: f32,
    // The particle's draw index (its instance): the order its fragment reaches the texel in an
    // engine's one-pass insertion. A particle has at most one fragment per texel, so it is a
    // total key of a texel's list.
    draw_index: u32,
};

@group(1) @binding(0) var<uniform> capture: CaptureParams;
@group(1) @binding(2) var<storage, read_write> offsets: array<u32>;
// The segments, one vec4 of words each (z0, z1, optical depth as their bits, the draw index):
// llvmpipe stores (and loads) a vec4 per lane in one go, where it moves a struct's four members
// one by one (the fill 26 -> 22 ms on the thesis frame). `segment_at` and `set_segment` move them.
@group(1) @binding(3) var<storage, read_write> segments: array<vec4<u32>>;

fn segment_at(i: u32) -> Segment {
    let words = segments[i];
    return Segment(bitcast<f32>(words.x), bitcast<f32>(words.y), bitcast<f32>(words.z), words.w);
}

fn set_segment(i: u32, s: Segment) {
    let depths = bitcast<vec2<u32>>(vec2<f32>(s.z0, s.z1));
    segments[i] = vec4<u32>(depths, bitcast<u32>(s.optical_depth), s.draw_index);
}
@group(1) @binding(4) var<storage, read_write> nodes: array<vec2<f32>>;
// A resolve into nodes (`dsm`'s) sorts its keys in two read-write storage textures of one
// R32Float each, row textures (shaders/common/rows.wgsl) in the nodes' index space
// (src/shadow/deep_capture.rs, SORT_KEY_FORMAT, says why textures; 1x1 placeholders for the
// others), depths in one and values in the other: the sort keys, a texel's events, its
// segments' starts (z0, slope) and ends (z1, -slope) as the resolve sorts them, at [2·first,
// 2·first + 2n), on either of two sides, `second_side()` apart, between which the merge passes
// alternate (which side a texel's pass reads is then an offset, never a branch). Its last pass
// writes the nodes (z, Ω(z)) at the same indices into `resolved_nodes`, an Rgba32Float row
// texture of two nodes a texel (nodes 2j and 2j + 1 in texel j; binding 9): the resolve's passes
// (shaders/shadow/deep_capture.wgsl) declare it write-only, the owner's pass
// (shaders/shadow/dsm_build.wgsl) read-only, where one load fetches two nodes
// (src/shadow/deep_capture.rs, NODE_FORMAT, has the measurements).
@group(1) @binding(6) var key_depths: texture_storage_2d<r32float, read_write>;
@group(1) @binding(7) var key_values: texture_storage_2d<r32float, read_write>;
// Per 8x8 tile of the band, 64 entries: its texels (map indices), longest list first, NO_TEXEL
// for a place outside the band (`order_texels` writes it, `band_texel` reads it).
@group(1) @binding(8) var<storage, read_write> texel_order: array<u32>;
@group(3) @binding(0) var<uniform> pass_round: Round;

// Where the second side of the key textures starts: after the band's 2·capacity sort keys.
fn second_side() -> u32 {
    return 2u * capture.capacity;
}

// The key at index `i` of the key textures.
fn key_at(i: u32) -> vec2<f32> {
    let texel = row_texel(i);
    return vec2<f32>(textureLoad(key_depths, texel).x, textureLoad(key_values, texel).x);
}

fn set_key_at(i: u32, key: vec2<f32>) {
    let texel = row_texel(i);
    textureStore(key_depths, texel, vec4<f32>(key.x));
    textureStore(key_values, texel, vec4<f32>(key.y));
}

// One texel's list: segments [first, first + count), nodes [2·first, 2·first + 2·count).
struct TexelList {
    first: u32,
    count: u32,
};

// Texel `index`'s list (a texel of the current band); empty when the lists did not hold it
// (never, once the capture has grown them to the band's count).
fn texel_list(index: u32) -> TexelList {
    var out: TexelList;
    out.first = offsets[index] - capture.band_base;
    out.count = offsets[index + 1u] - offsets[index];
    if out.first + out.count > capture.capacity {
        out.count = 0u;
    }
    return out;
}

const NO_TEXEL: u32 = 0xffffffffu;

// The texel a per-texel pass's invocation `id` handles, as an index into the map, or NO_TEXEL.
// The passes run 8x8 workgroups over the band's 8x8 tiles, and each takes its tile's texels in
// the order `order_texels` (shaders/shadow/deep_capture.wgsl) wrote for it: longest list first.
// llvmpipe runs each 8 invocations in a row as one SIMD group, looping in lockstep as long as the
// longest of their lists, so a group of lists of about one length wastes the least. Summed over
// the groups of the thesis frame, the longest lists came to 14.9% more than the lists themselves
// with the tiles' rows and 8.6% with 4x2 blocks of them; in this order the run sort, merges and
// search take about 13 ms less than with the blocks, for 3.6 ms of ordering (docs/studies.md,
// "Loop counts per SIMD group"). Ordering a band's texels across its tiles lost more to the
// lanes' scattered lists than it saved.
fn band_texel(id: vec3<u32>) -> u32 {
    let local = id.xy & vec2<u32>(7u);
    return tile_texel(id.xy >> vec2<u32>(3u), (local.y << 3u) + local.x);
}

// The texel at `place` (0..64) of the band's 8x8 tile `tile` in `order_texels`' order.
fn tile_texel(tile: vec2<u32>, place: u32) -> u32 {
    return texel_order[((tile.y * tiles_per_row() + tile.x) << 6u) + place];
}

// The 8x8 tiles across the map (a band's per-texel passes dispatch this many workgroups in x).
fn tiles_per_row() -> u32 {
    return (capture.resolution + 7u) / 8u;
}
