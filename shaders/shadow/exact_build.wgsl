// `exact` build: the particles binned into light-space tiles.
// 1. count: each particle adds 1 to every tile its light-space footprint covers (atomics), and
//    the largest footprint's width and height in tiles go after the counts (atomic max).
// 2. scan_rows, scan_total, scan_write (shaders/shadow/grid_scan.wgsl): exclusive prefix sum of
//    the counts -> list offsets (offsets[tiles²] = total).
// 3. fill, once per slice of the spheres (they are uploaded in order of their nearest distance
//    from the light, src/shadow/exact.rs): each particle of the slice writes its index into the
//    lists of its tiles (the counts, cleared, serve as cursors). The dispatches run in slice
//    order, so a list holds its spheres slice by slice; within a slice the order is the order
//    the atomics ran in, which the lookup's fixed-point sum does not depend on.
// The lists and the spheres are row textures (shaders/common/rows.wgsl; src/shadow/exact.rs says
// why).
// Keep `ExactParams` in sync with src/shadow/exact.rs and exact.wgsl.
#import shadow/grid_scan.wgsl
#import common/rows.wgsl

struct ExactParams {
    view_from_world: mat4x4<f32>,
    tan_half_fov: f32,
    tiles: u32,
    particle_count: u32,
    capacity: u32,
    slice_size: u32,
};

@group(1) @binding(0) var<uniform> exact: ExactParams;
@group(1) @binding(1) var<storage, read_write> counts: array<atomic<u32>>;
@group(1) @binding(2) var<storage, read_write> offsets: array<u32>;
// Particle indices, per tile: entry i at texel row_texel(i).
@group(1) @binding(3) var entries: texture_storage_2d<r32uint, write>;
// Particle i's centre and radius at texel 2i, its albedo and extinction at 2i + 1.
@group(1) @binding(4) var spheres: texture_2d<f32>;
@group(1) @binding(6) var<storage, read_write> row_sums: array<u32>;
// The fill's slice: spheres [first, first + count) (a dynamic offset per dispatch).
struct FillSlice {
    first: u32,
    count: u32,
};
@group(1) @binding(7) var<uniform> fill_slice: FillSlice;

const HALF_PI: f32 = 1.5707963;

// The range of one light-view axis a sphere covers, as tile indices [x, y], or x > y when it
// covers none. `a` is the centre's coordinate along the axis, `z` its view depth (< 0 in front).
// The sphere's extreme directions in the (a, z) plane are θ ± asin(r/ρ): exact, and widened by a
// relative 1e-4 so that rounding never drops a sphere the lookup's tile test would reach.
fn axis_tiles(a: f32, z: f32, r: f32, flip: bool) -> vec2<i32> {
    let n = i32(exact.tiles);
    let rho = sqrt(a * a + z * z);
    var lo = -1e30;
    var hi = 1e30;
    if rho > r {
        let theta = atan2(a, -z);
        let alpha = asin(r / rho) * 1.0001 + 1e-6;
        if theta - alpha > -HALF_PI {
            lo = tan(theta - alpha) / exact.tan_half_fov;
        }
        if theta + alpha < HALF_PI {
            hi = tan(theta + alpha) / exact.tan_half_fov;
        }
        if theta - alpha >= HALF_PI || theta + alpha <= -HALF_PI {
            return vec2<i32>(1, 0);
        }
    }
    // NDC -> uv; the image's y runs downwards.
    var u0 = 0.5 + 0.5 * lo;
    var u1 = 0.5 + 0.5 * hi;
    if flip {
        u0 = 0.5 - 0.5 * hi;
        u1 = 0.5 - 0.5 * lo;
    }
    if u1 < 0.0 || u0 > 1.0 {
        return vec2<i32>(1, 0);
    }
    let first = i32(floor(clamp(u0, 0.0, 1.0) * f32(n)));
    let last = i32(floor(clamp(u1, 0.0, 1.0) * f32(n)));
    return vec2<i32>(clamp(first, 0, n - 1), clamp(last, 0, n - 1));
}

struct Footprint {
    x: vec2<i32>,
    y: vec2<i32>,
};

fn footprint(index: u32) -> Footprint {
    var out: Footprint;
    let center_radius = textureLoad(spheres, row_texel(2u * index), 0);
    let density = textureLoad(spheres, row_texel(2u * index + 1u), 0).w;
    let r = center_radius.w;
    let view = (exact.view_from_world * vec4<f32>(center_radius.xyz, 1.0)).xyz;
    out.x = axis_tiles(view.x, view.z, r, false);
    out.y = axis_tiles(view.y, view.z, r, true);
    if density <= 0.0 || r <= 0.0 {
        out.x = vec2<i32>(1, 0);
    }
    return out;
}

@compute @workgroup_size(64)
fn count(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= exact.particle_count {
        return;
    }
    let f = footprint(id.x);
    let n = i32(exact.tiles);
    // The widest and tallest footprints, in tiles, after the counts (the build bounds the
    // count's and fill's loops over them by llvmpipe's loop limit).
    if f.x.x <= f.x.y && f.y.x <= f.y.y {
        atomicMax(&counts[n * n], u32(f.x.y - f.x.x + 1));
        atomicMax(&counts[n * n + 1], u32(f.y.y - f.y.x + 1));
    }
    for (var y = f.y.x; y <= f.y.y; y++) {
        for (var x = f.x.x; x <= f.x.y; x++) {
            atomicAdd(&counts[y * n + x], 1u);
        }
    }
}

// The scan's grid is the tiles (shaders/shadow/grid_scan.wgsl).
fn scan_side() -> u32 {
    return exact.tiles;
}

@compute @workgroup_size(64)
fn fill(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= fill_slice.count {
        return;
    }
    let index = fill_slice.first + id.x;
    let f = footprint(index);
    let n = i32(exact.tiles);
    for (var y = f.y.x; y <= f.y.y; y++) {
        for (var x = f.x.x; x <= f.x.y; x++) {
            let tile = y * n + x;
            let slot = offsets[tile] + atomicAdd(&counts[tile], 1u);
            if slot < exact.capacity {
                textureStore(entries, row_texel(slot), vec4<u32>(index));
            }
        }
    }
}
