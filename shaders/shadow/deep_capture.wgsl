// Deep capture (src/shadow/deep_capture.rs): every light-space particle fragment's chord
// segment stored per texel and merged into the texel's piecewise-linear optical depth, the
// uncompressed deep shadow map of Lokovic & Veach (2000) that `dsm` and `avsm` compress. A copy
// of `exact`'s build (shaders/shadow/exact_build.wgsl), with a total sort key.
// 1. fs_count: every light-space particle fragment (one light ray through one particle) counts
//    itself in its texel (atomic add).
// 2. scan_rows, scan_total, scan_write: exclusive prefix sum of the counts -> list offsets
//    (offsets[res²] = total).
// 3. fs_fill: every fragment of the current band of rows writes its segment (z0, z1, optical
//    depth) into its texel's list (counts, cleared, serve as cursors).
// 4. resolve (sort_segments_*, copy_ends, sort_ends_*, merge_nodes): per texel of the band,
//    sort the segments by (z0, z1, optical depth), sort their ends by (depth, slope), and merge both into the nodes (z, Ω(z)) of the piecewise-linear optical
//    depth: between events Ω grows by the sum of the slopes (optical depth per metre) of the
//    segments open there. The keys are total, so the lists, and everything computed from them,
//    do not depend on the order the fragments arrived in.
#import shadow/layered_build.wgsl
#import shadow/deep_capture_lists.wgsl

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

@fragment
fn fs_fill(in: BuildVertexOut) -> @location(0) vec4<f32> {
    let segment = fragment_segment(in);
    if segment.optical_depth < 0.0 {
        discard;
    }
    // The pass's scissor keeps to the band's rows; this makes sure of it.
    let row = u32(in.clip.y);
    if row < capture.row_begin || row >= capture.row_end {
        discard;
    }
    let index = texel_index(in.clip);
    let slot = offsets[index] - capture.band_base + atomicAdd(&counts[index], 1u);
    if slot < capture.capacity {
        segments[slot] = segment;
    }
    return vec4<f32>(0.0);
}

const SCAN_GROUP: u32 = 64u;

// Sum of each row's counts.
@compute @workgroup_size(64)
fn scan_rows(@builtin(global_invocation_id) id: vec3<u32>) {
    let row = id.x;
    if row >= capture.resolution {
        return;
    }
    var sum = 0u;
    for (var x = 0u; x < capture.resolution; x++) {
        sum += atomicLoad(&counts[row * capture.resolution + x]);
    }
    row_sums[row] = sum;
}

// Exclusive scan of the row sums (one invocation: there are only `resolution` of them).
@compute @workgroup_size(1)
fn scan_total() {
    var running = 0u;
    for (var row = 0u; row < capture.resolution; row++) {
        let sum = row_sums[row];
        row_sums[row] = running;
        running += sum;
    }
    row_sums[capture.resolution] = running;
    offsets[capture.resolution * capture.resolution] = running;
}

// Each row's exclusive offsets.
@compute @workgroup_size(64)
fn scan_write(@builtin(global_invocation_id) id: vec3<u32>) {
    let row = id.x;
    if row >= capture.resolution {
        return;
    }
    var running = row_sums[row];
    for (var x = 0u; x < capture.resolution; x++) {
        let index = row * capture.resolution + x;
        offsets[index] = running;
        running += atomicLoad(&counts[index]);
    }
}

// The total order of segments: by start, then end, then optical depth (segments equal in all
// three are interchangeable).
fn segment_before(a: Segment, b: Segment) -> bool {
    if a.z0 != b.z0 {
        return a.z0 < b.z0;
    }
    if a.z1 != b.z1 {
        return a.z1 < b.z1;
    }
    return a.optical_depth < b.optical_depth;
}

// The total order of (end depth, slope) pairs.
fn end_before(a: vec2<f32>, b: vec2<f32>) -> bool {
    if a.x != b.x {
        return a.x < b.x;
    }
    return a.y < b.y;
}

fn segment_slope(s: Segment) -> f32 {
    return s.optical_depth / (s.z1 - s.z0);
}

fn sift_segment(base: u32, root_in: u32, n: u32) {
    var root = root_in;
    let value = segments[base + root];
    loop {
        var child = 2u * root + 1u;
        if child >= n {
            break;
        }
        if child + 1u < n && segment_before(segments[base + child], segments[base + child + 1u]) {
            child += 1u;
        }
        if !segment_before(value, segments[base + child]) {
            break;
        }
        segments[base + root] = segments[base + child];
        root = child;
    }
    segments[base + root] = value;
}

fn sift_end(base: u32, root_in: u32, n: u32) {
    var root = root_in;
    let value = nodes[base + root];
    loop {
        var child = 2u * root + 1u;
        if child >= n {
            break;
        }
        if child + 1u < n && end_before(nodes[base + child], nodes[base + child + 1u]) {
            child += 1u;
        }
        if !end_before(value, nodes[base + child]) {
            break;
        }
        nodes[base + root] = nodes[base + child];
        root = child;
    }
    nodes[base + root] = value;
}

// The resolve, in phases (a dispatch each, or several: rounds), per texel of the band: heapsort
// its segments by `segment_before` (build the heap, then move the largest to the end), copy their
// ends with the slope each one closes into the upper half of its nodes and heapsort them by
// `end_before`, then merge both into the nodes. O(n log n) whatever the order the fragments
// arrived in. The heapsorts' sifts are split into rounds of `sifts_per_round()` each, so that no
// dispatch loops past `capture.loop_budget` (src/shadow/deep_capture.rs mirrors the arithmetic);
// a texel whose sort is done returns at once.

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

@compute @workgroup_size(8, 8)
fn sort_segments_build(@builtin(global_invocation_id) id: vec3<u32>) {
    let list = band_list(id);
    let r = build_range(list.count);
    for (var start = r.x; start > r.y; start--) {
        sift_segment(list.first, start - 1u, list.count);
    }
}

@compute @workgroup_size(8, 8)
fn sort_segments_extract(@builtin(global_invocation_id) id: vec3<u32>) {
    let list = band_list(id);
    let base = list.first;
    let r = extract_range(list.count);
    for (var end = r.x; end > r.y; end--) {
        let top = segments[base];
        segments[base] = segments[base + end - 1u];
        segments[base + end - 1u] = top;
        sift_segment(base, 0u, end - 1u);
    }
}

// The ends go to the upper half of the texel's nodes.
@compute @workgroup_size(8, 8)
fn copy_ends(@builtin(global_invocation_id) id: vec3<u32>) {
    let list = band_list(id);
    let ends = 2u * list.first + list.count;
    for (var i = 0u; i < list.count; i++) {
        let s = segments[list.first + i];
        nodes[ends + i] = vec2<f32>(s.z1, segment_slope(s));
    }
}

@compute @workgroup_size(8, 8)
fn sort_ends_build(@builtin(global_invocation_id) id: vec3<u32>) {
    let list = band_list(id);
    let r = build_range(list.count);
    for (var start = r.x; start > r.y; start--) {
        sift_end(2u * list.first + list.count, start - 1u, list.count);
    }
}

@compute @workgroup_size(8, 8)
fn sort_ends_extract(@builtin(global_invocation_id) id: vec3<u32>) {
    let list = band_list(id);
    let base = 2u * list.first + list.count;
    let r = extract_range(list.count);
    for (var end = r.x; end > r.y; end--) {
        let top = nodes[base];
        nodes[base] = nodes[base + end - 1u];
        nodes[base + end - 1u] = top;
        sift_end(base, 0u, end - 1u);
    }
}

// Merges the sorted starts and ends into nodes [2·first, 2·first + 2n). Writing node k = i + j
// never overtakes the unread ends (k <= n + j), so the merge works in place.
@compute @workgroup_size(8, 8)
fn merge_nodes(@builtin(global_invocation_id) id: vec3<u32>) {
    let list = band_list(id);
    let first = list.first;
    let n = list.count;
    if n == 0u {
        return;
    }
    let ends = 2u * first + n;
    var i = 0u;
    var j = 0u;
    var omega = 0.0;
    var slope = 0.0;
    var z_prev = segments[first].z0;
    for (var k = 0u; k < 2u * n; k++) {
        var z: f32;
        var delta: f32;
        if i < n && (j >= n || segments[first + i].z0 <= nodes[ends + j].x) {
            let s = segments[first + i];
            z = s.z0;
            delta = segment_slope(s);
            i++;
        } else {
            let e = nodes[ends + j];
            z = e.x;
            delta = -e.y;
            j++;
        }
        omega += slope * (z - z_prev);
        slope = max(slope + delta, 0.0);
        z_prev = z;
        nodes[2u * first + k] = vec2<f32>(z, omega);
    }
}
