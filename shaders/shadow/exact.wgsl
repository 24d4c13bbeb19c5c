// `exact` lookup: the particle model's transmittance in closed form at the point itself, with no
// texels: T(p) = exp(-Σ_i τ_i (1 - d_i/r_i) ℓ_i(p)), d_i the distance from particle i's centre
// to the segment light -> p and ℓ_i(p) the part of its chord between the light and p (the density
// model of the spherical billboards and the chord splat).
//
// The particles that can cross the segment are those whose light-space footprint covers p's
// point of the light's image plane: the build bins them into light-space tiles (seeds/001, "light
// occlusion": particles appended to the tiles they cover, lists walked per query). The walk
// covers the whole list (a sphere beyond p adds nothing) and sums in fixed point, 2^-26 of
// optical depth per unit: integer addition is associative, so the sum does not depend on the
// order the build's atomics filled the list in. Each term rounds by at most 2^-27 = 7.5e-9; a
// sum beyond 64 (T < 1.7e-28) saturates. Keep `ExactParams` in sync with src/shadow/exact.rs
// and exact_build.wgsl, and the arithmetic with src/shadow/closed_form.rs.
#import common/lighting.wgsl
#import common/rows.wgsl

struct ExactParams {
    // The light's view matrix (it looks down -z) and tan of half its field of view.
    view_from_world: mat4x4<f32>,
    tan_half_fov: f32,
    // Tiles per side of the light's image plane.
    tiles: u32,
    // Particles binned this frame, and entries the list buffer can hold.
    particle_count: u32,
    capacity: u32,
};

@group(1) @binding(0) var<uniform> exact: ExactParams;
@group(1) @binding(1) var<storage, read> exact_offsets: array<u32>;
// Particle indices, per tile: entry i at texel row_texel(i) (shaders/common/rows.wgsl).
// Textures, not storage buffers: llvmpipe fetches texels for the lanes of a SIMD group in one
// gather, where it loads a storage buffer's words lane by lane (src/shadow/exact.rs).
@group(1) @binding(2) var exact_entries: texture_2d<u32>;
// A particle as the renderer's instance buffer holds it (`ParticleInstance`): particle i's
// centre and radius (m) at texel 2i, its albedo and extinction τ (1/m) at 2i + 1.
@group(1) @binding(3) var exact_spheres: texture_2d<f32>;

// Fixed-point units per unit of optical depth, and the largest optical depth a sum holds.
const EXACT_UNITS: f32 = 67108864.0;
const EXACT_MAX_OPTICAL_DEPTH: f32 = 63.0;

// The tile a light-view point falls in, or -1 outside the light's image plane.
fn exact_tile(view: vec3<f32>) -> i32 {
    if view.z >= 0.0 {
        return -1;
    }
    let ndc = view.xy / (-view.z * exact.tan_half_fov);
    if any(abs(ndc) > vec2<f32>(1.0)) {
        return -1;
    }
    let uv = ndc * vec2<f32>(0.5, -0.5) + vec2<f32>(0.5);
    let n = i32(exact.tiles);
    let tile = clamp(vec2<i32>(floor(uv * f32(n))), vec2<i32>(0), vec2<i32>(n - 1));
    return tile.y * n + tile.x;
}

// Optical depth from the light to `p` through the spheres of p's tile.
fn exact_optical_depth(p: vec3<f32>) -> f32 {
    let view = (exact.view_from_world * vec4<f32>(p, 1.0)).xyz;
    let tile = exact_tile(view);
    if tile < 0 {
        return 0.0;
    }
    let origin = frame.light_pos.xyz;
    let to_p = p - origin;
    let length_m = length(to_p);
    if length_m <= 0.0 {
        return 0.0;
    }
    let dir = to_p / length_m;
    var sum = 0u;
    let end = exact_offsets[tile + 1];
    for (var i = exact_offsets[tile]; i < end; i++) {
        let j = 2u * textureLoad(exact_entries, row_texel(i), 0).x;
        let center_radius = textureLoad(exact_spheres, row_texel(j), 0);
        let density = textureLoad(exact_spheres, row_texel(j + 1u), 0).w;
        let r = center_radius.w;
        let oc = center_radius.xyz - origin;
        let t_mid = dot(oc, dir);
        // The perpendicular offset, not |oc|² - t², which cancels catastrophically.
        let d2 = dot(oc - dir * t_mid, oc - dir * t_mid);
        if d2 >= r * r {
            continue;
        }
        let half = sqrt(r * r - d2);
        let inside = max(min(t_mid + half, length_m) - max(t_mid - half, 0.0), 0.0);
        let term = density * (1.0 - sqrt(d2) / r) * inside;
        let units = u32(round(min(term, EXACT_MAX_OPTICAL_DEPTH) * EXACT_UNITS));
        sum = select(sum + units, 0xffffffffu, sum > 0xffffffffu - units);
    }
    return f32(sum) / EXACT_UNITS;
}

fn shadow_transmittance(p: vec3<f32>) -> f32 {
    return exp(-exact_optical_depth(p));
}
