// A dense density grid (src/medium/gpu_grid.rs): OpenVDB's conventions, as the f64 mirror in
// src/medium/grid.rs: voxel (i, j, k)'s density at its centre, at integer index coordinates,
// trilinear between centres, zero outside the voxels and their half-voxel ramp.
// The importer declares `grid_density` (texture_3d<f32>, R32Float, read with textureLoad: exact
// texel values, no filtering hardware) and `fn grid_params() -> GridParams` (the probes: their
// own uniform; the frame: `frame.grid`, shaders/common/frame.wgsl).

// Keep in sync with `GridParams` in src/medium/gpu_grid.rs.
struct GridParams {
    index_from_world: mat4x4<f32>,
    // Voxels along x, y, z (w unused); zero for an empty grid.
    dims: vec4<u32>,
    // Extinction per unit of density, 1/m.
    density_scale_per_m: f32,
    // The frame's marches (src/medium/frame.rs; the probes leave them 0): the eye's steps,
    // where in its step each eye sample lies (0.5 ± jitter/2 by a per-pixel hash), and the
    // reference's steps towards the light.
    eye_steps: u32,
    jitter: f32,
    reference_steps: u32,
    // rgb: single-scattering albedo; w: the powder term's weight (0 off).
    albedo_powder: vec4<f32>,
    // Steps of the techniques' light-space build along each texel's ray.
    build_steps: u32,
    // A homogeneous shape in index space (src/medium/grid.rs, IndexShape): 0 none (the
    // voxels), 1 an ellipsoid (shape_a.xyz its centre, shape_b.xyz its radii), 2 a box
    // (shape_a.xyz to shape_b.xyz); shape_a.w its density.
    shape_kind: u32,
    _pad1: u32,
    _pad2: u32,
    shape_a: vec4<f32>,
    shape_b: vec4<f32>,
};

fn grid_voxel(i: vec3<i32>) -> f32 {
    let d = vec3<i32>(grid_params().dims.xyz);
    if any(i < vec3<i32>(0)) || any(i >= d) {
        return 0.0;
    }
    return textureLoad(grid_density, i, 0).r;
}

// Whether index point `q` is inside the grid's shape.
fn grid_shape_contains(q: vec3<f32>) -> bool {
    let g = grid_params();
    if g.shape_kind == 1u {
        let u = (q - g.shape_a.xyz) / g.shape_b.xyz;
        return dot(u, u) <= 1.0;
    }
    return all(q >= g.shape_a.xyz) && all(q <= g.shape_b.xyz);
}

// The density at index coordinates `q`: the grid's shape's, else trilinear between voxel
// centres.
fn grid_density_at_index(q: vec3<f32>) -> f32 {
    if grid_params().shape_kind != 0u {
        return select(0.0, grid_params().shape_a.w, grid_shape_contains(q));
    }
    let base = floor(q);
    let f = q - base;
    let i = vec3<i32>(base);
    let x00 = mix(grid_voxel(i), grid_voxel(i + vec3<i32>(1, 0, 0)), f.x);
    let x10 = mix(grid_voxel(i + vec3<i32>(0, 1, 0)), grid_voxel(i + vec3<i32>(1, 1, 0)), f.x);
    let x01 = mix(grid_voxel(i + vec3<i32>(0, 0, 1)), grid_voxel(i + vec3<i32>(1, 0, 1)), f.x);
    let x11 = mix(grid_voxel(i + vec3<i32>(0, 1, 1)), grid_voxel(i + vec3<i32>(1, 1, 1)), f.x);
    return mix(mix(x00, x10, f.y), mix(x01, x11, f.y), f.z);
}

// The part [t0, t1] of qa + t (qb - qa), t in [0, 1], where the density can be non-zero (the
// voxels' box widened by the trilinear ramp's voxel); t0 >= t1 when there is none.
fn grid_support(qa: vec3<f32>, qb: vec3<f32>) -> vec2<f32> {
    let lo = vec3<f32>(-1.0);
    let hi = vec3<f32>(grid_params().dims.xyz);
    let d = qb - qa;
    var t0 = 0.0;
    var t1 = 1.0;
    // The axes written out (`#unroll`), not looped over: llvmpipe counts a loop's iterations
    // (its exit's too) against its budget for the whole invocation, and this one cost every
    // march 4 of them that the callers' bounds did not count.
    #unroll axis 0..3
        if d[axis] == 0.0 {
            if qa[axis] <= lo[axis] || qa[axis] >= hi[axis] {
                return vec2<f32>(1.0, 0.0);
            }
        } else {
            let u = (lo[axis] - qa[axis]) / d[axis];
            let v = (hi[axis] - qa[axis]) / d[axis];
            t0 = max(t0, min(u, v));
            t1 = min(t1, max(u, v));
        }
    #end_unroll
    return vec2<f32>(t0, t1);
}

// The fraction of the segment qa..qb (index space) inside the grid's shape, 0..1 (the chord of
// the unit sphere after dividing by the radii, or the box's slabs).
fn grid_shape_fraction(qa: vec3<f32>, qb: vec3<f32>) -> f32 {
    let g = grid_params();
    var t0 = 0.0;
    var t1 = 1.0;
    if g.shape_kind == 1u {
        let o = (qa - g.shape_a.xyz) / g.shape_b.xyz;
        let d = (qb - qa) / g.shape_b.xyz;
        let a = dot(d, d);
        if a == 0.0 {
            return 0.0;
        }
        let b = dot(o, d);
        let disc = b * b - a * (dot(o, o) - 1.0);
        if disc <= 0.0 {
            return 0.0;
        }
        let root = sqrt(disc);
        t0 = max(t0, (-b - root) / a);
        t1 = min(t1, (-b + root) / a);
    } else {
        let d = qb - qa;
        // Written out, as in `grid_support`.
        #unroll axis 0..3
            if d[axis] == 0.0 {
                if qa[axis] < g.shape_a[axis] || qa[axis] > g.shape_b[axis] {
                    return 0.0;
                }
            } else {
                let u = (g.shape_a[axis] - qa[axis]) / d[axis];
                let v = (g.shape_b[axis] - qa[axis]) / d[axis];
                t0 = max(t0, min(u, v));
                t1 = min(t1, max(u, v));
            }
        #end_unroll
    }
    return max(t1 - t0, 0.0);
}

// Optical depth from world point `a` to `b` by the midpoint rule with `steps` steps over the
// part of the segment where the density can be non-zero (`steps` + 3 loop iterations: the
// caller keeps it within the adapter's loop budget).
fn grid_optical_depth(a: vec3<f32>, b: vec3<f32>, steps: u32) -> f32 {
    let qa = (grid_params().index_from_world * vec4<f32>(a, 1.0)).xyz;
    let qb = (grid_params().index_from_world * vec4<f32>(b, 1.0)).xyz;
    let s = grid_support(qa, qb);
    if s.x >= s.y || steps == 0u {
        return 0.0;
    }
    let dt = (s.y - s.x) / f32(steps);
    var sum = 0.0;
    for (var i = 0u; i < steps; i++) {
        sum += grid_density_at_index(mix(qa, qb, s.x + (f32(i) + 0.5) * dt));
    }
    return grid_params().density_scale_per_m * sum * dt * length(b - a);
}

// Optical depth from world point `a` to `b` as the reference takes it: a shape's in closed form
// (its density times the chord inside it), a grid's by `steps` midpoint steps.
fn grid_reference_optical_depth(a: vec3<f32>, b: vec3<f32>, steps: u32) -> f32 {
    let g = grid_params();
    if g.shape_kind == 0u {
        return grid_optical_depth(a, b, steps);
    }
    let qa = (g.index_from_world * vec4<f32>(a, 1.0)).xyz;
    let qb = (g.index_from_world * vec4<f32>(b, 1.0)).xyz;
    return g.density_scale_per_m * g.shape_a.w * grid_shape_fraction(qa, qb) * length(b - a);
}
