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
#import common/medium.wgsl
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
    // Spheres per slice of the light-distance order.
    slice_size: u32,
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
// The spheres are uploaded by their nearest distance from the light, |c - light| - r, and their
// indices cut into slices of `slice_size`: the lowest distance in each slice (m, rounded down).
@group(1) @binding(4) var<storage, read> exact_slice_near: array<f32>;

// Fixed-point units per unit of optical depth; the optical depth a sum saturates at (T there is
// exp(-12) = 6.1e-6: what is lost beyond it changes T by less than that); entries per loop
// iteration of the walk. Keep them in sync with src/shadow/exact.rs and closed_form.rs.
const EXACT_UNITS: f32 = 67108864.0;
const EXACT_CUT: f32 = 12.0;
const EXACT_UNROLL: u32 = 8u;

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

// Sphere `index`'s term of the optical depth along the segment from `origin` along `dir` over
// `length_m`, in fixed-point units (at most EXACT_CUT's).
fn exact_units(index: u32, origin: vec3<f32>, dir: vec3<f32>, length_m: f32) -> u32 {
    let center_radius = textureLoad(exact_spheres, row_texel(2u * index), 0);
    let density = textureLoad(exact_spheres, row_texel(2u * index + 1u), 0).w;
    let r = center_radius.w;
    let oc = center_radius.xyz - origin;
    let t_mid = dot(oc, dir);
    // The perpendicular offset, not |oc|² - t², which cancels catastrophically.
    let d2 = dot(oc - dir * t_mid, oc - dir * t_mid);
    if d2 >= r * r {
        return 0u;
    }
    let half = sqrt(r * r - d2);
    let inside = max(min(t_mid + half, length_m) - max(t_mid - half, 0.0), 0.0);
    let term = density * (1.0 - sqrt(d2) / r) * inside;
    return u32(round(min(term, EXACT_CUT) * EXACT_UNITS));
}

fn exact_entry(i: u32) -> u32 {
    return textureLoad(exact_entries, row_texel(i), 0).x;
}

// Optical depth from the light to `p` through the spheres of p's tile, saturated at EXACT_CUT.
// - The saturation is order-free: the terms are not negative, so the clamped running sum is
//   min(partial sum, cut) at every step and the result min(τ, cut) whatever the list's order.
//   The walk stops once the cut is reached.
// - A list holds its spheres slice by slice of the light-distance order (src/shadow/exact.rs):
//   once an entry's slice starts beyond p, no sphere after it reaches the segment, and the walk
//   stops there (each sphere it skips adds exactly 0).
// - The walk takes EXACT_UNROLL entries per loop iteration: llvmpipe counts iterations, not
//   entries, so a list may hold EXACT_UNROLL times its loop budget.
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
    let cut = u32(EXACT_CUT * EXACT_UNITS);
    var sum = 0u;
    var i = exact_offsets[tile];
    let end = exact_offsets[tile + 1];
    // Whole groups of EXACT_UNROLL (8) entries, then the rest one at a time.
    while i + EXACT_UNROLL <= end && sum < cut {
        let a = exact_entry(i);
        if exact_slice_near[a / exact.slice_size] > length_m {
            return f32(sum) / EXACT_UNITS;
        }
        let b = exact_entry(i + 1u);
        let c = exact_entry(i + 2u);
        let d = exact_entry(i + 3u);
        let e = exact_entry(i + 4u);
        let f = exact_entry(i + 5u);
        let g = exact_entry(i + 6u);
        let h = exact_entry(i + 7u);
        sum = min(sum + exact_units(a, origin, dir, length_m), cut);
        sum = min(sum + exact_units(b, origin, dir, length_m), cut);
        sum = min(sum + exact_units(c, origin, dir, length_m), cut);
        sum = min(sum + exact_units(d, origin, dir, length_m), cut);
        sum = min(sum + exact_units(e, origin, dir, length_m), cut);
        sum = min(sum + exact_units(f, origin, dir, length_m), cut);
        sum = min(sum + exact_units(g, origin, dir, length_m), cut);
        sum = min(sum + exact_units(h, origin, dir, length_m), cut);
        i += EXACT_UNROLL;
    }
    while i < end && sum < cut {
        sum = min(sum + exact_units(exact_entry(i), origin, dir, length_m), cut);
        i++;
    }
    return f32(sum) / EXACT_UNITS;
}

// With a density volume, its optical depth too: a shape's in closed form, a grid's by a midpoint
// march towards the light with the reference's step count, shown to have converged
// (src/medium/frame.rs: four steps a voxel along the grid's diagonal, at least two, within the
// loop iterations src/shadow/exact.rs leaves it).
fn shadow_transmittance(p: vec3<f32>) -> f32 {
    let volume =
        medium_reference_optical_depth(frame.light_pos.xyz, p, grid_params().reference_steps);
    return exp(-(exact_optical_depth(p) + volume));
}
