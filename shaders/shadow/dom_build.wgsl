// `dom` build: two passes. `fs_depth` writes each fragment's chord entry into the depth channel
// with MIN blending, so each texel ends up with the depth where its smoke starts: the front
// surface of the first particle sphere along its ray (of the first enlarged sphere, with
// `dom_start_dilation` > 1), whatever the splat mode (a point splat still places the optical
// depth at the centres, behind that). The layer pass then adds each fragment's
// optical depth to every boundary z0 + offset(k) at or beyond it, reading z0 at its own texel.
#import shadow/layered_build.wgsl
#import shadow/dom.wgsl

// The start-depth pass draws each particle's sphere enlarged by `dom_start_dilation` (1: the
// sphere itself): the MIN of the enlarged spheres' entries is a smoother proxy of the smoke's
// front that starts at or before it wherever there is smoke.
@vertex
fn vs_depth(
    @builtin(vertex_index) vi: u32,
    @builtin(instance_index) instance: u32,
    particle: ParticleIn,
) -> BuildVertexOut {
    return build_vertex(vi, instance, particle, particle.center_radius.w * layered.dom_start_dilation);
}

@fragment
fn fs_depth(in: BuildVertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(splat_fragment(in, true).z0);
}

// The volume's start depth: its first step with density (shaders/shadow/volume_splat.wgsl).
@fragment
fn fs_depth_volume(in: VolumeVertexOut) -> @location(0) vec4<f32> {
    let extent = volume_extent(volume_light_ray(in.ndc));
    if extent.optical_depth <= 0.0 {
        discard;
    }
    return vec4<f32>(extent.front);
}

// Values for layer target `index`: boundaries k = 4·index + 1 ..= 4·index + 4.
// The fragment's splat and its texel's layer geometry (read once, used by every target).
struct Prepared {
    splat: Splat,
    z0: f32,
    thickness: f32,
};

fn prepare_values(splat: Splat, pixel: vec2<f32>) -> Prepared {
    let z0 = textureLoad(dom_depth, vec2<i32>(pixel), 0).r;
    return Prepared(splat, z0, dom_thickness(z0));
}

fn target_values(p: Prepared, index: u32) -> vec4<f32> {
    let k = vec4<f32>(f32(index * 4u + 1u)) + vec4<f32>(0.0, 1.0, 2.0, 3.0);
    let th = p.thickness;
    let boundary = vec4<f32>(p.z0) + vec4<f32>(dom_offset(k.x, th), dom_offset(k.y, th), dom_offset(k.z, th), dom_offset(k.w, th));
    return p.splat.optical_depth * covered_fraction(p.splat, boundary) * step(k, vec4<f32>(f32(layered.count)));
}

//{{BUILD_OUTPUTS}}
