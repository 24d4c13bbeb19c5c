// `esm` build: each light-space particle fragment writes the depth where its ray enters the
// particle sphere; MIN blending leaves each texel the depth where its smoke starts.
#import shadow/layered_build.wgsl

@fragment
fn fs_build(in: BuildVertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(splat_fragment(in, true).z0);
}

// The volume's: its first step with density (shaders/shadow/volume_splat.wgsl).
@fragment
fn fs_build_volume(in: VolumeVertexOut) -> @location(0) vec4<f32> {
    let extent = volume_extent(volume_light_ray(in.ndc));
    if extent.optical_depth <= 0.0 {
        discard;
    }
    return vec4<f32>(extent.front);
}
