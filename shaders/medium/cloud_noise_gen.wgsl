// The cloud noise's generators (src/medium/cloud.rs): the shape and detail textures' texels
// from a seed, written to storage buffers that are then copied into Rgba32Float 3D textures. The
// noise itself is shaders/medium/cloud_noise.wgsl.
#import medium/cloud_noise.wgsl

@group(0) @binding(0) var<uniform> noise: CloudNoiseParams;
@group(0) @binding(1) var<storage, read_write> shape_texels: array<f32>;
@group(0) @binding(2) var<storage, read_write> detail_texels: array<f32>;

// Dispatch (128 / 4)³ = (32, 32, 32) workgroups.
@compute @workgroup_size(4, 4, 4)
fn shape_main(@builtin(global_invocation_id) id: vec3<u32>) {
    if any(id >= vec3<u32>(SHAPE_SIZE)) {
        return;
    }
    let t = shape_texel(noise.seed, id);
    let base = ((id.z * SHAPE_SIZE + id.y) * SHAPE_SIZE + id.x) * FLOATS_PER_TEXEL;
    shape_texels[base] = t.x;
    shape_texels[base + 1u] = t.y;
    shape_texels[base + 2u] = t.z;
    shape_texels[base + 3u] = t.w;
}

// Dispatch (32 / 4)³ = (8, 8, 8) workgroups. The fourth float is 0: there is no three-channel
// 32-bit float texture format to copy into.
@compute @workgroup_size(4, 4, 4)
fn detail_main(@builtin(global_invocation_id) id: vec3<u32>) {
    if any(id >= vec3<u32>(DETAIL_SIZE)) {
        return;
    }
    let t = detail_texel(noise.seed, id);
    let base = ((id.z * DETAIL_SIZE + id.y) * DETAIL_SIZE + id.x) * FLOATS_PER_TEXEL;
    detail_texels[base] = t.x;
    detail_texels[base + 1u] = t.y;
    detail_texels[base + 2u] = t.z;
    detail_texels[base + 3u] = 0.0;
}
