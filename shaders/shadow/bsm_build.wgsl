// `bsm` build: each light-space particle fragment writes where its ray enters the particle
// sphere (MIN-blended: the front of the smoke), where it leaves it (MAX-blended: the back) and
// the chord's optical depth (added: the whole ray's optical depth).
#import shadow/layered_build.wgsl

struct BsmTargets {
    @location(0) front: vec4<f32>,
    @location(1) back: vec4<f32>,
    @location(2) optical_depth: vec4<f32>,
};

@fragment
fn fs_build(in: BuildVertexOut) -> BsmTargets {
    let s = splat_fragment(in, true);
    var out: BsmTargets;
    out.front = vec4<f32>(s.z0);
    out.back = vec4<f32>(s.z1);
    out.optical_depth = vec4<f32>(s.optical_depth);
    return out;
}

// The volume's: the first step with density, the last one's far end and the optical depth of
// the whole ray (shaders/shadow/volume_splat.wgsl).
@fragment
fn fs_build_volume(in: VolumeVertexOut) -> BsmTargets {
    let extent = volume_extent(volume_light_ray(in.ndc));
    if extent.optical_depth <= 0.0 {
        discard;
    }
    var out: BsmTargets;
    out.front = vec4<f32>(extent.front);
    out.back = vec4<f32>(extent.back);
    out.optical_depth = vec4<f32>(extent.optical_depth);
    return out;
}
