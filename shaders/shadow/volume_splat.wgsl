// The techniques' shared light-space build from a density volume (issue 26 §3): a full-screen
// triangle over a technique's maps, whose fragments each march their texel's light ray through
// the grid, over the part of the frame's depth range [near, far] the grid covers, in
// `build_steps` steps (the same for every technique), and hand each step to the technique's own
// accumulation as a splat: the step's optical depth σ·Δt, spread over its depths [z0, z1]
// (segment splat) or at its middle (point splat), exactly as a particle fragment hands its chord
// (shaders/shadow/layered_build.wgsl). The particles' billboards and the volume's triangle draw
// into the same maps with the same blending, so one map holds both.
#import common/medium.wgsl

struct VolumeVertexOut {
    @builtin(position) clip: vec4<f32>,
    // The fragment's light-space NDC.
    @location(0) ndc: vec2<f32>,
};

@vertex
fn vs_volume(@builtin(vertex_index) vi: u32) -> VolumeVertexOut {
    let uv = vec2<f32>(f32((vi << 1u) & 2u), f32(vi & 2u));
    var out: VolumeVertexOut;
    out.clip = vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
    out.ndc = out.clip.xy;
    return out;
}

// A texel's light ray: radial distances t from the light along the unit `dir`, marched from t0
// in `steps` steps of dt (steps = 0: the ray misses the grid).
struct VolumeRay {
    dir: vec3<f32>,
    t0: f32,
    dt: f32,
    steps: u32,
};

fn volume_light_ray(ndc: vec2<f32>) -> VolumeRay {
    var ray: VolumeRay;
    ray.steps = 0u;
    if !medium_present() {
        return ray;
    }
    let origin = frame.light_pos.xyz;
    let h = frame.world_from_light_clip * vec4<f32>(ndc, 1.0, 1.0);
    ray.dir = normalize(h.xyz / h.w - origin);
    let near = frame.light_depth.x;
    let far = frame.light_depth.y;
    let m = grid_params().index_from_world;
    let s = grid_support((m * vec4<f32>(origin + near * ray.dir, 1.0)).xyz, (m * vec4<f32>(origin + far * ray.dir, 1.0)).xyz);
    if s.x >= s.y {
        return ray;
    }
    ray.steps = max(grid_params().build_steps, 1u);
    ray.t0 = near + s.x * (far - near);
    ray.dt = (s.y - s.x) * (far - near) / f32(ray.steps);
    return ray;
}

// Step `i` of `ray` as a splat (optical depth 0 where the grid is empty).
fn volume_splat(ray: VolumeRay, i: u32, segment: bool) -> Splat {
    let t = ray.t0 + (f32(i) + 0.5) * ray.dt;
    let p = frame.light_pos.xyz + t * ray.dir;
    let q = (grid_params().index_from_world * vec4<f32>(p, 1.0)).xyz;
    var out: Splat;
    out.optical_depth = grid_params().density_scale_per_m * grid_density_at_index(q) * ray.dt;
    let k = frame.light_depth.z;
    let near = frame.light_depth.x;
    if segment {
        out.z0 = (t - 0.5 * ray.dt - near) * k;
        out.z1 = (t + 0.5 * ray.dt - near) * k;
    } else {
        out.z0 = (t - near) * k;
        out.z1 = out.z0;
    }
    return out;
}

// Where the volume's smoke starts along the ray (the first step with density), and where it
// ends (the last one's far end), normalised; (1, 0) where there is none.
struct VolumeExtent {
    front: f32,
    back: f32,
    optical_depth: f32,
};

fn volume_extent(ray: VolumeRay) -> VolumeExtent {
    var out = VolumeExtent(1.0, 0.0, 0.0);
    for (var i = 0u; i < ray.steps; i++) {
        let s = volume_splat(ray, i, true);
        if s.optical_depth > 0.0 {
            out.front = min(out.front, s.z0);
            out.back = max(out.back, s.z1);
            out.optical_depth += s.optical_depth;
        }
    }
    return out;
}
