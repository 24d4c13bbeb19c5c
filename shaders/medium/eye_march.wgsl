// The eye's ray march through a density grid (src/medium/eye.rs; the f64 mirror is
// `DensityGrid::march_eye` in src/medium/grid.rs): front to back, single scattering, over the
// part of the ray where the density can be non-zero.
//
// Each step holds the extinction σ and the in-scattered source S at its sample (the jittered
// point of the step) constant over the step, and integrates exactly over it:
//   L += T · albedo · S · (1 - exp(-σ Δt)),   T *= exp(-σ Δt)
// (the energy-conserving form of Hillaire 2015: the radiance of a step stays bounded however
// thick the step is). With S constant, the sum telescopes to albedo · S · (1 - T): the march
// is exact for any step count, whatever σ does, which tests/medium.rs holds it to.
//
// The importer supplies `grid`, `grid_density` (shaders/medium/grid.wgsl) and
// `medium_in_scatter(p: vec3<f32>, dir: vec3<f32>) -> vec3<f32>`: the radiance scattered towards
// -dir at p per unit of scattering, with the light's transmittance to p folded in (the active
// technique's, or a march towards the light).
#import medium/grid.wgsl

struct EyeMarch {
    // Radiance towards the eye, scattered along the ray.
    radiance: vec3<f32>,
    // Transmittance of the whole ray.
    transmittance: f32,
};

// Marches `origin + t·dir` (dir a unit vector, world metres) for t in [t_near, t_far] with
// `steps` steps over the grid's support, each sampled at `jitter` (0..1) of its length.
// Loops `steps` + 3 times plus what `medium_in_scatter` loops per step.
fn march_eye(origin: vec3<f32>, dir: vec3<f32>, t_near: f32, t_far: f32, steps: u32, jitter: f32, albedo: vec3<f32>) -> EyeMarch {
    var out = EyeMarch(vec3<f32>(0.0), 1.0);
    let a = origin + t_near * dir;
    let b = origin + t_far * dir;
    let qa = (grid_params().index_from_world * vec4<f32>(a, 1.0)).xyz;
    let qb = (grid_params().index_from_world * vec4<f32>(b, 1.0)).xyz;
    let s = grid_support(qa, qb);
    if s.x >= s.y || steps == 0u || t_far <= t_near {
        return out;
    }
    let dt = (s.y - s.x) / f32(steps);
    let step_m = dt * (t_far - t_near);
    for (var i = 0u; i < steps; i++) {
        let f = s.x + (f32(i) + jitter) * dt;
        let sigma = grid_params().density_scale_per_m * grid_density_at_index(mix(qa, qb, f));
        if sigma <= 0.0 {
            continue;
        }
        let step_t = exp(-sigma * step_m);
        let p = mix(a, b, f);
        out.radiance += out.transmittance * albedo * medium_in_scatter(p, dir) * (1.0 - step_t);
        out.transmittance *= step_t;
    }
    return out;
}
