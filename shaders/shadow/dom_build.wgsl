// `dom` build: two passes. `fs_depth` writes each fragment's start depth into the depth channel
// with MIN blending (the chord's entry for segment splats, the centre for point splats), so each
// texel ends up with the depth where its smoke starts. The layer pass then adds each fragment's
// optical depth to every boundary z0 + offset(k) at or beyond it, reading z0 at its own texel.
#import shadow/layered_build.wgsl
#import shadow/dom.wgsl

@fragment
fn fs_depth(in: BuildVertexOut) -> @location(0) vec4<f32> {
    let splat = splat_fragment(in, layered.splat == 1u);
    return vec4<f32>(splat.z0);
}

// Values for layer target `index`: boundaries k = 4·index + 1 ..= 4·index + 4.
fn target_values(splat: Splat, index: u32, pixel: vec2<f32>) -> vec4<f32> {
    let z0 = textureLoad(dom_depth, vec2<i32>(pixel), 0).r;
    let k = vec4<f32>(f32(index * 4u + 1u)) + vec4<f32>(0.0, 1.0, 2.0, 3.0);
    let boundary = vec4<f32>(z0) + vec4<f32>(dom_offset(k.x), dom_offset(k.y), dom_offset(k.z), dom_offset(k.w));
    return splat.optical_depth * covered_fraction(splat, boundary) * step(k, vec4<f32>(f32(layered.count)));
}

//{{BUILD_OUTPUTS}}
