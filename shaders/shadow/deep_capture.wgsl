// Deep capture (src/shadow/deep_capture.rs): every light-space particle fragment's chord
// segment stored per texel and merged into the texel's piecewise-linear optical depth, the
// uncompressed deep shadow map of Lokovic & Veach (2000) that `dsm` and `avsm` compress.
// 1. fs_count: every light-space particle fragment (one light ray through one particle) counts
//    itself in its texel (atomic add).
// 2. scan_rows, scan_total, scan_write (shaders/shadow/grid_scan.wgsl, shared with `exact`):
//    exclusive prefix sum of the counts -> list offsets (offsets[res²] = total).
// 3. fs_fill: every fragment of the current band of rows writes its segment (z0, z1, optical
//    depth, draw index) into its texel's list (counts, cleared, serve as cursors); for `dsm`,
//    fs_fill_split writes its start (z0, slope) and its end (z1, slope) to the sort keys (two
//    read-write storage textures) instead.
// 4. resolve (run_sort and merge_runs for the starts, the same for the ends, merge_nodes): per
//    texel of the band, `dsm`'s sorts the starts and the ends each by (depth, slope), and merges both
//    into the nodes (z, Ω(z)) of the piecewise-linear optical depth: between events Ω grows by
//    the sum of the slopes (optical depth per metre) of the segments open there. The keys are total over what is sorted, so
//    the nodes do not depend on the order the fragments arrived in. An owner that needs the
//    segments themselves has them sorted whole (an insertion sort that gives up early, then a
//    heapsort of the lists it left): by (z0, z1, optical depth, draw index), or with
//    SORT_BY_DRAW by draw index, which puts each texel's list back in the order the particles
//    were drawn, whatever order the fill's atomics wrote it in.
#import shadow/layered_build.wgsl
#import shadow/deep_capture_lists.wgsl
#import shadow/grid_scan.wgsl

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

// The colour output is a dummy (its target's write mask is empty): the lists are the result.
@fragment
fn fs_count(in: BuildVertexOut) -> @location(0) vec4<f32> {
    if fragment_segment(in).optical_depth < 0.0 {
        discard;
    }
    atomicAdd(&counts[texel_index(in.clip)], 1u);
    return vec4<f32>(0.0);
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
        segments[at.slot] = segment;
    }
    return vec4<f32>(0.0);
}

// The fill of a resolve into nodes (`dsm`'s): each segment goes straight to the sort keys,
// split into its start (z0, slope) and its end (z1, slope) (the end's place needs the texel's
// count: the offsets give it); nothing reads the segments. (A compute pass that split the
// stored segments instead cost 50-150 ms more of `dsm`'s frame on the thesis scene.)
@fragment
fn fs_fill_split(in: BuildVertexOut) -> @location(0) vec4<f32> {
    let segment = fragment_segment(in);
    let at = fill_slot(in, segment);
    if at.index == NO_TEXEL {
        discard;
    }
    let first = offsets[at.index] - capture.band_base;
    let count = offsets[at.index + 1u] - offsets[at.index];
    if first + count <= capture.capacity {
        let slope = segment_slope(segment);
        let i = at.slot - first;
        set_sort_key(2u * first + i, vec2<f32>(segment.z0, slope));
        set_sort_key(2u * first + count + i, vec2<f32>(segment.z1, slope));
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

@fragment
fn fs_count_volume(in: VolumeVertexOut) -> @location(0) vec4<f32> {
    let ray = volume_light_ray(in.ndc);
    var n = 0u;
    for (var i = 0u; i < ray.steps; i++) {
        n += u32(volume_segment(ray, i).optical_depth >= 0.0);
    }
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
            segments[slot] = segment;
        }
    }
    return vec4<f32>(0.0);
}

@fragment
fn fs_fill_split_volume(in: VolumeVertexOut) -> @location(0) vec4<f32> {
    let index = volume_texel(in.clip);
    let ray = volume_light_ray(in.ndc);
    if index == NO_TEXEL || ray.steps == 0u {
        discard;
    }
    let first = offsets[index] - capture.band_base;
    let count = offsets[index + 1u] - offsets[index];
    for (var i = 0u; i < ray.steps; i++) {
        let segment = volume_segment(ray, i);
        if segment.optical_depth < 0.0 {
            continue;
        }
        let slot = offsets[index] - capture.band_base + atomicAdd(&counts[index], 1u);
        if first + count <= capture.capacity {
            let slope = segment_slope(segment);
            let k = slot - first;
            set_sort_key(2u * first + k, vec2<f32>(segment.z0, slope));
            set_sort_key(2u * first + count + k, vec2<f32>(segment.z1, slope));
        }
    }
    return vec4<f32>(0.0);
}

// The scan's grid is the map (shaders/shadow/grid_scan.wgsl).
fn scan_side() -> u32 {
    return capture.resolution;
}

fn segment_slope(s: Segment) -> f32 {
    return s.optical_depth / (s.z1 - s.z0);
}

// Which list a sort pipeline sorts (set per pipeline: src/shadow/deep_capture.rs, `Resolve`):
// the texel's segments whole, or its starts or its ends, which `fs_fill_split` writes to the
// sort keys.
const LIST_SEGMENTS: u32 = 0u;
const LIST_STARTS: u32 = 1u;
const LIST_ENDS: u32 = 2u;
override SORT_LIST: u32 = LIST_SEGMENTS;
// Whether the segments are sorted by draw index alone rather than by depth.
override SORT_BY_DRAW: bool = false;

// An element of the whole-segment sorts (the insertion sort and the heapsort): a segment's
// (z0, z1, optical depth) and its draw index. (The index stays a u32: its bits as a float would
// be a denormal, which a GPU may flush.) `dsm`'s starts and ends have their own merge sort,
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
    let s = segments[i];
    return HeapItem(vec3<f32>(s.z0, s.z1, s.optical_depth), s.draw_index);
}

fn set_heap_key(i: u32, item: HeapItem) {
    segments[i] = Segment(item.key.x, item.key.y, item.key.z, item.draw_index);
}

// Where the list SORT_LIST names starts: the segments at `first`; the starts at 2·first and the
// ends after them in the sort keys.
fn list_base(list: TexelList) -> u32 {
    if SORT_LIST == LIST_ENDS {
        return 2u * list.first + list.count;
    }
    if SORT_LIST == LIST_STARTS {
        return 2u * list.first;
    }
    return list.first;
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
// slope) to the sort keys: merge sort the starts (`run_sort`, `merge_runs`, below), then the
// ends (the same entry points, SORT_LIST set); merge both into the nodes. Only the starts and
// ends are sorted, two words each: two starts (or ends) with equal keys are equal, so the order
// is total over what is sorted. `avsm`'s: sort the whole segments (by depth or by draw index) with `insertion_sort`,
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
    let base = list_base(list);
    let r = build_range(list.count);
    for (var start = r.x; start > r.y; start--) {
        sift(base, start - 1u, list.count);
    }
}

// The extraction: this round's ends, each taking the heap's largest before the heap shrinks.
@compute @workgroup_size(8, 8)
fn heap_extract(@builtin(global_invocation_id) id: vec3<u32>) {
    let list = heap_list(id);
    let base = list_base(list);
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
// after n/4 moves (the list,
// still a permutation of itself, is left to the heapsort, as most lists of the by-depth resolve
// are); a list it sorts is marked SORTED in `counts` (the fill's cursors, unused from here on),
// and the heap passes skip it. At most n + 2·(n/4) + 2 loop iterations, within the loop budget
// for any list the capture accepts (n <= budget/2 - 2).
const SORTED: u32 = 0xffffffffu;

// How many of a list's first segments are in draw order, read a word a segment (the draw
// index; the insertion sort reads all four): where the rasteriser keeps the draw order per
// pixel, the whole list, and then nothing else is read. Loops as many times as it returns (plus
// one), and the insertion sort goes on from there, so the two together stay within its bound.
fn draw_ordered_prefix(list: TexelList) -> u32 {
    var before = 0u;
    for (var i = 0u; i < list.count; i++) {
        let draw = segments[list.first + i].draw_index;
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
    var moves = list.count / 4u;
    if list.count > start {
        // The largest of the sorted prefix: a segment not before it stays where it is.
        var last = heap_key(list.first + start - 1u);
        for (var i = start; i < list.count; i++) {
            let v = heap_key(list.first + i);
            if !key_before(v, last) {
                last = v;
                continue;
            }
            var j = i;
            loop {
                if j == 0u {
                    break;
                }
                let prev = heap_key(list.first + j - 1u);
                if !key_before(v, prev) {
                    break;
                }
                if moves == 0u {
                    sorted = false;
                    break;
                }
                set_heap_key(list.first + j, prev);
                j--;
                moves--;
            }
            set_heap_key(list.first + j, v);
            if !sorted {
                break;
            }
        }
    }
    if sorted {
        atomicStore(&counts[index], SORTED);
    }
}

// Merges the sorted starts and ends (the sort keys) into the node textures' [2·first, 2·first +
// 2n). The next start and the next end are held, each loaded once.
@compute @workgroup_size(8, 8)
fn merge_nodes(@builtin(global_invocation_id) id: vec3<u32>) {
    let list = band_list(id);
    let first = list.first;
    let n = list.count;
    if n == 0u {
        return;
    }
    let starts = 2u * first;
    let ends = starts + n;
    var i = 0u;
    var j = 0u;
    var omega = 0.0;
    var slope = 0.0;
    var start = sort_key(starts);
    var end = sort_key(ends);
    var z_prev = start.x;
    for (var k = 0u; k < 2u * n; k++) {
        var z: f32;
        var delta: f32;
        if i < n && (j >= n || start.x <= end.x) {
            z = start.x;
            delta = start.y;
            i++;
            if i < n {
                start = sort_key(starts + i);
            }
        } else {
            z = end.x;
            delta = -end.y;
            j++;
            if j < n {
                end = sort_key(ends + j);
            }
        }
        omega += slope * (z - z_prev);
        slope = max(slope + delta, 0.0);
        z_prev = z;
        set_node_texel(starts + k, vec2<f32>(z, omega));
    }
}

// `dsm`'s sort of the starts (or the ends, SORT_LIST) by (depth, slope): a merge sort whose
// first runs are sorted in registers. `run_sort` reads the list in runs of RUN (or RUN / 2)
// keys, sorts each by insertion into a private array written out slot by slot (`#unroll`, no
// index known only at run time, so the array stays in registers), and writes it back in place;
// `merge_runs` then merges groups of four runs (or of two), one pass a round, between the sort
// keys and the node textures (free until `merge_nodes` fills them; the same indices): odd
// passes (round 0, 2, ...) from the keys into the nodes, even passes back. A texel takes the
// shorter runs, or two passes of pairs, when the longer ones or groups of four would leave it
// an odd number of passes, so every list ends sorted in the keys, and each round reads and
// writes the same textures for every texel. Against the heapsort it replaced (the same order:
// the keys are total), each key is read and written once a pass instead of log2(n) times (the
// textures' loads and stores are most of a sort's cost on llvmpipe), and merging four runs at
// a time halves the passes again.
const RUN: u32 = 16u;

struct Runs {
    // Keys per run, the two-run merge levels that join them (even), and the passes that make
    // those levels: two levels a pass (four runs merged), or one a pass (pairs) for the first
    // two passes when levels / 2 is odd, so that the passes are even too.
    length: u32,
    levels: u32,
    passes: u32,
};

// ceil(log2(runs)) for runs >= 1.
fn levels_for(runs: u32) -> u32 {
    if runs <= 1u {
        return 0u;
    }
    return firstLeadingBit(runs - 1u) + 1u;
}

// Keep in sync with `merge_passes` in src/shadow/deep_capture.rs.
fn runs_of(n: u32) -> Runs {
    var out = Runs(RUN, levels_for((n + RUN - 1u) / RUN), 0u);
    if out.levels % 2u == 1u {
        // Halved runs take one level more: ceil(log2(2r - 1)) = ceil(log2(r)) + 1 for r >= 2.
        out.length = RUN / 2u;
        out.levels += 1u;
    }
    let fours = out.levels / 2u;
    out.passes = fours + fours % 2u;
    return out;
}

// Runs merged by pass `step` (1-based): 2 in the first two passes of a texel whose levels / 2
// is odd, else 4.
fn runs_merged(runs: Runs, step: u32) -> u32 {
    if (runs.levels / 2u) % 2u == 1u && step <= 2u {
        return 2u;
    }
    return 4u;
}

fn key_less(a: vec2<f32>, b: vec2<f32>) -> bool {
    return a.x < b.x || (a.x == b.x && a.y < b.y);
}

// A run while it is sorted: keys (depth[k], slope[k]), the first `count` in order.
struct Run {
    depth: array<f32, RUN>,
    slope: array<f32, RUN>,
    count: u32,
};

// Inserts `key` after every key of the run not after it.
fn insert_key(run: ptr<function, Run>, key: vec2<f32>) {
    let n = (*run).count;
    var at = 0u;
    #unroll k 0..RUN
        at += u32(k < n && !key_less(key, vec2<f32>((*run).depth[k], (*run).slope[k])));
    #end_unroll
    #unroll k rev 1..RUN
        (*run).depth[k] = select(select((*run).depth[k], key.x, k == at), (*run).depth[k - 1u], k > at);
        (*run).slope[k] = select(select((*run).slope[k], key.y, k == at), (*run).slope[k - 1u], k > at);
    #end_unroll
    (*run).depth[0] = select((*run).depth[0], key.x, at == 0u);
    (*run).slope[0] = select((*run).slope[0], key.y, at == 0u);
    (*run).count = n + 1u;
}

// Loops: n / (RUN / 2) runs of at most RUN reads each.
@compute @workgroup_size(8, 8)
fn run_sort(@builtin(global_invocation_id) id: vec3<u32>) {
    let list = band_list(id);
    let n = list.count;
    if n < 2u {
        return;
    }
    let base = list_base(list);
    let runs = runs_of(n);
    for (var start = 0u; start < n; start += runs.length) {
        let m = min(runs.length, n - start);
        var run: Run;
        run.count = 0u;
        for (var i = 0u; i < m; i++) {
            insert_key(&run, sort_key(base + start + i));
        }
        #unroll k 0..RUN
            if k < m {
                set_sort_key(base + start + k, vec2<f32>(run.depth[k], run.slope[k]));
            }
        #end_unroll
    }
}

// One merge pass (the round's index + 1) over the texel's runs: groups of 4 (or 2) sorted runs
// of `width` keys, merged (stably: the first run's key on a tie) from one pair of textures into
// the other at the same indices. Loops n + n / width times at most.
fn key_from(nodes_side: bool, i: u32) -> vec2<f32> {
    if nodes_side {
        return node_texel(i);
    }
    return sort_key(i);
}

fn set_key_to(nodes_side: bool, i: u32, key: vec2<f32>) {
    if nodes_side {
        set_node_texel(i, key);
    } else {
        set_sort_key(i, key);
    }
}

// The next key of one run: its index and end, and the key there.
struct Head {
    at: u32,
    end: u32,
    key: vec2<f32>,
};

fn head(from_nodes: bool, base: u32, begin: u32, end: u32) -> Head {
    var h = Head(begin, end, vec2<f32>(0.0));
    if begin < end {
        h.key = key_from(from_nodes, base + begin);
    }
    return h;
}

// Whether head `h` holds a key before the best so far (`best_open`: whether there is one).
fn better(h: Head, best: vec2<f32>, best_open: bool) -> bool {
    return h.at < h.end && (!best_open || key_less(h.key, best));
}

@compute @workgroup_size(8, 8)
fn merge_runs(@builtin(global_invocation_id) id: vec3<u32>) {
    let list = band_list(id);
    let n = list.count;
    let step = pass_round.index + 1u;
    let runs = runs_of(n);
    if step > runs.passes {
        return;
    }
    let base = list_base(list);
    // Odd passes read the keys and write the nodes; even passes the other way.
    let from_nodes = step % 2u == 0u;
    var width = runs.length;
    for (var p = 1u; p < step; p++) {
        width *= runs_merged(runs, p);
    }
    let ways = runs_merged(runs, step);
    for (var start = 0u; start < n; start += ways * width) {
        let end = min(start + ways * width, n);
        var h0 = head(from_nodes, base, start, min(start + width, end));
        var h1 = head(from_nodes, base, h0.end, min(h0.end + width, end));
        // With pairs the last two runs are empty.
        let third = select(h1.end, min(h1.end + width, end), ways == 4u);
        var h2 = head(from_nodes, base, h1.end, third);
        var h3 = head(from_nodes, base, h2.end, select(h2.end, end, ways == 4u));
        for (var k = start; k < end; k++) {
            // The least head, the earliest run's on a tie; no branch on which (lanes that
            // took from different runs would otherwise run every side's loads and stores).
            var best = h0.key;
            var taken = 0u;
            var open = h0.at < h0.end;
            let t1 = better(h1, best, open);
            best = select(best, h1.key, t1);
            taken = select(taken, 1u, t1);
            open = open || h1.at < h1.end;
            let t2 = better(h2, best, open);
            best = select(best, h2.key, t2);
            taken = select(taken, 2u, t2);
            open = open || h2.at < h2.end;
            let t3 = better(h3, best, open);
            best = select(best, h3.key, t3);
            taken = select(taken, 3u, t3);
            set_key_to(!from_nodes, base + k, best);
            h0.at += u32(taken == 0u);
            h1.at += u32(taken == 1u);
            h2.at += u32(taken == 2u);
            h3.at += u32(taken == 3u);
            // The taken run's next key.
            let next = select(select(select(h0.at, h1.at, taken == 1u), h2.at, taken == 2u), h3.at, taken == 3u);
            let next_end = select(select(select(h0.end, h1.end, taken == 1u), h2.end, taken == 2u), h3.end, taken == 3u);
            if next < next_end {
                let key = key_from(from_nodes, base + next);
                h0.key = select(h0.key, key, taken == 0u);
                h1.key = select(h1.key, key, taken == 1u);
                h2.key = select(h2.key, key, taken == 2u);
                h3.key = select(h3.key, key, taken == 3u);
            }
        }
    }
}
