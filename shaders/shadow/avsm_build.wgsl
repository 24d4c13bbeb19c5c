// `avsm` build: adaptive volumetric shadow maps (Salvi, Vidimče, Lauritzen & Lefohn 2010) as a
// resolve over the deep capture (shaders/shadow/deep_capture.wgsl). WebGPU has no fragment
// shader interlock, so instead of inserting fragments as they are rasterised, one invocation per
// texel inserts its captured segments in the order the capture's resolve left them: by draw
// index (`avsm_insert = draw`, the paper's streaming insertion, serialised in primitive order as
// an interlock would) or by (z0, z1, optical depth) (`sorted`, independent of the draw order).
// A segment adds an entry node at z0 (T of the curve there) and an exit node at z1; T is linear
// inside it, so the nodes behind its entry are multiplied by its ramp, 1 at z0 to
// e^-optical_depth at z1 and beyond (`avsm_chord = linear`, the paper's). With
// `avsm_chord = pieces` the chord enters as CHORD_PIECES linear pieces, their ends at the
// chord's exponential T, and the ramp is exponential. While the curve has more than N = deep.nodes_per_texel
// nodes, the interior node whose removal loses the least area under it (the triangle with its
// neighbours) goes; the first and last nodes stay.
// Keep `DeepParams` in sync with src/shadow/deep_nodes.rs. The CPU mirror is
// src/shadow/deep_compress.rs.
#import shadow/deep_capture_lists.wgsl
#import shadow/deep_params.wgsl

@group(2) @binding(0) var<uniform> deep: DeepParams;
@group(2) @binding(1) var<storage, read_write> out_nodes: array<vec2<f32>>;

// The curve's slots, CURVE_NODES: the budget's N plus the CHORD_PIECES + 1 nodes a segment
// inserts before its removals, constants composed before this file (src/shadow/avsm.rs,
// `compress_constants`).
const_assert CURVE_NODES >= 4u;
const_assert CHORD_PIECES >= 1u;

// One texel's transmittance curve while it is built: nodes (z[k], t[k]) sorted by z, the first
// `count` of them meaningful (the others hold leftovers that every step masks out).
//
// Every loop over the curve is written out slot by slot (`#unroll`, src/shaders.rs), over its
// CURVE_NODES slots, and selects where a branch, a search or an early exit
// would go: no element is indexed by a value known only at run time, so the curve stays in
// registers. (llvmpipe keeps a dynamically indexed private array in memory and moves its
// elements one lane at a time: loops that searched and shifted by index cost `avsm`'s build on
// the thesis scene 300 ms against 60 ms.) The results are the CPU mirror's, node for node.
struct Curve {
    z: array<f32, CURVE_NODES>,
    t: array<f32, CURVE_NODES>,
    count: u32,
};

// T of the curve at z: 1 in front of the first node, the last node's T behind the last, linear
// between the nodes k - 1 and k of the first k with z[k] > z.
fn curve_at(c: ptr<function, Curve>, z: f32) -> f32 {
    let n = (*c).count;
    // The bracketing nodes; behind the last node both are the last.
    var a = vec2<f32>((*c).z[0], (*c).t[0]);
    var b = a;
    #unroll k 1..CURVE_NODES
        let node = vec2<f32>((*c).z[k], (*c).t[k]);
        let inside = k < n && (*c).z[k - 1u] <= z && z < node.x;
        a = select(a, vec2<f32>((*c).z[k - 1u], (*c).t[k - 1u]), inside);
        b = select(b, node, inside);
        let behind = k + 1u == n && z >= node.x;
        a = select(a, node, behind);
        b = select(b, node, behind);
    #end_unroll
    // (mix(t, t, u) is t for u in {0, 1}, the only u a = b gives.)
    let value = mix(a.y, b.y, clamp((z - a.x) / max(b.x - a.x, 1e-12), 0.0, 1.0));
    return select(select(value, (*c).t[0], n == 1u), 1.0, n == 0u || z <= (*c).z[0]);
}

// Inserts node (z, t) after every node at depth <= z.
fn insert_node(c: ptr<function, Curve>, z: f32, t: f32) {
    let n = (*c).count;
    var at = 0u;
    #unroll k 0..CURVE_NODES
        at += u32(k < n && (*c).z[k] <= z);
    #end_unroll
    #unroll k rev 1..CURVE_NODES
        (*c).z[k] = select(select((*c).z[k], z, k == at), (*c).z[k - 1u], k > at);
        (*c).t[k] = select(select((*c).t[k], t, k == at), (*c).t[k - 1u], k > at);
    #end_unroll
    (*c).z[0] = select((*c).z[0], z, at == 0u);
    (*c).t[0] = select((*c).t[0], t, at == 0u);
    (*c).count = n + 1u;
}

// Depth of the end of piece j (0..=CHORD_PIECES) of a segment's chord.
fn piece_depth(s: Segment, j: u32) -> f32 {
    return s.z0 + (s.z1 - s.z0) * f32(j) / f32(CHORD_PIECES);
}

fn insert_segment(c: ptr<function, Curve>, s: Segment) {
    let t_exit = exp(-s.optical_depth);
    let t_entry = curve_at(c, s.z0);
    let t_behind = curve_at(c, s.z1) * t_exit;
    // The interior piece ends' T, read off the curve before the ramp changes it (none for the
    // linear chord): the curve's T there times the chord's own exponential T.
    var inner: array<f32, CHORD_PIECES>;
    #unroll j 1..CHORD_PIECES
        inner[j] = curve_at(c, piece_depth(s, j)) * exp(-s.optical_depth * f32(j) / f32(CHORD_PIECES));
    #end_unroll
    let width = max(s.z1 - s.z0, 1e-12);
    let n = (*c).count;
    #unroll k 0..CURVE_NODES
        let z = (*c).z[k];
        let u = min((z - s.z0) / width, 1.0);
        let ramp = select(mix(1.0, t_exit, u), exp(-s.optical_depth * u), CHORD_PIECES > 1u);
        (*c).t[k] = select((*c).t[k], (*c).t[k] * ramp, k < n && z > s.z0);
    #end_unroll
    insert_node(c, s.z0, t_entry);
    #unroll j 1..CHORD_PIECES
        insert_node(c, piece_depth(s, j), inner[j]);
    #end_unroll
    insert_node(c, s.z1, t_behind);
}

// Removes the interior node whose removal changes the area under the curve least (the first of
// equals).
fn remove_least_area(c: ptr<function, Curve>) {
    let n = (*c).count;
    var best = 1u;
    var best_area = 3.0e38;
    #unroll k 1..CURVE_NODES-1
        let za = (*c).z[k - 1u];
        let ta = (*c).t[k - 1u];
        let area = abs(((*c).z[k] - za) * ((*c).t[k + 1u] - ta) - ((*c).z[k + 1u] - za) * ((*c).t[k] - ta));
        let smaller = k + 1u < n && area < best_area;
        best = select(best, k, smaller);
        best_area = select(best_area, area, smaller);
    #end_unroll
    #unroll k 1..CURVE_NODES-1
        (*c).z[k] = select((*c).z[k], (*c).z[k + 1u], k >= best);
        (*c).t[k] = select((*c).t[k], (*c).t[k + 1u], k >= best);
    #end_unroll
    (*c).count = n - 1u;
}

// Segments inserted per round (see src/shadow/deep_capture.rs): the curve's steps are written
// out, not looped, so one insertion loops 2·CHORD_PIECES + 2 times at most (the loop over the
// segments, and the removals' `while`: CHORD_PIECES + 1 removals and its exit; the interior
// nodes are written out too, but counted); twice that, for a margin. Keep in sync with
// `avsm::iterations_per_segment`.
const ITERATIONS_PER_SEGMENT: u32 = 2u * (2u * CHORD_PIECES + 2u);

fn segments_per_round() -> u32 {
    return max(1u, capture.loop_budget / ITERATIONS_PER_SEGMENT);
}

@compute @workgroup_size(8, 8)
fn compress(@builtin(global_invocation_id) id: vec3<u32>) {
    let index = band_texel(id);
    if index == NO_TEXEL {
        return;
    }
    let list = texel_list(index);
    let limit = deep.nodes_per_texel;
    let out = index * limit;
    // This round's segments [begin, end); between rounds the curve (at most `limit` nodes once
    // a segment's removals are done) waits in the texel's capture nodes, which avsm does not
    // otherwise read: its count at nodes[2·first].x, its nodes after it (a list that needs more
    // than one round has 2n > limit + 1 slots).
    let per_round = segments_per_round();
    let begin = pass_round.index * per_round;
    if begin >= max(list.count, 1u) {
        return;
    }
    let end = min(list.count, begin + per_round);
    let scratch = 2u * list.first;
    var curve: Curve;
    curve.count = 0u;
    if begin > 0u {
        curve.count = u32(nodes[scratch].x);
        #unroll k 0..CURVE_NODES
            if k < curve.count {
                let node = nodes[scratch + 1u + k];
                curve.z[k] = node.x;
                curve.t[k] = node.y;
            }
        #end_unroll
    }
    for (var i = begin; i < end; i++) {
        insert_segment(&curve, segment_at(list.first + i));
        while curve.count > limit {
            remove_least_area(&curve);
        }
    }
    if end < list.count {
        nodes[scratch] = vec2<f32>(f32(curve.count), 0.0);
        #unroll k 0..CURVE_NODES
            if k < curve.count {
                nodes[scratch + 1u + k] = vec2<f32>(curve.z[k], curve.t[k]);
            }
        #end_unroll
        return;
    }
    if curve.count == 0u {
        // No smoke on this ray: T = 1 at every depth.
        for (var k = 0u; k < limit; k++) {
            out_nodes[out + k] = vec2<f32>(0.0, 1.0);
        }
        return;
    }
    // The nodes, the last repeated into the free slots.
    var last = vec2<f32>(0.0);
    #unroll k 0..CURVE_NODES
        if k < curve.count {
            last = vec2<f32>(curve.z[k], curve.t[k]);
        }
        if k < limit {
            out_nodes[out + k] = last;
        }
    #end_unroll
}
