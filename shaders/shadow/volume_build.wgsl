// `volume` build: the particles' extinction voxelised into a world-space grid (src/shadow/volume.rs).
// 1. scatter: one invocation per (particle, voxel row) pair of the slab's candidate jobs (the
//    CPU sorted the particles' boxes by their first z-slice and numbered their rows with a
//    prefix sum, so that the jobs that can reach a slab are one run of them). It finds its
//    particle by binary search, skips a row that misses the sphere or the slab, and adds to each
//    voxel of the row that the sphere reaches the particle's extinction at the voxel
//    (`radial_extinction`, below), from VOLUME_SUBSAMPLES³ points at the centres of its
//    sub-cells (one: its centre), in fixed point (atomicAdd: integer sums do not depend on the order, so the grid
//    is the same at any slab depth). Only the z-slices of this slab are written.
// 2. convert: the slab's sums as half floats, two voxels a word, rows padded for the copy into
//    the 3D texture.
// Loops per invocation: the search (among the jobs of the row's block of VOLUME_ROWS_PER_BLOCK
// rows: at most 9 steps) and at most G <= 1023 voxels
// of VOLUME_SUBSAMPLES³ sub-samples (1): within llvmpipe's 65,535 iterations. Keep `VolumeBuild` and `VolumeJob` in
// sync with src/shadow/volume.rs.

#import common/medium.wgsl

struct VolumeBuild {
    // The grid's corner (m) and voxels per side.
    origin: vec3<f32>,
    side: u32,
    // One voxel's size per axis (m), and the end of this slab's (particle, row) pairs.
    voxel_size: vec3<f32>,
    row_end: u32,
    // This slab's first z-slice and its slices; staging words per row; the first of the
    // (particle, row) pairs this slab's scatter runs over (the rows of the jobs, sorted by their
    // first z-slice, that can reach the slab: the others' never do).
    slab_z0: u32,
    slab_depth: u32,
    words_per_row: u32,
    row_first: u32,
    // The light (m), for the light-aligned field; fixed-point units per 1/m of extinction.
    light_pos: vec3<f32>,
    units_per_extinction: f32,
    // The run of jobs that can reach this slab, for the scatter by job (`scatter_*_jobs`).
    job_first: u32,
    job_end: u32,
    _pad1: u32,
    _pad2: u32,
};

struct VolumeJob {
    // The sphere: centre (m), radius (m), extinction τ (1/m).
    center: vec3<f32>,
    radius: f32,
    tau: f32,
    // Its first row in the frame's numbering.
    row_start: u32,
    // Its box of voxels: first voxel and voxels per axis, x | y << 10 | z << 20.
    lo: u32,
    size: u32,
};

// Sub-samples per axis of a voxel's value (keep in sync with SUBSAMPLES_PER_AXIS): 1, the
// voxel's centre, a point sample as every map's texel is (one filtering policy: none).
const VOLUME_SUBSAMPLES: u32 = 1u;
// The largest half float: a mean beyond it is clamped (T = 0 within a millimetre anyway).
const VOLUME_HALF_MAX: f32 = 65504.0;

// The particle model's extinction as a field in space, per unit τ, at (distance / radius)² = ρ²:
// f = 1 - (4 E(m) - 2 K(m)) / π with m = 1 - ρ² (0 from the surface out), the inverse Abel
// transform of the model's optical depth along a line at distance d, 2 (1 - d/r) sqrt(r² - d²),
// so that every line through the sphere integrates it to exactly that. K and E are Abramowitz &
// Stegun 17.3.34 and 17.3.36 (|error| <= 2e-8) in m1 = 1 - m = ρ², which carry the centre's
// logarithm explicitly; 4E - 2K is combined here into c(m1) - e(m1) ln m1. The CPU mirror is
// `radial_extinction` in src/shadow/volume.rs.
fn radial_extinction(rho2: f32) -> f32 {
    let m1 = clamp(rho2, 1e-12, 1.0);
    let c = 1.22741127776 + m1 * (1.57967877334 + m1 * (0.17862220114 + m1 * (0.11544406758
        + m1 * 0.0404363338)));
    let e = -1.0 + m1 * (0.74996286046 + m1 * (0.23040222996 + m1 * (0.09622079412
        + m1 * 0.01222224532)));
    return max(1.0 - (c - e * log2(m1) * 0.69314718056) * 0.31830988618, 0.0);
}

// The particle model's extinction per unit τ at `at` along the light's ray through it:
// 1 - d/r, d the distance from the centre to that ray (common/particle.wgsl's chord_extinction).
// Constant along each chord, so every partial chord matches the model too; it depends on the
// light.
fn light_ray_extinction(at: vec3<f32>, job: VolumeJob) -> f32 {
    let ray = at - build.light_pos;
    let to_center = job.center - build.light_pos;
    let along = dot(to_center, ray) / max(dot(ray, ray), 1e-20);
    let d = length(to_center - ray * along);
    return max(1.0 - d / job.radius, 0.0);
}

@group(1) @binding(0) var<uniform> build: VolumeBuild;
@group(1) @binding(1) var<storage, read> jobs: array<VolumeJob>;
@group(1) @binding(2) var<storage, read_write> scratch: array<atomic<u32>>;
@group(1) @binding(3) var<storage, read_write> staging: array<u32>;
// For each block of VOLUME_ROWS_PER_BLOCK rows the job of its first row, then the last job
// (src/shadow/volume.rs, `VoxelPlan::row_blocks`; keep in sync with ROWS_PER_BLOCK there).
const VOLUME_ROWS_PER_BLOCK: u32 = 256u;
@group(1) @binding(4) var<storage, read> row_blocks: array<u32>;

fn unpack3(v: u32) -> vec3<u32> {
    return vec3<u32>(v & 1023u, (v >> 10u) & 1023u, v >> 20u);
}

// The last job whose first row is at or before `row` (row_start rises strictly: every box has
// at least one row), searched among the jobs of the row's block: from the job of the block's
// first row to that of the next block's (the last job after the last block), both included.
fn job_of(row: u32) -> u32 {
    let block = row / VOLUME_ROWS_PER_BLOCK;
    var lo = row_blocks[block];
    var hi = row_blocks[block + 1u] + 1u;
    while hi - lo > 1u {
        let mid = (lo + hi) / 2u;
        if jobs[mid].row_start <= row {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

// One (particle, voxel row) pair of the scatter by row: the `index`th row of the slab's run,
// through the light-aligned field or the light-independent one. Two entry points call it with a
// constant `aligned`, so each compiles only its own field: llvmpipe runs both sides of a branch
// under a mask, even a uniform one.
fn scatter_row(index: u32, aligned: bool) {
    let row = build.row_first + index;
    if row >= build.row_end {
        return;
    }
    let job = jobs[job_of(row)];
    let first = unpack3(job.lo);
    let size = unpack3(job.size);
    let local = row - job.row_start;
    let y = first.y + local % size.y;
    let z = first.z + local / size.y;
    if z < build.slab_z0 || z >= build.slab_z0 + build.slab_depth {
        return;
    }
    scatter_voxel_row(job, y, z, aligned);
}

// The scatter by job, for thin slabs (where most of a run's rows lie outside the slab): job
// `job_first + j`'s `r`th row within the slab, rows z-major as in the frame's numbering. No
// search, and no invocation for a row of the job outside the slab.
fn scatter_job_row(j: u32, r: u32, aligned: bool) {
    let index = build.job_first + j;
    if index >= build.job_end {
        return;
    }
    let job = jobs[index];
    let first = unpack3(job.lo);
    let size = unpack3(job.size);
    let z_lo = max(first.z, build.slab_z0);
    let z_end = min(first.z + size.z, build.slab_z0 + build.slab_depth);
    if z_end <= z_lo || r >= (z_end - z_lo) * size.y {
        return;
    }
    scatter_voxel_row(job, first.y + r % size.y, z_lo + r / size.y, aligned);
}

// What one job adds to the voxels of its row (y, z) of this slab.
fn scatter_voxel_row(job: VolumeJob, y: u32, z: u32, aligned: bool) {
    let first = unpack3(job.lo);
    let size = unpack3(job.size);
    // The row's voxels span a rectangle in (y, z): skip the row when it lies beyond the radius,
    // and walk x only where the sphere's cross-section at the rectangle's nearest point reaches.
    let h = build.voxel_size;
    let cell_lo = build.origin.yz + vec2<f32>(f32(y), f32(z)) * h.yz;
    let off = job.center.yz - clamp(job.center.yz, cell_lo, cell_lo + h.yz);
    let r2 = job.radius * job.radius;
    let rest = r2 - dot(off, off);
    if rest <= 0.0 {
        return;
    }
    let half_width = sqrt(rest);
    let x_lo = i32(first.x);
    let x_hi = i32(first.x + size.x) - 1;
    let x_first = max(i32(floor((job.center.x - half_width - build.origin.x) / h.x)), x_lo);
    let x_last = min(i32(floor((job.center.x + half_width - build.origin.x) / h.x)), x_hi);
    let base = ((z - build.slab_z0) * build.side + y) * build.side;
    let n = f32(VOLUME_SUBSAMPLES);
    let inv_r2 = 1.0 / r2;
    for (var x = x_first; x <= x_last; x++) {
        let corner = build.origin + vec3<f32>(f32(x), f32(y), f32(z)) * h;
        var sum = 0.0;
        for (var s = 0u; s < VOLUME_SUBSAMPLES * VOLUME_SUBSAMPLES * VOLUME_SUBSAMPLES; s++) {
            let cell = vec3<u32>(
                s % VOLUME_SUBSAMPLES,
                (s / VOLUME_SUBSAMPLES) % VOLUME_SUBSAMPLES,
                s / (VOLUME_SUBSAMPLES * VOLUME_SUBSAMPLES),
            );
            let at = corner + (vec3<f32>(cell) + 0.5) / n * h;
            let to_center = at - job.center;
            let rho2 = dot(to_center, to_center) * inv_r2;
            if aligned {
                sum += select(0.0, light_ray_extinction(at, job), rho2 < 1.0);
            } else {
                // 0 from the surface out.
                sum += radial_extinction(rho2);
            }
        }
        let mean = min(job.tau * sum / (n * n * n), VOLUME_HALF_MAX);
        let units = u32(round(mean * build.units_per_extinction));
        if units > 0u {
            atomicAdd(&scratch[base + u32(x)], units);
        }
    }
}

@compute @workgroup_size(64)
fn scatter_radial(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    scatter_row((group.y * groups.x + group.x) * 64u + lane, false);
}

@compute @workgroup_size(64)
fn scatter_light_aligned(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    scatter_row((group.y * groups.x + group.x) * 64u + lane, true);
}

// By job: x (and its 64 lanes) the row within the job's part of the slab, y and z the job.
@compute @workgroup_size(64)
fn scatter_radial_jobs(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    scatter_job_row(group.z * 65535u + group.y, group.x * 64u + lane, false);
}

@compute @workgroup_size(64)
fn scatter_light_aligned_jobs(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    scatter_job_row(group.z * 65535u + group.y, group.x * 64u + lane, true);
}

// The scene's density volume's extinction at voxel `v` of this slab (group 0's grid,
// shaders/common/medium.wgsl), from the same VOLUME_SUBSAMPLES³ points as the particles'.
fn density_volume_mean(v: vec3<u32>) -> f32 {
    if !medium_present() {
        return 0.0;
    }
    let corner = build.origin + vec3<f32>(v + vec3<u32>(0u, 0u, build.slab_z0)) * build.voxel_size;
    let n = VOLUME_SUBSAMPLES;
    var sum = 0.0;
    for (var s = 0u; s < n * n * n; s++) {
        let f = (vec3<f32>(vec3<u32>(s % n, (s / n) % n, s / (n * n))) + 0.5) / f32(n);
        let q = (grid_params().index_from_world * vec4<f32>(corner + f * build.voxel_size, 1.0)).xyz;
        sum += grid_density_at_index(q);
    }
    return grid_params().density_scale_per_m * sum / f32(n * n * n);
}

// Voxel `v` of this slab (flat `index`): the particles' sum, and with `medium` the density
// volume's mean.
fn extinction(index: u32, v: vec3<u32>, medium: bool) -> f32 {
    let particles = f32(atomicLoad(&scratch[index])) / build.units_per_extinction;
    if medium {
        return min(particles + density_volume_mean(v), VOLUME_HALF_MAX);
    }
    return min(particles, VOLUME_HALF_MAX);
}

// The binary16 bits of v in [0, 65504], rounded to nearest, ties to even (WGSL's pack2x16float
// needs a capability some adapters lack). The particles' sums are at least one fixed-point unit,
// 2^-14 (1/m), binary16's smallest normal; a density volume's thin edges go below it, into
// binary16's subnormals (multiples of 2^-24, rounded to nearest; 1024 of them is 2^-14 again).
fn half_bits(v: f32) -> u32 {
    let bits = bitcast<u32>(v);
    let exponent = i32((bits >> 23u) & 0xffu) - 127 + 15;
    if exponent <= 0 {
        return u32(v * 16777216.0 + 0.5);
    }
    let mantissa = bits & 0x7fffffu;
    var half = (u32(exponent) << 10u) | (mantissa >> 13u);
    let rest = mantissa & 0x1fffu;
    if rest > 0x1000u || (rest == 0x1000u && (half & 1u) == 1u) {
        half += 1u;
    }
    return min(half, 0x7bffu);
}

// One staging word: voxels (2 id.x, id.y, id.z) and the next in x. Two entry points call it with
// a constant `medium` (the scene's density volume, or none), so that a scene without one does
// not pay for its sampling: llvmpipe runs both sides of a branch under a mask, even a uniform
// one, and sampling no volume under a mask took 75 ms of a 311 ms build at 185³.
fn convert_word(id: vec3<u32>, medium: bool) {
    let words = (build.side + 1u) / 2u;
    if id.x >= words || id.y >= build.side || id.z >= build.slab_depth {
        return;
    }
    let x = id.x * 2u;
    let base = (id.z * build.side + id.y) * build.side;
    var word = half_bits(extinction(base + x, vec3<u32>(x, id.y, id.z), medium));
    if x + 1u < build.side {
        word |= half_bits(extinction(base + x + 1u, vec3<u32>(x + 1u, id.y, id.z), medium)) << 16u;
    }
    staging[(id.z * build.side + id.y) * build.words_per_row + id.x] = word;
}

@compute @workgroup_size(8, 8, 1)
fn convert(@builtin(global_invocation_id) id: vec3<u32>) {
    convert_word(id, false);
}

@compute @workgroup_size(8, 8, 1)
fn convert_with_medium(@builtin(global_invocation_id) id: vec3<u32>) {
    convert_word(id, true);
}
