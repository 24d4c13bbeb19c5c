// Particle pass: billboards sorted back to front, composited with premultiplied "over"
// (thesis Eq. 1.5). `fs_spherical` clips each particle's chord against the opaque depth
// (spherical billboards, thesis 3.2.2.3); `fs_flat` is the plain billboard with a hard depth test.
// The lighting was computed per particle beforehand (render/particle_lighting.wgsl).
#import common/frame.wgsl
#import common/particle.wgsl

// Keep in sync with `ParticleLight` in render/particle_lighting.wgsl.
struct ParticleLight {
    radiance: array<vec4<f32>, 4>,
};

@group(1) @binding(0) var<storage, read> particle_light: array<ParticleLight>;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) @interpolate(flat) center_radius: vec4<f32>,
    // Extinction τ of the particle (1/m).
    @location(2) @interpolate(flat) density: f32,
    // Position in the billboard's [-1, 1]² square.
    @location(3) local: vec2<f32>,
    // Radiance scattered towards the eye at the four lighting points (see vs_main).
    @location(4) @interpolate(flat) radiance_00: vec3<f32>,
    @location(5) @interpolate(flat) radiance_10: vec3<f32>,
    @location(6) @interpolate(flat) radiance_01: vec3<f32>,
    @location(7) @interpolate(flat) radiance_11: vec3<f32>,
};

// Where the four lighting points sit, as a fraction of the radius (as in
// particle_lighting.wgsl): the fragment's position in that 2x2 grid weights their radiance.
const SHADE_OFFSET: f32 = 0.5;

// A particle whose sphere holds the eye, or nearly (within 1% of its radius, where its
// silhouette fills most of the view and the centre quad would need to grow without bound), is
// drawn as a full-screen quad at this normalised depth (just past the near plane at 0).
const EYE_INSIDE_MARGIN: f32 = 1.01;
const EYE_INSIDE_DEPTH: f32 = 1.0e-6;

@vertex
fn vs_main(
    @builtin(vertex_index) vi: u32,
    @builtin(instance_index) instance: u32,
    particle: ParticleIn,
) -> VertexOut {
    var out: VertexOut;
    let center = particle.center_radius.xyz;
    let radius = particle.center_radius.w;
    let eye = frame.camera_pos.xyz;
    let corner = quad_corner(vi);
    if distance(center, eye) < radius * EYE_INSIDE_MARGIN {
        // The eye is inside the sphere (or at its surface): rays leave it in every direction,
        // and many miss a quad through the centre, so the sphere is drawn as the whole screen
        // just past the near plane; each fragment clips its own chord (fs_spherical discards
        // the rays that miss it). Its lighting is the four points' mean (local = 0).
        out.clip = vec4<f32>(corner, EYE_INSIDE_DEPTH, 1.0);
        let world = frame.world_from_clip * out.clip;
        out.world = world.xyz / world.w;
        out.local = vec2<f32>(0.0);
    } else {
        let bb = billboard_frame(center, radius, eye);
        let world = billboard_corner(center, radius, bb, corner);
        out.clip = frame.clip_from_world * vec4<f32>(world, 1.0);
        out.world = world;
        out.local = corner;
    }
    out.center_radius = particle.center_radius;
    out.density = particle.albedo_density.a;
    let light = particle_light[instance];
    out.radiance_00 = light.radiance[0].rgb;
    out.radiance_10 = light.radiance[1].rgb;
    out.radiance_01 = light.radiance[2].rgb;
    out.radiance_11 = light.radiance[3].rgb;
    return out;
}

// The lighting at this fragment: bilinear between the four lighting points.
fn fragment_radiance(in: VertexOut) -> vec3<f32> {
    let grow = length(in.world - in.center_radius.xyz) / max(length(in.local) * in.center_radius.w, 1e-6);
    let t = clamp(in.local * (grow / (2.0 * SHADE_OFFSET)) + vec2<f32>(0.5), vec2<f32>(0.0), vec2<f32>(1.0));
    return mix(mix(in.radiance_00, in.radiance_10, t.x), mix(in.radiance_01, in.radiance_11, t.x), t.y);
}

// Composites one particle over the ray segment [t0, t1] of its chord.
fn shade_segment(in: VertexOut, chord: Chord, t0: f32, t1: f32) -> vec4<f32> {
    let ds = max(t1 - t0, 0.0);
    let sigma = chord_extinction(in.density, chord.d, in.center_radius.w);
    let alpha = 1.0 - exp(-sigma * ds);
    return vec4<f32>(fragment_radiance(in) * alpha, alpha);
}

@group(2) @binding(0) var opaque_depth: texture_depth_2d;

// Distance along the eye ray `dir` to the opaque surface behind pixel `pixel`.
fn opaque_distance(pixel: vec2<f32>, dir: vec3<f32>) -> f32 {
    let depth = textureLoad(opaque_depth, vec2<i32>(pixel), 0);
    if depth >= 1.0 {
        return 3.0e38;
    }
    // Invert the perspective depth (0 at near, 1 at far) to view-space z, then go along the ray.
    let near = frame.camera_pos.w;
    let far = frame.camera_forward.w;
    let view_z = near * far / (far - depth * (far - near));
    return view_z / max(dot(dir, frame.camera_forward.xyz), 1e-4);
}

@fragment
fn fs_spherical(in: VertexOut) -> @location(0) vec4<f32> {
    let dir = normalize(in.world - frame.camera_pos.xyz);
    let chord = sphere_chord(frame.camera_pos.xyz, dir, in.center_radius.xyz, in.center_radius.w);
    if chord.d >= in.center_radius.w {
        discard;
    }
    // Δs = min(Zs, |B|) - max(near, |F|), measured along the ray.
    let near_t = frame.camera_pos.w / max(dot(dir, frame.camera_forward.xyz), 1e-4);
    let zs = opaque_distance(in.clip.xy, dir);
    let t0 = max(near_t, chord.t_mid - chord.half_width);
    let t1 = min(zs, chord.t_mid + chord.half_width);
    if t1 <= t0 {
        discard;
    }
    return shade_segment(in, chord, t0, t1);
}

@fragment
fn fs_flat(in: VertexOut) -> @location(0) vec4<f32> {
    let dir = normalize(in.world - frame.camera_pos.xyz);
    let chord = sphere_chord(frame.camera_pos.xyz, dir, in.center_radius.xyz, in.center_radius.w);
    if chord.d >= in.center_radius.w {
        discard;
    }
    // The whole chord, whatever is behind it: the hard depth test alone decides visibility.
    return shade_segment(in, chord, chord.t_mid - chord.half_width, chord.t_mid + chord.half_width);
}
