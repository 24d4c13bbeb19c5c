// Per-particle lighting: once per particle and frame, the single-scattered radiance towards the
// eye at four points inside the sphere (a 2x2 grid across the camera-facing disc, at
// ±SHADE_OFFSET·r), with the technique's T(p). The particle pass blends them bilinearly per
// fragment. (Evaluated per vertex instead, T would be paid six times per particle; per fragment,
// for every layer of overdraw.) Keep `ParticleLight` in sync with src/render/particles.rs and
// the four points with src/render/shaded.rs.
#import common/lighting.wgsl
#import common/particle.wgsl
#import shadow_technique
#import occluders
#import render/shadow_history.wgsl

// Where the four lighting points sit, as a fraction of the radius along the billboard's axes.
const SHADE_OFFSET: f32 = 0.5;

struct ParticleData {
    center_radius: vec4<f32>,
    albedo_density: vec4<f32>,
};

// Radiance at the points (-,-), (+,-), (-,+), (+,+) along (right, up); w: the smoke's T there,
// as this frame's lighting used it (the draw reads rgb; `Renderer::lit_particles` reads w back,
// so the tests and the sweep measure the T the frame rendered).
struct ParticleLight {
    radiance: array<vec4<f32>, 4>,
};

// The particles [start, start + count) of the instance buffer to light; when `ordered` is not
// 0, invocation i lights particle lit_order[start + i] instead of start + i (the technique's
// lighting order, a permutation of the range: `ShadowTechnique::lighting_order`).
struct LightRange {
    start: u32,
    count: u32,
    ordered: u32,
};

@group(2) @binding(0) var<storage, read> lit_particles: array<ParticleData>;
@group(2) @binding(1) var<storage, read_write> lit_out: array<ParticleLight>;
@group(2) @binding(2) var<uniform> lit_range: LightRange;
@group(2) @binding(3) var<storage, read> lit_order: array<u32>;

// Single scattering at `p` towards the eye plus ambient, for a particle of albedo `albedo`,
// given the smoke's transmittance `t` from the light to `p`.
fn scattered_radiance(p: vec3<f32>, eye: vec3<f32>, albedo: vec3<f32>, t: f32) -> vec3<f32> {
    let light_dir = normalize(p - frame.light_pos.xyz);
    let view_dir = normalize(p - eye);
    let phase = hg_phase_4pi(dot(light_dir, -view_dir), frame.light_radiance.w);
    // The opaque geometry's shadow times the smoke's: every technique's T(p) is multiplied by
    // the same occluder visibility.
    let direct = spot_irradiance(p) * (occluder_visibility(p) * t) * phase;
    // Normalised like a diffuse surface (E/π), so smoke and ground share one exposure: single
    // scattering alone would leave dense smoke far darker than the multiple scattering of real
    // smoke makes it look.
    return albedo * (direct / PI + frame.ambient.rgb);
}

// Particles per workgroup: each workgroup lights 64 particles with 256 invocations, one per
// lighting point (PARTICLES_PER_WORKGROUP in src/frame/particles.rs).
const PARTICLES_PER_WORKGROUP: u32 = 64u;

// One lighting point per invocation: each invocation makes one lookup, so a lookup that loops
// (`exact`'s walk over a tile list) may take the whole of llvmpipe's loop budget, and the
// lookup is compiled once, not inlined four times (llvmpipe compiles this shader in up to
// seconds for the moment maps otherwise). Invocation i of a workgroup lights point i / 64 of
// its particle i % 64, so that neighbouring lanes light the same point of neighbouring
// particles (in a technique's lighting order, neighbours in light space). A point light's six
// faces each light the points in their own face (`in_light_face`).
@compute @workgroup_size(256)
fn light_particles(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(local_invocation_index) lane: u32,
) {
    let k = lane / PARTICLES_PER_WORKGROUP;
    let local = group.x * PARTICLES_PER_WORKGROUP + lane % PARTICLES_PER_WORKGROUP;
    if local >= lit_range.count {
        return;
    }
    let slot = lit_range.start + local;
    var index = slot;
    if lit_range.ordered != 0u {
        index = lit_order[slot];
    }
    let particle = lit_particles[index];
    let center = particle.center_radius.xyz;
    let radius = particle.center_radius.w;
    let eye = frame.camera_pos.xyz;
    let bb = billboard_frame(center, radius, eye);
    let r = bb.right * (radius * SHADE_OFFSET);
    let u = bb.up * (radius * SHADE_OFFSET);
    let sx = select(-1.0, 1.0, (k & 1u) != 0u);
    let sy = select(-1.0, 1.0, (k & 2u) != 0u);
    let p = center + sx * r + sy * u;
    if in_light_face(p) {
        let t = filtered_t(index, k, shadow_transmittance(p));
        let albedo = particle.albedo_density.rgb;
        lit_out[index].radiance[k] = vec4<f32>(scattered_radiance(p, eye, albedo, t), t);
    }
}
