// Deep capture (src/shadow/deep_capture.rs): every light-space particle fragment's chord
// segment stored per texel and merged into the texel's piecewise-linear optical depth, the
// uncompressed deep shadow map of Lokovic & Veach (2000) that `dsm` and `avsm` compress.
// 1. fs_count: every light-space particle fragment (one light ray through one particle) counts
//    itself in its texel (atomic add); or fs_count_blended, by adding 1 to its texel of a float
//    target, which counts_from_blend turns into the counts.
// 2. scan_rows, scan_total, scan_write (shaders/shadow/grid_scan.wgsl, shared with `exact`):
//    exclusive prefix sum of the counts -> list offsets (offsets[res²] = total).
// 3. fs_fill: every fragment of the current band of rows writes its segment (z0, z1, optical
//    depth, draw index) into its texel's list (counts, cleared, serve as cursors).
// 4. resolve (order_texels, which orders each tile's texels by list length for the passes
//    after it, then run_sort, merge_runs): per texel of the band, `dsm`'s sorts its segments'
//    events, their starts (z0, slope) and ends (z1, -slope), by depth and turns them into the
//    nodes (z, Ω(z)) of the piecewise-linear optical depth as its last pass writes them: between
//    events Ω grows by the sum of the slopes (optical depth per metre) of the segments open
//    there. The keys are total over what is sorted, so the nodes do not depend on the order the
//    fragments arrived in. An owner that needs the segments themselves has them sorted whole
//    (an insertion sort that gives up early, then a heapsort of the lists it left): by (z0, z1,
//    optical depth, draw index), or with SORT_BY_DRAW by draw index, which puts each texel's
//    list back in the order the particles were drawn, whatever order the fill's atomics wrote
//    it in.
#import shadow/layered_build.wgsl
#import shadow/deep_capture_lists.wgsl
#import shadow/grid_scan.wgsl

// The nodes of a resolve into nodes, written by its last pass, two a texel (see
// shaders/shadow/deep_capture_lists.wgsl).
@group(1) @binding(9) var resolved_nodes: texture_storage_2d<rgba32float, write>;

// Stores nodes i and i + 1 (i even: a texel's two).
fn set_node_pair(i: u32, first: vec2<f32>, second: vec2<f32>) {
    textureStore(resolved_nodes, row_texel(i >> 1u), vec4<f32>(first, second));
}

@group(1) @binding(1) var<storage, read_write> counts: array<atomic<u32>>;
@group(1) @binding(5) var<storage, read_write> row_sums: array<u32>;
// Shortest chord kept, metres: shorter ones (grazing rays) are widened to this so that every
// segment has a finite slope; their optical depth τ(1 - d/r)·2w is vanishingly small anyway.
const MIN_WIDTH_M: f32 = 1e-4;

// The fragment's segment, or optical depth < 0 when its ray misses the sphere.
fn fragment_segment(in: BuildVertexOut) -> Segment {
    var out: Segment;
    let origin = frame.light_pos.xyz;
    let dir = normalize(in.world - origin);
    let chord = sphere_chord(origin, dir, in.center_radius.xyz, in.center_radius.w);
    if chord.d >= in.center_radius.w {
        out.optical_depth = -1.0;
        return out;
    }
    let w = max(chord.half_width, 0.5 * MIN_WIDTH_M);
    out.z0 = chord.t_mid - w;
    out.z1 = chord.t_mid + w;
    out.optical_depth = chord_extinction(in.density, chord.d, in.center_radius.w) * 2.0 * chord.half_width;
    out.draw_index = in.draw_index;
    return out;
}

fn texel_index(clip: vec4<f32>) -> u32 {
    let texel = vec2<u32>(clip.xy);
    return texel.y * capture.resolution + texel.x;
}

// The colour output adds nothing to its target (a dummy here): the counts are the result.
@fragment
fn fs_count(in: BuildVertexOut) -> @location(0) vec4<f32> {
    if fragment_segment(in).optical_depth < 0.0 {
        discard;
    }
    atomicAdd(&counts[texel_index(in.clip)], 1u);
    return vec4<f32>(0.0);
}

// fs_count where the count pass counts by blending (src/shadow/deep_capture.rs,
// `counts_by_blending`): the fragment adds 1 to its texel of the R32Float target, which
// `counts_from_blend` then turns into the counts.
@fragment
fn fs_count_blended(in: BuildVertexOut) -> @location(0) vec4<f32> {
    if fragment_segment(in).optical_depth < 0.0 {
        discard;
    }
    return vec4<f32>(1.0);
}

// The counts from the count target's floats, copied into `counts` as their bits (whole numbers,
// exact in floats far beyond the longest list a capture accepts).
@compute @workgroup_size(8, 8)
fn counts_from_blend(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= capture.resolution || id.y >= capture.resolution {
        return;
    }
    let texel = id.y * capture.resolution + id.x;
    atomicStore(&counts[texel], u32(bitcast<f32>(atomicLoad(&counts[texel]))));
}

// The band texel of a fill fragment and its slot in the lists, or NO_TEXEL (the fragment is
// then discarded) for a fragment that misses its sphere or lies outside the band.
struct FillSlot {
    index: u32,
    slot: u32,
};

fn fill_slot(in: BuildVertexOut, segment: Segment) -> FillSlot {
    var out = FillSlot(NO_TEXEL, 0u);
    // The pass's scissor keeps to the band's rows; this makes sure of it.
    let row = u32(in.clip.y);
    if segment.optical_depth < 0.0 || row < capture.row_begin || row >= capture.row_end {
        return out;
    }
    out.index = texel_index(in.clip);
    out.slot = offsets[out.index] - capture.band_base + atomicAdd(&counts[out.index], 1u);
    return out;
}

@fragment
fn fs_fill(in: BuildVertexOut) -> @location(0) vec4<f32> {
    let segment = fragment_segment(in);
    let at = fill_slot(in, segment);
    if at.index == NO_TEXEL {
        discard;
    }
    if at.slot < capture.capacity {
        set_segment(at.slot, segment);
    }
    return vec4<f32>(0.0);
}

// The density volume's segments (shaders/shadow/volume_splat.wgsl): each step of the texel's
// light ray that has density is one segment [t - dt/2, t + dt/2] (metres) of its optical depth,
// drawn after every particle (its draw index counts on from VOLUME_DRAW_BASE).
const VOLUME_DRAW_BASE: u32 = 0x80000000u;

fn volume_segment(ray: VolumeRay, i: u32) -> Segment {
    var out: Segment;
    let s = volume_splat(ray, i, true);
    let t = ray.t0 + (f32(i) + 0.5) * ray.dt;
    let w = max(0.5 * ray.dt, 0.5 * MIN_WIDTH_M);
    out.z0 = t - w;
    out.z1 = t + w;
    out.optical_depth = select(-1.0, s.optical_depth, s.optical_depth > 0.0);
    out.draw_index = VOLUME_DRAW_BASE + i;
    return out;
}

// The segments of a volume fragment's light ray (the steps with density).
fn volume_segments(in: VolumeVertexOut) -> u32 {
    let ray = volume_light_ray(in.ndc);
    var n = 0u;
    for (var i = 0u; i < ray.steps; i++) {
        n += u32(volume_segment(ray, i).optical_depth >= 0.0);
    }
    return n;
}

@fragment
fn fs_count_volume(in: VolumeVertexOut) -> @location(0) vec4<f32> {
    let n = volume_segments(in);
    if n == 0u {
        discard;
    }
    atomicAdd(&counts[texel_index(in.clip)], n);
    return vec4<f32>(0.0);
}

// The band texel of a volume fragment, or NO_TEXEL outside the band.
fn volume_texel(clip: vec4<f32>) -> u32 {
    let row = u32(clip.y);
    if row < capture.row_begin || row >= capture.row_end {
        return NO_TEXEL;
    }
    return texel_index(clip);
}

// fs_count_volume where the count pass counts by blending: the fragment adds its segments.
@fragment
fn fs_count_volume_blended(in: VolumeVertexOut) -> @location(0) vec4<f32> {
    let n = volume_segments(in);
    if n == 0u {
        discard;
    }
    return vec4<f32>(f32(n));
}

@fragment
fn fs_fill_volume(in: VolumeVertexOut) -> @location(0) vec4<f32> {
    let index = volume_texel(in.clip);
    let ray = volume_light_ray(in.ndc);
    if index == NO_TEXEL || ray.steps == 0u {
        discard;
    }
    for (var i = 0u; i < ray.steps; i++) {
        let segment = volume_segment(ray, i);
        if segment.optical_depth < 0.0 {
            continue;
        }
        let slot = offsets[index] - capture.band_base + atomicAdd(&counts[index], 1u);
        if slot < capture.capacity {
            set_segment(slot, segment);
        }
    }
    return vec4<f32>(0.0);
}

// Before a band's per-texel passes: each 8x8 tile's texels by the length of their lists, longest
// first (ties in the tile's order), into `texel_order` (see `band_texel`). Any order gives the
// same lists, nodes and images: it only decides which texels a SIMD group takes together.
var<workgroup> tile_keys: array<u32, 64>;
var<workgroup> tile_longest: atomic<u32>;

@compute @workgroup_size(8, 8)
fn order_texels(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(local_invocation_index) place: u32,
    @builtin(workgroup_id) tile: vec3<u32>,
) {
    let row = capture.row_begin + id.y;
    let inside = id.x < capture.resolution && row < capture.row_end;
    let texel = row * capture.resolution + id.x;
    // A list's length + 1; 0 for a place outside the band, which goes last.
    var key = 0u;
    if inside {
        key = offsets[texel + 1u] - offsets[texel] + 1u;
    }
    tile_keys[place] = key;
    atomicMax(&tile_longest, key);
    workgroupBarrier();
    // A tile without smoke keeps its order (most of the map: no loop at all there).
    var rank = place;
    if workgroupUniformLoad(&tile_longest) > 1u {
        rank = 0u;
        for (var j = 0u; j < 64u; j++) {
            let other = tile_keys[j];
            rank += u32(other > key || (other == key && j < place));
        }
    }
    texel_order[((tile.y * tiles_per_row() + tile.x) << 6u) + rank] = select(NO_TEXEL, texel, inside);
}

// The scan's grid is the map (shaders/shadow/grid_scan.wgsl).
fn scan_side() -> u32 {
    return capture.resolution;
}

fn segment_slope(s: Segment) -> f32 {
    return s.optical_depth / (s.z1 - s.z0);
}

// Whether the segments are sorted by draw index alone rather than by depth.
override SORT_BY_DRAW: bool = false;

// An element of the whole-segment sorts (the insertion sort and the heapsort): a segment's
// (z0, z1, optical depth) and its draw index. (The index stays a u32: its bits as a float would
// be a denormal, which a GPU may flush.) `dsm`'s events have their own merge sort,
// below.
struct HeapItem {
    key: vec3<f32>,
    draw_index: u32,
};

fn key_before(a: HeapItem, b: HeapItem) -> bool {
    if SORT_BY_DRAW {
        return a.draw_index < b.draw_index;
    }
    // Lexicographic (z0, z1, optical depth), then the draw index: a total order, so the sorted
    // lists do not depend on the order the fragments arrived in.
    if a.key.x != b.key.x {
        return a.key.x < b.key.x;
    }
    if a.key.y != b.key.y {
        return a.key.y < b.key.y;
    }
    if a.key.z != b.key.z {
        return a.key.z < b.key.z;
    }
    return a.draw_index < b.draw_index;
}

fn heap_key(i: u32) -> HeapItem {
    let s = segment_at(i);
    return HeapItem(vec3<f32>(s.z0, s.z1, s.optical_depth), s.draw_index);
}

fn set_heap_key(i: u32, item: HeapItem) {
    set_segment(i, Segment(item.key.x, item.key.y, item.key.z, item.draw_index));
}

// Sifts element `root_in` down the max-heap [base, base + n). Each level reads its two children
// once and writes one element (storage reads are most of a sort's cost on llvmpipe).
fn sift(base: u32, root_in: u32, n: u32) {
    var root = root_in;
    let value = heap_key(base + root);
    loop {
        var child = 2u * root + 1u;
        if child >= n {
            break;
        }
        var key = heap_key(base + child);
        if child + 1u < n {
            let right = heap_key(base + child + 1u);
            if key_before(key, right) {
                child += 1u;
                key = right;
            }
        }
        if !key_before(value, key) {
            break;
        }
        set_heap_key(base + root, key);
        root = child;
    }
    set_heap_key(base + root, value);
}

// The resolve, in phases (a dispatch each, or several: rounds), per texel of the band.
// `dsm`'s (Resolve::Nodes), whose fill wrote each segment's start (z0, slope) and end (z1,
// -slope) to the sort keys: merge sort these events (`run_sort`, `merge_runs`, below), the last
// pass turning them into the nodes. Only the events are sorted, two words each: two events with
// equal keys are equal, so the order is total over what is sorted. `avsm`'s: sort the whole segments (by depth or by draw index) with `insertion_sort`,
// then heapsort what it left. O(n log n) whatever the order the fragments arrived in. The
// heapsorts' sifts are split into rounds of `sifts_per_round()` each, so that no dispatch loops
// past `capture.loop_budget` (src/shadow/deep_capture.rs mirrors the arithmetic); a texel whose
// sort is done returns at once.

// Sifts per round of a heapsort: each sift takes at most log2(n) + 1 iterations.
fn sifts_per_round() -> u32 {
    let depth = firstLeadingBit(max(capture.max_list, 1u)) + 3u;
    return max(1u, capture.loop_budget / depth);
}

// This round's starts of a heap build over n elements: sift starts (hi, lo] in descending order
// (hi = lo when there is none left).
fn build_range(n: u32) -> vec2<u32> {
    let c = sifts_per_round();
    let done = pass_round.index * c;
    let h = n / 2u;
    if done >= h {
        return vec2<u32>(0u, 0u);
    }
    let hi = h - done;
    return vec2<u32>(hi, hi - min(c, hi));
}

// This round's ends of the extraction: ends (hi, lo] in descending order, lo >= 1.
fn extract_range(n: u32) -> vec2<u32> {
    let c = sifts_per_round();
    let done = pass_round.index * c;
    if n < 2u || done >= n - 1u {
        return vec2<u32>(1u, 1u);
    }
    let hi = n - done;
    return vec2<u32>(hi, max(1u, hi - min(c, hi)));
}

// The band texel's list for invocation `id`; empty outside the band.
fn band_list(id: vec3<u32>) -> TexelList {
    let index = band_texel(id);
    if index == NO_TEXEL {
        var none: TexelList;
        none.first = 0u;
        none.count = 0u;
        return none;
    }
    return texel_list(index);
}

// The list a heap pass sorts: the band texel's, unless `insertion_sort` has sorted it already.
fn heap_list(id: vec3<u32>) -> TexelList {
    var list = band_list(id);
    // (`dsm`'s lists are never marked: a cursor holds a list's length.)
    if list.count > 0u && atomicLoad(&counts[band_texel(id)]) == SORTED {
        list.count = 0u;
    }
    return list;
}

// The heap build: this round's starts, each sifted down.
@compute @workgroup_size(8, 8)
fn heap_build(@builtin(global_invocation_id) id: vec3<u32>) {
    let list = heap_list(id);
    let base = list.first;
    let r = build_range(list.count);
    for (var start = r.x; start > r.y; start--) {
        sift(base, start - 1u, list.count);
    }
}

// The extraction: this round's ends, each taking the heap's largest before the heap shrinks.
@compute @workgroup_size(8, 8)
fn heap_extract(@builtin(global_invocation_id) id: vec3<u32>) {
    let list = heap_list(id);
    let base = list.first;
    let r = extract_range(list.count);
    for (var end = r.x; end > r.y; end--) {
        let top = heap_key(base);
        set_heap_key(base, heap_key(base + end - 1u));
        set_heap_key(base + end - 1u, top);
        sift(base, 0u, end - 1u);
    }
}

// The first pass of a whole-segment resolve. The fill's atomics hand out a texel's slots in the
// order its fragments arrive, and where the rasteriser keeps the draw order per pixel (llvmpipe
// does: one thread shades a tile's primitives in order) that is the order the draw-order resolve
// wants: an insertion sort then reads each segment once (for that resolve only its draw index,
// `draw_ordered_prefix`, and the sort starts behind the prefix found in order). It gives up
// after n/16 - 1 moves (the list, still a permutation of itself, is left to the heapsort, as
// most lists of the by-depth resolve are); a list it sorts is marked SORTED in `counts` (the
// fill's cursors, unused from here on), and the heap passes skip it.
//
// The loop limit. llvmpipe counts loop iterations per SIMD group of invocations, all lanes
// together, so the sort is one flat loop in which each iteration of a lane either takes its next
// segment or moves one: the group loops as often as its busiest lane, at most (n - start) +
// 2·moves + 1 times (each insertion moves once at least, and takes one more iteration to set its
// segment down). The prefix before it loops at most n + 1 times, so a group loops at most 2n +
// 2·(n/16 - 1) + 2 <= 2n + ceil(2n / 16) times (n >= 16), the bound `longest_list` in
// src/shadow/deep_capture.rs holds every single pass to. (The nested loops this replaced, an
// insertion's moves inside the loop over the segments, ran each lane's moves at its own segment
// indices: a group looped up to every lane's moves together.)
const SORTED: u32 = 0xffffffffu;

// How many of a list's first segments are in draw order, read a word a segment (the draw
// index; the insertion sort reads all four): where the rasteriser keeps the draw order per
// pixel, the whole list, and then nothing else is read. Loops as many times as it returns (plus
// one).
fn draw_ordered_prefix(list: TexelList) -> u32 {
    var before = 0u;
    for (var i = 0u; i < list.count; i++) {
        let draw = segments[list.first + i].w;
        if i > 0u && draw < before {
            return i;
        }
        before = draw;
    }
    return list.count;
}

@compute @workgroup_size(8, 8)
fn insertion_sort(@builtin(global_invocation_id) id: vec3<u32>) {
    let index = band_texel(id);
    if index == NO_TEXEL {
        return;
    }
    let list = texel_list(index);
    // The sorted prefix the insertion starts behind.
    var start = 1u;
    if SORT_BY_DRAW {
        start = max(draw_ordered_prefix(list), 1u);
    }
    var sorted = true;
    var moves = max(list.count / 16u, 1u) - 1u;
    if list.count > start {
        // The largest of the sorted prefix: a segment not before it stays where it is.
        var last = heap_key(list.first + start - 1u);
        // The segment being taken or inserted (i), its hole (j) while it is inserted.
        var i = start;
        var j = start;
        var v = last;
        var inserting = false;
        while i < list.count {
            if !inserting {
                v = heap_key(list.first + i);
                if !key_before(v, last) {
                    last = v;
                    i++;
                    continue;
                }
                // Before `last`, the segment at i - 1: it moves once at least.
                inserting = true;
                j = i;
            }
            var set_down = j == 0u;
            if !set_down {
                let prev = heap_key(list.first + j - 1u);
                set_down = !key_before(v, prev);
                if !set_down {
                    if moves == 0u {
                        sorted = false;
                        set_heap_key(list.first + j, v);
                        break;
                    }
                    set_heap_key(list.first + j, prev);
                    j--;
                    moves--;
                }
            }
            if set_down {
                set_heap_key(list.first + j, v);
                inserting = false;
                i++;
            }
        }
    }
    if sorted {
        atomicStore(&counts[index], SORTED);
    }
}

// `dsm`'s sort of the 2n events of a texel's n segments by depth, starts before ends at one
// depth: a merge sort whose first runs are sorted in registers and whose last pass turns the
// events into the nodes (z, Ω(z)) (`next_node`). `run_sort` reads the segments in runs of RUN
// events (RUN / 2 segments), sorts each in a private array with a bitonic network (`#unroll`:
// every index a constant, so the array stays in registers; 80 compare-exchanges, where an
// insertion sort ran 16 compares and 32 selects an event: run sort 62 -> 55 ms on the thesis
// frame; the network alone costs 2 ms of it, the loads and stores the rest, so runs of 32 (68
// ms, merges 79 -> 65) or 64 (119 ms) gain nothing) and writes it out; `merge_runs` then merges
// groups of up to WAYS runs, one pass a round, between the two sides of the key textures (which
// side is an index offset, `second_side()`, not a branch): pass `step` writes the second side
// when it is odd, the first when it is even (`run_sort` is step 0), and a texel's last pass
// writes its nodes to `resolved_nodes` instead (a list of a single run too, as if its first pass:
// `run_sort` writing those nodes itself, behind a branch on every key, took 3.5 ms more than
// the copy on the thesis frame). Against the heapsort it replaced (the same order: the keys are
// total), each key is read and written once a pass instead of log2(n) times (the textures' loads
// and stores are most of a sort's cost on llvmpipe); merging eight runs a pass instead of four,
// and sorting the starts and ends as one list instead of two then merging them, took the sort and
// merge of the thesis frame from 177 to 128 ms on lavapipe. Each merge group's heads are loaded
// outside the loop over its keys: llvmpipe runs an `if` body inside a loop for every iteration,
// its lanes masked off or not (four runs a pass with each group started inside the one loop: 94
// ms; outside: 81). The fill stores whole segments, one 16-byte store a fragment, which
// `run_sort` splits into events as it reads them: the fill writing both events to the key
// textures instead (four texture stores) took 65 ms against 41, for a run sort of 54 against 63.
// The passes loop 2n + ceil(2n / RUN) times at most, within the budget for any list the capture
// accepts (`longest_list` in src/shadow/deep_capture.rs).
const RUN: u32 = 16u;

// Runs merged at most by one pass, and the two-run levels that makes.
const WAYS: u32 = 8u;
const HALF_WAYS: u32 = 4u;
const WAY_LEVELS: u32 = 3u;

struct Runs {
    // Two-run merge levels over the list's runs of RUN keys, the passes that make them (WAY_LEVELS
    // a pass, WAYS runs merged, the last pass the rest: 1 to WAY_LEVELS), and the levels of the
    // last.
    levels: u32,
    passes: u32,
    last: u32,
};

// ceil(log2(runs)) for runs >= 1.
fn levels_for(runs: u32) -> u32 {
    if runs <= 1u {
        return 0u;
    }
    return firstLeadingBit(runs - 1u) + 1u;
}

// Keep in sync with `merge_passes` in src/shadow/deep_capture.rs.
fn runs_of(keys: u32) -> Runs {
    let levels = levels_for((keys + RUN - 1u) / RUN);
    let passes = (levels + WAY_LEVELS - 1u) / WAY_LEVELS;
    return Runs(levels, passes, levels - WAY_LEVELS * (max(passes, 1u) - 1u));
}

// Keys per run before pass `step` (1-based): RUN · WAYS^(step - 1), whatever the list's length.
// Every texel's pass `step` therefore merges groups of the same width, RUN · WAYS^step, at the
// same indices (a texel's last pass one group, its whole list, within that width), so the lanes
// of a SIMD group walk their groups in step: the pass loops, per group of invocations, no more
// than for its longest list (llvmpipe's loop limit counts per group: `longest_list` in
// src/shadow/deep_capture.rs). (Merging the leftover levels first instead would give texels of
// different lengths groups of different widths, and a SIMD group up to 9% more iterations than
// its longest list.)
fn run_width(step: u32) -> u32 {
    return RUN << (WAY_LEVELS * (step - 1u));
}

// Runs merged by pass `step`: WAYS, the last pass what is left.
fn runs_merged(runs: Runs, step: u32) -> u32 {
    return 1u << select(WAY_LEVELS, runs.last, step == runs.passes);
}

// Whether pass `step` (0: `run_sort`) writes its keys to the second side of the key textures
// (the passes alternate, so pass `step` reads what pass step - 1 wrote).
fn writes_second_side(step: u32) -> bool {
    return step % 2u == 1u;
}

// Events by depth; at one depth the larger change of slope first (starts before ends). A total
// order: two events with equal keys are equal.
fn key_less(a: vec2<f32>, b: vec2<f32>) -> bool {
    return a.x < b.x || (a.x == b.x && a.y > b.y);
}

// The optical depth while a texel's events are turned into nodes in depth order: between
// events Ω grows by the sum of the slopes (optical depth per metre) of the segments open there.
struct Nodes {
    omega: f32,
    slope: f32,
    z: f32,
};

// The node (z, Ω(z)) at `event` (its depth and change of slope), the one after `acc`'s last.
// The slope is kept from dipping below 0 by the rounding of its sum.
fn next_node(acc: ptr<function, Nodes>, event: vec2<f32>) -> vec2<f32> {
    (*acc).omega += (*acc).slope * (event.x - (*acc).z);
    (*acc).slope = max((*acc).slope + event.y, 0.0);
    (*acc).z = event.x;
    return vec2<f32>(event.x, (*acc).omega);
}

// log2(RUN): the bitonic network's stages.
const RUN_BITS: u32 = 4u;
// A run's segments: two events each.
const RUN_SEGMENTS: u32 = 8u;
// The depth of the keys that pad a short run: after every event's. f32::MAX, written as a
// decimal that rounds to it: Tint (the browser's WGSL compiler) refuses 3.4028235e38 as out of
// range.
const PAD_DEPTH: f32 = 3.4028234e38;

// The key at `i` on one side of the key textures.
fn key_from(second: bool, i: u32) -> vec2<f32> {
    return key_at(i + select(0u, second_side(), second));
}

fn set_key_to(second: bool, i: u32, key: vec2<f32>) {
    set_key_at(i + select(0u, second_side(), second), key);
}

// Each run of RUN events sorted in registers and written out.
@compute @workgroup_size(8, 8)
fn run_sort(@builtin(global_invocation_id) id: vec3<u32>) {
    let list = band_list(id);
    let n = 2u * list.count;
    if n == 0u {
        return;
    }
    let base = 2u * list.first;
    let to_second = writes_second_side(0u);
    let last_segment = list.first + list.count - 1u;
    for (var start = 0u; start < n; start += RUN) {
        let m = min(RUN, n - start);
        // The run's segments, two events each (m is even); keys past its end are padding.
        var keys: array<vec2<f32>, RUN>;
        #unroll h 0..RUN_SEGMENTS
            let segment = segment_at(min(list.first + start / 2u + h, last_segment));
            let slope = segment_slope(segment);
            let real = 2u * h < m;
            let pad = vec2<f32>(PAD_DEPTH, 0.0);
            keys[2u * h] = select(pad, vec2<f32>(segment.z0, slope), real);
            keys[2u * h + 1u] = select(pad, vec2<f32>(segment.z1, -slope), real);
        #end_unroll
        // Bitonic sorting network: stage p merges bitonic runs of 2^p keys, each step q
        // compare-exchanges keys 2^(p-1-q) apart, ascending where bit p of i is clear.
        #unroll p 1..RUN_BITS+1
            #unroll q 0..p
                #unroll i 0..RUN
                    if (i ^ (1u << (p - 1u - q))) > i {
                        let l = i ^ (1u << (p - 1u - q));
                        let x = keys[i];
                        let y = keys[l];
                        let swap = select(key_less(x, y), key_less(y, x), (i & (1u << p)) == 0u);
                        keys[i] = select(x, y, swap);
                        keys[l] = select(y, x, swap);
                    }
                #end_unroll
            #end_unroll
        #end_unroll
        #unroll k 0..RUN
            if k < m {
                set_key_to(to_second, base + start + k, keys[k]);
            }
        #end_unroll
    }
}

// Every merge pass of a texel but its last, one a round: the round's index + 1 is the pass.
@compute @workgroup_size(8, 8)
fn merge_runs(@builtin(global_invocation_id) id: vec3<u32>) {
    let list = band_list(id);
    let step = pass_round.index + 1u;
    if step >= runs_of(2u * list.count).passes {
        return;
    }
    merge_pass(list, step, false);
}

// Every texel's last merge pass, which writes its nodes, in one dispatch after all the others:
// `last` is a constant in each entry point, so neither carries the other's stores (a branch on
// it per key took the merges 40-41 -> 45-46 ms on the thesis frame). Each texel's last pass
// merges its whole list as one group, so a SIMD group loops here as often as its longest list.
@compute @workgroup_size(8, 8)
fn merge_last(@builtin(global_invocation_id) id: vec3<u32>) {
    let list = band_list(id);
    if list.count == 0u {
        return;
    }
    // A list of one run (no merge pass) is merged as if by a first pass: copied into its nodes.
    merge_pass(list, max(runs_of(2u * list.count).passes, 1u), true);
}

// Merge pass `step` over the texel's runs: groups of WAYS (or fewer) sorted runs of `run_width`
// keys, merged (stably: the first run's key on a tie) from one side of the key textures to the
// other at the same indices, or for the `last` its nodes into `resolved_nodes`. A loop over the
// groups, each group's heads loaded before a loop over its keys. The runs' next keys are held in
// registers (every index below is a constant), each loaded once.
fn merge_pass(list: TexelList, step: u32, last: bool) {
    let n = 2u * list.count;
    let runs = runs_of(n);
    let base = 2u * list.first;
    let to_second = writes_second_side(step);
    let from_second = !to_second;
    let width = run_width(step);
    let ways = runs_merged(runs, step);
    var nodes = Nodes(0.0, 0.0, 0.0);
    var previous = vec2<f32>(0.0);
    // Each run's next index and end, and its key there: once the run is used up, an infinite
    // depth, after every event's (so the selection needs no check of which runs are open).
    var at: array<u32, WAYS>;
    var end: array<u32, WAYS>;
    var depth: array<f32, WAYS>;
    var slope: array<f32, WAYS>;
    // (Made of a value known only at run time: Tint, the browser's WGSL compiler, refuses an
    // infinity its constant evaluation computes.)
    let exhausted = vec2<f32>(bitcast<f32>(0x7f800000u | (list.count & 0u)), 0.0);
    for (var group = 0u; group < n; group += ways * width) {
        let group_end = min(group + ways * width, n);
        var begin = group;
        #unroll w 0..WAYS
            at[w] = begin;
            end[w] = select(begin, min(begin + width, group_end), w < ways);
            depth[w] = exhausted.x;
            slope[w] = exhausted.y;
            if begin < end[w] {
                let key = key_from(from_second, base + begin);
                depth[w] = key.x;
                slope[w] = key.y;
            }
            begin = end[w];
        #end_unroll
        for (var k = group; k < group_end; k++) {
            // The least next key, the earliest run's on a tie; no branch on which (lanes that took
            // from different runs would otherwise run every side's loads and stores). A tree of
            // pairwise minima, each taking the right only where it is strictly less: three
            // compares deep where a scan over the runs chained seven (each waiting on the last),
            // the merges 13.7-14.0 -> 12.0-12.2 ms and the last pass 29.5-30.9 -> 26.4-27.9 on
            // the thesis frame.
            var tree_depth = depth;
            var tree_slope = slope;
            var tree_run: array<u32, WAYS>;
            #unroll w 0..WAYS
                tree_run[w] = w;
            #end_unroll
            #unroll level 0..WAY_LEVELS
                #unroll i 0..HALF_WAYS
                    if i < (WAYS >> (level + 1u)) {
                        let left = vec2<f32>(tree_depth[2u * i], tree_slope[2u * i]);
                        let right = vec2<f32>(tree_depth[2u * i + 1u], tree_slope[2u * i + 1u]);
                        let take_right = key_less(right, left);
                        tree_depth[i] = select(left.x, right.x, take_right);
                        tree_slope[i] = select(left.y, right.y, take_right);
                        tree_run[i] = select(tree_run[2u * i], tree_run[2u * i + 1u], take_right);
                    }
                #end_unroll
            #end_unroll
            let best = vec2<f32>(tree_depth[0], tree_slope[0]);
            let taken = tree_run[0];
            let node = next_node(&nodes, best);
            if last {
                // The last pass's one group starts at 0, and n is even: every pair is whole.
                if k % 2u == 1u {
                    set_node_pair(base + k - 1u, previous, node);
                }
                previous = node;
            } else {
                set_key_to(to_second, base + k, best);
            }
            // The taken run's next key.
            var next = 0u;
            var next_end = 0u;
            #unroll w 0..WAYS
                at[w] += u32(taken == w);
                next = select(next, at[w], taken == w);
                next_end = select(next_end, end[w], taken == w);
            #end_unroll
            var key = exhausted;
            if next < next_end {
                key = key_from(from_second, base + next);
            }
            #unroll w 0..WAYS
                depth[w] = select(depth[w], key.x, taken == w);
                slope[w] = select(slope[w], key.y, taken == w);
            #end_unroll
        }
    }
}
