// The procedural cloud baked into a density grid (src/medium/cloud.rs, CloudBaker): the
// extinction `cloud_density` gives at each voxel centre of a box over the cloud layer, from the
// shape and detail noise textures read with repeat addressing and trilinear weights computed
// here (Rgba32Float is not filterable everywhere; and so the CPU mirror,
// src/medium/cloud_noise.rs `baked_voxel`, can do the same). The baked grid is the cloud's
// medium for the eye, the reference and every technique's build: one density model for all.
#import medium/cloud_noise.wgsl

// Keep in sync with `BakeParams` in src/medium/cloud.rs.
struct BakeParams {
    // xyz: the world position of voxel (0, 0, 0)'s centre, metres.
    first_voxel_m: vec4<f32>,
    // xyz: a voxel's size along x, y, z, metres.
    voxel_m: vec4<f32>,
    // xyz: voxels along x, y, z; w: the noise's seed (the coverage map's).
    dims: vec4<u32>,
    // xyz: how far the wind has carried the noise and the coverage map, metres (the layer's
    // box stays where it is).
    drift_m: vec4<f32>,
};

@group(0) @binding(0) var<uniform> cloud: CloudParams;
@group(0) @binding(1) var<uniform> bake: BakeParams;
@group(0) @binding(2) var shape_noise: texture_3d<f32>;
@group(0) @binding(3) var detail_noise: texture_3d<f32>;
@group(0) @binding(4) var<storage, read_write> baked: array<f32>;

fn wrap(i: vec3<i32>, size: i32) -> vec3<i32> {
    return ((i % size) + size) % size;
}

// The texture at `uvw` (one period per unit, repeating): texel i holds the noise at i / size,
// trilinear between texels.
fn sample_repeat(tex: texture_3d<f32>, uvw: vec3<f32>, size: u32) -> vec4<f32> {
    let x = uvw * f32(size);
    let base = floor(x);
    let f = x - base;
    let n = i32(size);
    let i = vec3<i32>(base);
    let t000 = textureLoad(tex, wrap(i, n), 0);
    let t100 = textureLoad(tex, wrap(i + vec3<i32>(1, 0, 0), n), 0);
    let t010 = textureLoad(tex, wrap(i + vec3<i32>(0, 1, 0), n), 0);
    let t110 = textureLoad(tex, wrap(i + vec3<i32>(1, 1, 0), n), 0);
    let t001 = textureLoad(tex, wrap(i + vec3<i32>(0, 0, 1), n), 0);
    let t101 = textureLoad(tex, wrap(i + vec3<i32>(1, 0, 1), n), 0);
    let t011 = textureLoad(tex, wrap(i + vec3<i32>(0, 1, 1), n), 0);
    let t111 = textureLoad(tex, wrap(i + vec3<i32>(1, 1, 1), n), 0);
    let x00 = t000 + (t100 - t000) * f.x;
    let x10 = t010 + (t110 - t010) * f.x;
    let x01 = t001 + (t101 - t001) * f.x;
    let x11 = t011 + (t111 - t011) * f.x;
    let y0 = x00 + (x10 - x00) * f.y;
    let y1 = x01 + (x11 - x01) * f.y;
    return y0 + (y1 - y0) * f.z;
}

// Dispatch ceil(dims / 4) workgroups.
@compute @workgroup_size(4, 4, 4)
fn bake_main(@builtin(global_invocation_id) id: vec3<u32>) {
    if any(id >= bake.dims.xyz) {
        return;
    }
    let p = bake.first_voxel_m.xyz + vec3<f32>(id) * bake.voxel_m.xyz;
    let q = p - bake.drift_m.xyz;
    let shape = sample_repeat(shape_noise, cloud_shape_uvw(q, cloud), SHAPE_SIZE);
    let detail = sample_repeat(detail_noise, cloud_detail_uvw(q, cloud), DETAIL_SIZE).xyz;
    let coverage = cloud_coverage_map(bake.dims.w, cloud_layer_point(q, cloud), cloud);
    let density = cloud_density(cloud_layer_point(p, cloud), shape, detail, coverage, cloud);
    baked[(id.z * bake.dims.y + id.y) * bake.dims.x + id.x] = density;
}
