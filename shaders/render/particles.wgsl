// Particle pass: billboards sorted back to front, composited with premultiplied "over"
// (thesis Eq. 1.5). `fs_spherical` clips each particle's chord against the opaque depth
// (spherical billboards, thesis 3.2.2.3); `fs_flat` is the plain billboard with a hard depth test.
#import common/lighting.wgsl
#import common/particle.wgsl
#import shadow_technique

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) @interpolate(flat) center_radius: vec4<f32>,
    @location(2) @interpolate(flat) albedo_density: vec4<f32>,
};

@vertex
fn vs_main(@builtin(vertex_index) vi: u32, particle: ParticleIn) -> VertexOut {
    var out: VertexOut;
    let world = billboard_corner(
        particle.center_radius.xyz, particle.center_radius.w, frame.camera_pos.xyz, quad_corner(vi));
    out.clip = frame.clip_from_world * vec4<f32>(world, 1.0);
    out.world = world;
    out.center_radius = particle.center_radius;
    out.albedo_density = particle.albedo_density;
    return out;
}

// Single scattering at `p` towards the eye plus ambient, for a particle of albedo `albedo`.
fn scattered_radiance(p: vec3<f32>, view_dir: vec3<f32>, albedo: vec3<f32>) -> vec3<f32> {
    let light_dir = normalize(p - frame.light_pos.xyz);
    let phase = hg_phase_4pi(dot(light_dir, -view_dir), frame.light_radiance.w);
    let direct = spot_irradiance(p) * shadow_transmittance(p) * phase;
    // Normalised like a diffuse surface (E/π), so smoke and ground share one exposure: single
    // scattering alone would leave dense smoke far darker than the multiple scattering of real
    // smoke makes it look.
    return albedo * (direct / PI + frame.ambient.rgb);
}

// Composites one particle over the ray segment [t0, t1] of its chord.
fn shade_segment(in: VertexOut, dir: vec3<f32>, chord: Chord, t0: f32, t1: f32) -> vec4<f32> {
    let ds = max(t1 - t0, 0.0);
    let sigma = chord_extinction(in.albedo_density.a, chord.d, in.center_radius.w);
    let alpha = 1.0 - exp(-sigma * ds);
    // Shade at the middle of the visible part of the chord.
    let p = frame.camera_pos.xyz + dir * (0.5 * (t0 + t1));
    let radiance = scattered_radiance(p, dir, in.albedo_density.rgb);
    return vec4<f32>(radiance * alpha, alpha);
}

@group(2) @binding(0) var opaque_depth: texture_depth_2d;

// Distance along the eye ray `dir` to the opaque surface behind pixel `pixel`.
fn opaque_distance(pixel: vec2<f32>, dir: vec3<f32>) -> f32 {
    let depth = textureLoad(opaque_depth, vec2<i32>(pixel), 0);
    if depth >= 1.0 {
        return 3.0e38;
    }
    let ndc = vec2<f32>(pixel.x * frame.viewport.z * 2.0 - 1.0, 1.0 - pixel.y * frame.viewport.w * 2.0);
    let world = frame.world_from_clip * vec4<f32>(ndc, depth, 1.0);
    return distance(world.xyz / world.w, frame.camera_pos.xyz);
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
    return shade_segment(in, dir, chord, t0, t1);
}

@fragment
fn fs_flat(in: VertexOut) -> @location(0) vec4<f32> {
    let dir = normalize(in.world - frame.camera_pos.xyz);
    let chord = sphere_chord(frame.camera_pos.xyz, dir, in.center_radius.xyz, in.center_radius.w);
    if chord.d >= in.center_radius.w {
        discard;
    }
    // The whole chord, whatever is behind it: the hard depth test alone decides visibility.
    return shade_segment(in, dir, chord, chord.t_mid - chord.half_width, chord.t_mid + chord.half_width);
}
