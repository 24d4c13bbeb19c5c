// `has` light pass: a batch of particles drawn from the light adds each light ray's optical
// depth through each particle, τ(1 - d/r)·2w, to the light buffer (additive blending); and the
// composite that puts the eye buffer, built slice by slice, over the opaque frame.
#import shadow/layered_build.wgsl

@fragment
fn fs_light(in: BuildVertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(splat_fragment(in, false).optical_depth);
}

@group(1) @binding(0) var has_eye: texture_2d<f32>;

@vertex
fn vs_composite(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    // One triangle covering the screen.
    let uv = vec2<f32>(f32((vi << 1u) & 2u), f32(vi & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

// The eye buffer is premultiplied; the pipeline blends it "over" the frame.
@fragment
fn fs_composite(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    return textureLoad(has_eye, vec2<i32>(pos.xy), 0);
}
