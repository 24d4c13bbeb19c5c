// `volume` lookup: secondary ray marching through the extinction grid (dissertation 000, chapter
// 3.2.3; src/shadow/volume.rs). The segment from p to the light is clipped to the grid's box (the
// smoke's bounds and an empty voxel each side) and marched in K equal steps, sampling the mean
// extinction trilinearly at each step's midpoint: T = exp(-Σ σ_i Δs). Beyond the box there is no
// smoke, so the march starts and ends there; a point outside the box on the far side marches
// through it all. Keep `VolumeParams` in sync with src/shadow/volume.rs.
#import common/frame.wgsl

struct VolumeParams {
    // The grid's corner (m) and K, the samples of a march.
    origin: vec3<f32>,
    steps: u32,
    // The grid's size (m); occupied = 0 when there is no smoke (T = 1).
    extent: vec3<f32>,
    occupied: u32,
};

@group(1) @binding(0) var<uniform> volume: VolumeParams;
@group(1) @binding(1) var volume_sampler: sampler;
// Mean extinction per voxel (1/m), R16Float.
@group(1) @binding(2) var volume_grid: texture_3d<f32>;

// Optical depth from p to the light through the grid.
fn volume_optical_depth(p: vec3<f32>) -> f32 {
    let to_light = frame.light_pos.xyz - p;
    let length_m = length(to_light);
    if volume.occupied == 0u || length_m <= 0.0 {
        return 0.0;
    }
    let dir = to_light / length_m;
    // The slab test; an axis the ray runs parallel to gets a huge finite inverse (its slab then
    // holds the ray entirely or not at all).
    let tiny = abs(dir) < vec3<f32>(1e-12);
    let inv = 1.0 / select(dir, vec3<f32>(1e-12), tiny);
    let a = (volume.origin - p) * inv;
    let b = (volume.origin + volume.extent - p) * inv;
    let near = min(a, b);
    let far = max(a, b);
    let t0 = max(max(max(near.x, near.y), near.z), 0.0);
    let t1 = min(min(min(far.x, far.y), far.z), length_m);
    if t1 <= t0 {
        return 0.0;
    }
    let step_m = (t1 - t0) / f32(volume.steps);
    let start = (p + dir * (t0 + 0.5 * step_m) - volume.origin) / volume.extent;
    let stride = dir * step_m / volume.extent;
    var sum = 0.0;
    for (var i = 0u; i < volume.steps; i++) {
        sum += textureSampleLevel(volume_grid, volume_sampler, start + stride * f32(i), 0.0).r;
    }
    return sum * step_m;
}

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    return exp(-volume_optical_depth(p));
}
