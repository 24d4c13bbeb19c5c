// The eye's march at a list of rays (src/medium/eye.rs, EyeMarchProbe): what the volume's eye
// pass computes per pixel, with the light's transmittance by secondary ray marching (the 2022
// dissertation's SRM: `light_steps` samples towards the light from every eye sample), so that
// tests can hold it to the f64 mirror. The source is the light's transmittance alone (a unit,
// isotropic light), so a lit and an unlit ray differ only by the smoke between them and it.
#import medium/eye_march.wgsl

// Keep in sync with `EyeProbeParams` in src/medium/eye.rs.
struct EyeProbeParams {
    // xyz: the light's position, world metres.
    light: vec4<f32>,
    // rgb: the medium's single-scattering albedo.
    albedo: vec4<f32>,
    eye_steps: u32,
    light_steps: u32,
    count: u32,
    // The eye samples' place in their steps, 0..1.
    jitter: f32,
};

// A ray: xyz origin, w t_near; xyz unit direction, w t_far.
struct EyeRay {
    origin: vec4<f32>,
    dir: vec4<f32>,
};

@group(0) @binding(0) var<uniform> grid: GridParams;
@group(0) @binding(1) var grid_density: texture_3d<f32>;

fn grid_params() -> GridParams {
    return grid;
}
@group(0) @binding(2) var<uniform> eye_probe: EyeProbeParams;
@group(0) @binding(3) var<storage, read> eye_rays: array<EyeRay>;
// Per ray: rgb radiance, a transmittance.
@group(0) @binding(4) var<storage, read_write> eye_results: array<vec4<f32>>;

fn medium_in_scatter(p: vec3<f32>, dir: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(exp(-grid_optical_depth(eye_probe.light.xyz, p, eye_probe.light_steps)));
}

@compute @workgroup_size(64)
fn eye_probe_main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= eye_probe.count {
        return;
    }
    let ray = eye_rays[id.x];
    let m = march_eye(ray.origin.xyz, ray.dir.xyz, ray.origin.w, ray.dir.w, eye_probe.eye_steps, eye_probe.jitter, eye_probe.albedo.rgb);
    eye_results[id.x] = vec4<f32>(m.radiance, m.transmittance);
}
