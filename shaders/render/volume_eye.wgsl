// The density volume seen by the eye (src/medium/eye_pass.rs): a front-to-back march of each
// pixel's ray over the part the grid covers, up to the opaque surface, in rounds of `round.steps`
// eye steps. Each round runs two kernels:
//   `eye_light`: one invocation per (pixel, step) sample of the round with density, one lookup
//     each: the smoke's T(p) from the active technique times the occluders' visibility. One
//     lookup per invocation, as the particles' lighting does, keeps every technique's lookup
//     (`exact`'s walk may take llvmpipe's whole loop budget) within what an invocation may loop.
//     A point light's faces each light the samples in their own face.
//   `eye_accumulate`: one invocation per pixel: the round's steps, in order, into the pixel's
//     running radiance and transmittance, each step integrated exactly for a source constant over
//     it (shaders/medium/eye_march.wgsl's energy-conserving form).
// `fs_composite` then lays the volume over the frame with premultiplied "over" (alpha 1 - T).
// The shading is the particles' (render/particle_lighting.wgsl: `scattered_radiance`):
// albedo · (E · phase · V · T / π + ambient), with the slides' powder term as an option.
#import common/lighting.wgsl
#import common/medium.wgsl
#import shadow_technique
#import occluders

// Keep in sync with `EyeRound` in src/medium/eye_pass.rs.
struct EyeRound {
    // The round's first eye step and how many it takes (the last may take fewer than `stride`).
    first: u32,
    steps: u32,
    // Sample slots per pixel in the light buffer (the largest round's steps).
    stride: u32,
    _pad: u32,
};

// Group 1 is the technique's lookup.
@group(2) @binding(0) var<uniform> eye_round: EyeRound;
@group(2) @binding(1) var eye_depth: texture_depth_2d;
// V·T at each sample of the round: pixel-major, `stride` slots a pixel.
@group(2) @binding(2) var<storage, read_write> eye_light_out: array<f32>;
// rgb: radiance scattered towards the eye so far; a: the ray's transmittance so far.
@group(2) @binding(3) var<storage, read_write> eye_state: array<vec4<f32>>;
// The same, read by the composite (its own group 2).
@group(2) @binding(4) var<storage, read> eye_final: array<vec4<f32>>;

// The invocation's index in a dispatch laid out over x and y (one dimension holds at most
// 65,535 workgroups).
fn linear_id(id: vec3<u32>, groups: vec3<u32>) -> u32 {
    return id.x + id.y * groups.x * 64u;
}

// One pixel's ray: the grid's part of it in front of the opaque surface.
struct EyeRay {
    origin: vec3<f32>,
    dir: vec3<f32>,
    // The part of the ray the march covers, metres from the eye, and a step's length.
    t0: f32,
    dt: f32,
    // Where in its step each sample lies, 0..1.
    offset: f32,
    hit: bool,
};

fn pixel_hash(p: vec2<u32>) -> f32 {
    var h = p.x * 1664525u + p.y * 1013904223u;
    h ^= h >> 16u;
    h *= 0x7feb352du;
    h ^= h >> 15u;
    h *= 0x846ca68bu;
    h ^= h >> 16u;
    return f32(h >> 8u) / 16777216.0;
}

fn eye_ray(pixel: vec2<u32>) -> EyeRay {
    var out: EyeRay;
    out.hit = false;
    let size = vec2<u32>(frame.viewport.xy);
    if any(pixel >= size) || !medium_present() {
        return out;
    }
    let uv = (vec2<f32>(pixel) + vec2<f32>(0.5)) * frame.viewport.zw;
    let ndc = vec2<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
    let depth = textureLoad(eye_depth, vec2<i32>(pixel), 0);
    let far_h = frame.world_from_clip * vec4<f32>(ndc, depth, 1.0);
    let near_h = frame.world_from_clip * vec4<f32>(ndc, 0.0, 1.0);
    let far_p = far_h.xyz / far_h.w;
    let near_p = near_h.xyz / near_h.w;
    out.origin = frame.camera_pos.xyz;
    out.dir = normalize(far_p - out.origin);
    let t_near = distance(near_p, out.origin);
    let t_far = distance(far_p, out.origin);
    if t_far <= t_near {
        return out;
    }
    let a = out.origin + t_near * out.dir;
    let b = out.origin + t_far * out.dir;
    let s = grid_support((grid_params().index_from_world * vec4<f32>(a, 1.0)).xyz, (grid_params().index_from_world * vec4<f32>(b, 1.0)).xyz);
    if s.x >= s.y {
        return out;
    }
    out.t0 = t_near + s.x * (t_far - t_near);
    out.dt = (s.y - s.x) * (t_far - t_near) / f32(grid_params().eye_steps);
    out.offset = 0.5 + grid_params().jitter * (pixel_hash(pixel) - 0.5);
    out.hit = true;
    return out;
}

fn eye_sample_point(ray: EyeRay, step: u32) -> vec3<f32> {
    return ray.origin + (ray.t0 + (f32(step) + ray.offset) * ray.dt) * ray.dir;
}

fn extinction_at(p: vec3<f32>) -> f32 {
    return grid_params().density_scale_per_m * grid_density_at_index((grid_params().index_from_world * vec4<f32>(p, 1.0)).xyz);
}

@compute @workgroup_size(64)
fn eye_light(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let width = u32(frame.viewport.x);
    let i = linear_id(id, groups);
    let pixel_index = i / eye_round.steps;
    let k = i % eye_round.steps;
    let pixel = vec2<u32>(pixel_index % width, pixel_index / width);
    if pixel.y >= u32(frame.viewport.y) {
        return;
    }
    let ray = eye_ray(pixel);
    if !ray.hit {
        return;
    }
    let p = eye_sample_point(ray, eye_round.first + k);
    if extinction_at(p) <= 0.0 || !in_light_face(p) {
        return;
    }
    var lit = 0.0;
    if any(spot_irradiance(p) > vec3<f32>(0.0)) {
        let visibility = occluder_visibility(p);
        if visibility > 0.0 {
            lit = visibility * shadow_transmittance(p);
        }
    }
    eye_light_out[pixel_index * eye_round.stride + k] = lit;
}

@compute @workgroup_size(64)
fn eye_accumulate(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let width = u32(frame.viewport.x);
    let index = linear_id(id, groups);
    let pixel = vec2<u32>(index % width, index / width);
    if pixel.y >= u32(frame.viewport.y) {
        return;
    }
    var state = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    if eye_round.first > 0u {
        state = eye_state[index];
    }
    let ray = eye_ray(pixel);
    if ray.hit {
        let albedo = grid_params().albedo_powder.rgb;
        let powder = grid_params().albedo_powder.w;
        for (var k = 0u; k < eye_round.steps; k++) {
            let p = eye_sample_point(ray, eye_round.first + k);
            let sigma = extinction_at(p);
            if sigma <= 0.0 {
                continue;
            }
            let lit = eye_light_out[index * eye_round.stride + k];
            let light_dir = normalize(p - frame.light_pos.xyz);
            let phase = hg_phase_4pi(dot(light_dir, -ray.dir), frame.light_radiance.w);
            // The slides' powder: Beer's T times 2(1 - T²), blended in by its weight.
            let shaped = lit * mix(1.0, 2.0 * (1.0 - lit * lit), powder);
            let source = albedo * (spot_irradiance(p) * (shaped * phase) / PI + frame.ambient.rgb);
            let step_t = exp(-sigma * ray.dt);
            state = vec4<f32>(state.rgb + state.a * source * (1.0 - step_t), state.a * step_t);
        }
    }
    eye_state[index] = state;
}

@vertex
fn vs_composite(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((vi << 1u) & 2u), f32(vi & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

// Premultiplied: the volume's radiance, and its opacity 1 - T (blended "over" the frame).
@fragment
fn fs_composite(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let pixel = vec2<u32>(pos.xy);
    let state = eye_final[pixel.y * u32(frame.viewport.x) + pixel.x];
    return vec4<f32>(state.rgb, 1.0 - state.a);
}
