// `avsm` build: adaptive volumetric shadow maps (Salvi, Vidimče, Lauritzen & Lefohn 2010) as a
// resolve over the deep capture (shaders/shadow/deep_capture.wgsl). WebGPU has no fragment
// shader interlock, so instead of inserting fragments as they are rasterised, one invocation per
// texel inserts its captured segments in the order the capture's resolve left them: by draw
// index (`avsm_insert = draw`, the paper's streaming insertion, serialised in primitive order as
// an interlock would) or by (z0, z1, optical depth) (`sorted`, independent of the draw order).
// A segment adds an entry node at z0 (T of the curve there) and an exit node at z1; T is linear
// inside it, so the nodes behind its entry are multiplied by its ramp, 1 at z0 to
// e^-optical_depth at z1 and beyond. While the curve has more than N = deep.nodes_per_texel
// nodes, the interior node whose removal loses the least area under it (the triangle with its
// neighbours) goes; the first and last nodes stay.
// Keep `DeepParams` in sync with src/shadow/deep_nodes.rs. The CPU mirror is
// src/shadow/deep_compress.rs.
#import shadow/deep_capture_lists.wgsl
#import shadow/deep_params.wgsl

@group(2) @binding(0) var<uniform> deep: DeepParams;
@group(2) @binding(1) var<storage, read_write> out_nodes: array<vec2<f32>>;

// N <= MAX_CHANNELS / 2 = 16 nodes, plus the two one segment inserts before compressing.
const MAX_NODES: u32 = 18u;

// One texel's transmittance curve while it is built: nodes (z[k], t[k]) sorted by z.
struct Curve {
    z: array<f32, MAX_NODES>,
    t: array<f32, MAX_NODES>,
    count: u32,
};

// T of the curve at z: 1 in front of the first node, the last node's T behind the last, linear
// between.
fn curve_at(c: ptr<function, Curve>, z: f32) -> f32 {
    let n = (*c).count;
    if n == 0u || z <= (*c).z[0] {
        return 1.0;
    }
    if z >= (*c).z[n - 1u] {
        return (*c).t[n - 1u];
    }
    var k = 1u;
    while (*c).z[k] <= z {
        k++;
    }
    let z0 = (*c).z[k - 1u];
    let z1 = (*c).z[k];
    return mix((*c).t[k - 1u], (*c).t[k], clamp((z - z0) / max(z1 - z0, 1e-12), 0.0, 1.0));
}

// Inserts node (z, t) after every node at depth <= z.
fn insert_node(c: ptr<function, Curve>, z: f32, t: f32) {
    var k = (*c).count;
    while k > 0u && (*c).z[k - 1u] > z {
        (*c).z[k] = (*c).z[k - 1u];
        (*c).t[k] = (*c).t[k - 1u];
        k--;
    }
    (*c).z[k] = z;
    (*c).t[k] = t;
    (*c).count++;
}

fn insert_segment(c: ptr<function, Curve>, s: Segment) {
    let t_exit = exp(-s.optical_depth);
    let t_entry = curve_at(c, s.z0);
    let t_behind = curve_at(c, s.z1) * t_exit;
    let width = max(s.z1 - s.z0, 1e-12);
    for (var k = 0u; k < (*c).count; k++) {
        let z = (*c).z[k];
        if z > s.z0 {
            (*c).t[k] *= mix(1.0, t_exit, min((z - s.z0) / width, 1.0));
        }
    }
    insert_node(c, s.z0, t_entry);
    insert_node(c, s.z1, t_behind);
}

// Removes the interior node whose removal changes the area under the curve least (the first of
// equals).
fn remove_least_area(c: ptr<function, Curve>) {
    let n = (*c).count;
    var best = 1u;
    var best_area = 3.0e38;
    for (var k = 1u; k + 1u < n; k++) {
        let za = (*c).z[k - 1u];
        let ta = (*c).t[k - 1u];
        let area = abs(((*c).z[k] - za) * ((*c).t[k + 1u] - ta) - ((*c).z[k + 1u] - za) * ((*c).t[k] - ta));
        if area < best_area {
            best_area = area;
            best = k;
        }
    }
    for (var k = best; k + 1u < n; k++) {
        (*c).z[k] = (*c).z[k + 1u];
        (*c).t[k] = (*c).t[k + 1u];
    }
    (*c).count = n - 1u;
}

// Segments inserted per round (see src/shadow/deep_capture.rs): one insertion and the removals
// after it loop about 160 times (curve_at twice, the ramp, two insert_node and two
// remove_least_area, each over at most MAX_NODES nodes). Keep in sync with `avsm::rounds`.
const ITERATIONS_PER_SEGMENT: u32 = 200u;

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
        for (var k = 0u; k < curve.count; k++) {
            let node = nodes[scratch + 1u + k];
            curve.z[k] = node.x;
            curve.t[k] = node.y;
        }
    }
    for (var i = begin; i < end; i++) {
        insert_segment(&curve, segments[list.first + i]);
        while curve.count > limit {
            remove_least_area(&curve);
        }
    }
    if end < list.count {
        nodes[scratch] = vec2<f32>(f32(curve.count), 0.0);
        for (var k = 0u; k < curve.count; k++) {
            nodes[scratch + 1u + k] = vec2<f32>(curve.z[k], curve.t[k]);
        }
        return;
    }
    if curve.count == 0u {
        // No smoke on this ray: T = 1 at every depth.
        for (var k = 0u; k < limit; k++) {
            out_nodes[out + k] = vec2<f32>(0.0, 1.0);
        }
        return;
    }
    for (var k = 0u; k < limit; k++) {
        let j = min(k, curve.count - 1u);
        out_nodes[out + k] = vec2<f32>(curve.z[j], curve.t[j]);
    }
}
