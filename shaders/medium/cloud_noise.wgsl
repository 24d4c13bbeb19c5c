// Procedural cloud noise and the cloud's density, after Schneider & Vos (GPU Pro 7, "Real-time
// volumetric cloudscapes of Horizon Zero Dawn") as the seeds describe it:
// - the two textures and their channels: the slides' "Cloud Shape" table (003: shape 128³, R
//   Perlin, G B A Worley; detail 32³, R G B Worley) and the 2022 dissertation's §3.2.1 (000: R
//   Perlin–Worley, G B A Worley of higher frequency; detail = increasingly higher frequency
//   Worley, "to further erode the cloud");
// - the density: the 2018 thesis' §3.1 (004, eq. 5–16, appendix B.2–B.5): shape noise remapped by
//   its own Worley FBM (eq. 11), a shape height gradient (eq. 5–7), the coverage remap (eq. 12/15),
//   detail erosion (eq. 13, 14, 16) and a density height gradient (eq. 8–10).
// Where the seeds are silent (frequencies, octaves, the Perlin–Worley mix) this follows the common
// implementation of GPU Pro 7 (Hillaire's TileableVolumeNoise): Perlin FBM at 8 with 3 octaves,
// dilated by 1 − Worley FBM at 8, 32, 56 cells; Worley FBMs at 8..64 cells (shape), 2..16 (detail).
//
// The CPU mirror, operation for operation, is src/medium/cloud_noise.rs; keep the two in step.
// The generators' bindings and entry points are in shaders/medium/cloud_noise_gen.wgsl, so that a
// march can import the noise and the density without them.
//
// Determinism and tiling: every lattice coordinate is an integer (voxel × frequency, then divided
// by the texture size), so cells and fractions are exact and the same on every device; the hash
// (pcg3d) is integer-only and sees the cell modulo the frequency, so each noise repeats exactly
// once per texture. Floats only enter as exact fractions k / size (size a power of two).
//
// Bindings of the generators (`shape_main`, `detail_main` in cloud_noise_gen.wgsl; each uses
// only its own buffer):
//   @group(0) @binding(0) noise         CloudNoiseParams  uniform
//   @group(0) @binding(1) shape_texels  array<f32>        storage, read_write, 128³ × 4 floats
//   @group(0) @binding(2) detail_texels array<f32>        storage, read_write, 32³ × 4 floats
// Texel (x, y, z) channel c is at ((z * size + y) * size + x) * 4 + c: x fastest, then y, then z,
// 4 floats a texel so the buffer copies straight into an Rgba32Float 3D texture.

// Keep in sync with `CloudNoiseParams` in src/medium/cloud_noise.rs.
struct CloudNoiseParams {
    seed: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
};

// The cloud layer, a box in the world (+y up); the scene's fields.
// Keep in sync with `CloudParams` in src/medium/cloud_noise.rs.
struct CloudParams {
    // The layer's smallest x and z, metres.
    origin_xz_m: vec2<f32>,
    // The layer's width along x and z, metres.
    size_xz_m: vec2<f32>,
    // The layer's base (world y), metres.
    altitude_m: f32,
    // The layer's thickness along y, metres.
    thickness_m: f32,
    // The global coverage g_c, 0..1 (004 §3.1.1).
    coverage: f32,
    // Extinction of the densest cloud, 1/m (004's global density g_d, given a unit).
    density_per_m: f32,
    // The height fraction the cloud tops reach, (0, 1] (004's weather-map w_h, eq. 6).
    top_fraction: f32,
    // World metres one period of the shape texture spans.
    shape_period_m: f32,
    // World metres one period of the detail texture spans.
    detail_period_m: f32,
    // How much the coverage map shapes the layer, 0..1: 0 the layer's coverage everywhere, 1
    // the map's fields of cloud and clear sky (`cloud_coverage_map`).
    coverage_map: f32,
};

const SHAPE_SIZE: u32 = 128u;
const DETAIL_SIZE: u32 = 32u;
const FLOATS_PER_TEXEL: u32 = 4u;

// Salts keep every noise's lattice independent of the others' for one seed (the same cell at 8
// cells in Perlin and in Worley would otherwise get the same random numbers).
const SALT_SHAPE_WORLEY: u32 = 0x100u;
const SALT_PERLIN: u32 = 0x200u;
const SALT_DETAIL_WORLEY: u32 = 0x300u;

const SALT_COVERAGE: u32 = 0x400u;
// The coverage map: COVERAGE_SIZE² texels over the layer, Perlin noise of COVERAGE_CELLS cells
// and twice that.
const COVERAGE_SIZE: u32 = 256u;
const COVERAGE_CELLS: u32 = 4u;

const PERLIN_BASE_CELLS: u32 = 8u;
const PERLIN_OCTAVES: u32 = 3u;

// pcg3d (Jarzynski & Olano, "Hash Functions for GPU Rendering", JCGT 2020): integer-only, so the
// same bits on every device and in the CPU mirror; u32 arithmetic wraps in WGSL.
fn pcg3d(v_in: vec3<u32>) -> vec3<u32> {
    var v = v_in * 1664525u + 1013904223u;
    v.x += v.y * v.z;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v ^= v >> vec3<u32>(16u);
    v.x += v.y * v.z;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    return v;
}

// The key one noise adds to its cells before hashing: the seed and the noise's salt, hashed.
fn noise_key(seed: u32, salt: u32) -> vec3<u32> {
    return pcg3d(vec3<u32>(seed, salt, 0x9e3779b9u));
}

// [0, 1) from the top 24 bits: exactly representable, so no rounding anywhere.
fn unit_from_bits(bits: u32) -> f32 {
    return f32(bits >> 8u) * (1.0 / 16777216.0);
}

// Voxel `voxel` of a texture of `size` voxels in the lattice of `cells` cells per period: its
// cell (not yet wrapped) and its exact position in that cell.
struct LatticePoint {
    cell: vec3<u32>,
    frac: vec3<f32>,
};

fn lattice_point(voxel: vec3<u32>, cells: u32, size: u32) -> LatticePoint {
    let q = voxel * cells;
    return LatticePoint(q / size, vec3<f32>(q % size) / f32(size));
}

// a + (b − a) t, spelled out rather than `mix` so the CPU mirror does the same operations.
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    return a + (b - a) * t;
}

// Remap v from [lo, hi] to [new_lo, new_hi], unclamped (004 eq. 1, appendix B.1).
fn remap(v: f32, lo: f32, hi: f32, new_lo: f32, new_hi: f32) -> f32 {
    return new_lo + (v - lo) * (new_hi - new_lo) / (hi - lo);
}

// Inverted Worley noise 1 − F1 (Worley 1996; inverted for "white blobs", 004 §2.2 note 1): F1 the
// distance to the nearest feature point, one point per cell, in cell units and clamped to 1.
// Loops: 27 neighbour cells (3 × 3 × 3; 3 + 9 + 27 = 39 loop iterations in all).
fn worley_inverted(voxel: vec3<u32>, cells: u32, size: u32, key: vec3<u32>) -> f32 {
    let lp = lattice_point(voxel, cells, size);
    // Starting at 1 is the clamp of F1 to 1, done before the square root.
    var nearest_sq = 1.0;
    for (var dz = 0u; dz < 3u; dz++) {
        for (var dy = 0u; dy < 3u; dy++) {
            for (var dx = 0u; dx < 3u; dx++) {
                let offset = vec3<u32>(dx, dy, dz);
                // The neighbour cell − 1 + offset, wrapped to the period; `cells` is added first
                // so that cell 0's left neighbour does not wrap around the u32.
                let cell = (lp.cell + offset + vec3<u32>(cells - 1u)) % vec3<u32>(cells);
                let h = pcg3d(cell + key);
                let jitter = vec3<f32>(unit_from_bits(h.x), unit_from_bits(h.y), unit_from_bits(h.z));
                let d = vec3<f32>(offset) - vec3<f32>(1.0) + jitter - lp.frac;
                nearest_sq = min(nearest_sq, d.x * d.x + d.y * d.y + d.z * d.z);
            }
        }
    }
    return 1.0 - sqrt(nearest_sq);
}

// The gradient of Perlin's improved noise (2002): 12 cube-edge directions picked by 4 hash bits,
// dotted with the offset `d` without a multiply.
fn perlin_gradient_dot(bits: u32, d: vec3<f32>) -> f32 {
    let g = bits >> 28u;
    let u = select(d.y, d.x, g < 8u);
    let v = select(select(d.z, d.x, g == 12u || g == 14u), d.y, g < 4u);
    return select(-u, u, (g & 1u) == 0u) + select(-v, v, (g & 2u) == 0u);
}

fn perlin_corner(c: vec3<u32>, key: vec3<u32>, d: vec3<f32>) -> f32 {
    return perlin_gradient_dot(pcg3d(c + key).x, d);
}

// Perlin's quintic fade 6t⁵ − 15t⁴ + 10t³.
fn fade(t: f32) -> f32 {
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
}

// Periodic improved Perlin noise (Perlin 2002), about −1..1, with `cells` cells per period.
fn perlin_periodic(voxel: vec3<u32>, cells: u32, size: u32, key: vec3<u32>) -> f32 {
    let lp = lattice_point(voxel, cells, size);
    let c0 = lp.cell % vec3<u32>(cells);
    let c1 = (lp.cell + vec3<u32>(1u)) % vec3<u32>(cells);
    let f = lp.frac;
    let g = f - vec3<f32>(1.0);
    let n000 = perlin_corner(vec3<u32>(c0.x, c0.y, c0.z), key, vec3<f32>(f.x, f.y, f.z));
    let n100 = perlin_corner(vec3<u32>(c1.x, c0.y, c0.z), key, vec3<f32>(g.x, f.y, f.z));
    let n010 = perlin_corner(vec3<u32>(c0.x, c1.y, c0.z), key, vec3<f32>(f.x, g.y, f.z));
    let n110 = perlin_corner(vec3<u32>(c1.x, c1.y, c0.z), key, vec3<f32>(g.x, g.y, f.z));
    let n001 = perlin_corner(vec3<u32>(c0.x, c0.y, c1.z), key, vec3<f32>(f.x, f.y, g.z));
    let n101 = perlin_corner(vec3<u32>(c1.x, c0.y, c1.z), key, vec3<f32>(g.x, f.y, g.z));
    let n011 = perlin_corner(vec3<u32>(c0.x, c1.y, c1.z), key, vec3<f32>(f.x, g.y, g.z));
    let n111 = perlin_corner(vec3<u32>(c1.x, c1.y, c1.z), key, vec3<f32>(g.x, g.y, g.z));
    let wx = fade(f.x);
    let wy = fade(f.y);
    let wz = fade(f.z);
    let x00 = lerp(n000, n100, wx);
    let x10 = lerp(n010, n110, wx);
    let x01 = lerp(n001, n101, wx);
    let x11 = lerp(n011, n111, wx);
    return lerp(lerp(x00, x10, wy), lerp(x01, x11, wy), wz);
}

// Perlin FBM in 0..1: PERLIN_OCTAVES octaves from PERLIN_BASE_CELLS cells, each twice the cells
// and half the amplitude of the last, normalised by the amplitudes' sum (1.75), then mapped from
// about −1..1 and clamped. Loops: PERLIN_OCTAVES = 3 iterations.
fn perlin_fbm(seed: u32, voxel: vec3<u32>, size: u32) -> f32 {
    var sum = 0.0;
    var amplitude = 1.0;
    var cells = PERLIN_BASE_CELLS;
    for (var octave = 0u; octave < PERLIN_OCTAVES; octave++) {
        sum += amplitude * perlin_periodic(voxel, cells, size, noise_key(seed, SALT_PERLIN + cells));
        amplitude *= 0.5;
        cells *= 2u;
    }
    return clamp(0.5 + 0.5 * (sum / 1.75), 0.0, 1.0);
}

fn shape_worley(seed: u32, voxel: vec3<u32>, cells: u32) -> f32 {
    return worley_inverted(voxel, cells, SHAPE_SIZE, noise_key(seed, SALT_SHAPE_WORLEY + cells));
}

fn detail_worley(seed: u32, voxel: vec3<u32>, cells: u32) -> f32 {
    return worley_inverted(voxel, cells, DETAIL_SIZE, noise_key(seed, SALT_DETAIL_WORLEY + cells));
}

// One texel of the shape texture: R Perlin–Worley (Perlin FBM dilated by a Worley FBM, GPU Pro 7:
// remap(perlin, 0, 1, worley_fbm, 1)), G B A Worley FBMs at increasing frequencies (000 §3.2.1).
// All four channels are stored, not one pre-combined value, so eq. 11's remap stays in
// `cloud_shape_noise` where it can be tuned and tested, as the thesis samples it (004 B.4).
// Loops: 5 Worley evaluations × 39 + 3 Perlin octaves = 198 iterations.
fn shape_texel(seed: u32, voxel: vec3<u32>) -> vec4<f32> {
    let perlin = perlin_fbm(seed, voxel, SHAPE_SIZE);
    let w8 = shape_worley(seed, voxel, 8u);
    let w16 = shape_worley(seed, voxel, 16u);
    let w32 = shape_worley(seed, voxel, 32u);
    let w56 = shape_worley(seed, voxel, 56u);
    let w64 = shape_worley(seed, voxel, 64u);
    let perlin_worley = remap(perlin, 0.0, 1.0, w8 * 0.625 + w32 * 0.25 + w56 * 0.125, 1.0);
    return vec4<f32>(
        perlin_worley,
        w8 * 0.625 + w16 * 0.25 + w32 * 0.125,
        w16 * 0.625 + w32 * 0.25 + w64 * 0.125,
        // 128 cells would be one per voxel (pure aliasing), so the last FBM has two octaves.
        w32 * 0.75 + w64 * 0.25,
    );
}

// One texel of the detail texture: Worley FBMs at 3 increasing frequencies (003, 000 §3.2.1).
// Loops: 4 Worley evaluations × 39 = 156 iterations.
fn detail_texel(seed: u32, voxel: vec3<u32>) -> vec3<f32> {
    let w2 = detail_worley(seed, voxel, 2u);
    let w4 = detail_worley(seed, voxel, 4u);
    let w8 = detail_worley(seed, voxel, 8u);
    let w16 = detail_worley(seed, voxel, 16u);
    return vec3<f32>(
        w2 * 0.625 + w4 * 0.25 + w8 * 0.125,
        w4 * 0.625 + w8 * 0.25 + w16 * 0.125,
        // 32 cells would be one per voxel, so the last FBM has two octaves.
        w8 * 0.75 + w16 * 0.25,
    );
}

// The coverage map's texel (x, z) (004's weather map WM_c, §3.1.1; the slides' coverage): two
// octaves of periodic Perlin noise across the layer, 4 and 8 cells, pushed through a smoothstep
// from 0.45 to 0.55 (about a third of the map each way) so that the map holds fields of cloud
// (1) and of clear sky (0) with soft borders, as a weather map painted by hand does. Periodic
// over the layer, like the textures.
fn coverage_texel(seed: u32, x: u32, z: u32) -> f32 {
    let voxel = vec3<u32>(x, 0u, z);
    let coarse = perlin_periodic(voxel, COVERAGE_CELLS, COVERAGE_SIZE, noise_key(seed, SALT_COVERAGE));
    let fine = perlin_periodic(voxel, 2u * COVERAGE_CELLS, COVERAGE_SIZE, noise_key(seed, SALT_COVERAGE + 1u));
    let v = clamp(0.5 + 0.5 * (coarse + 0.5 * fine) / 1.5, 0.0, 1.0);
    let t = saturate((v - 0.45) / 0.1);
    return t * t * (3.0 - 2.0 * t);
}

// The coverage map at the layer point's x and z (0..1 across the layer), bilinear between
// texels (texel i at i / COVERAGE_SIZE, repeating), blended towards 1 (no map) by
// `params.coverage_map`.
fn cloud_coverage_map(seed: u32, p_layer: vec3<f32>, params: CloudParams) -> f32 {
    let x = fract(vec2<f32>(p_layer.x, p_layer.z)) * f32(COVERAGE_SIZE);
    let base = floor(x);
    let f = x - base;
    let i = vec2<u32>(base);
    let j = (i + vec2<u32>(1u)) % vec2<u32>(COVERAGE_SIZE);
    let c00 = coverage_texel(seed, i.x, i.y);
    let c10 = coverage_texel(seed, j.x, i.y);
    let c01 = coverage_texel(seed, i.x, j.y);
    let c11 = coverage_texel(seed, j.x, j.y);
    let map = lerp(lerp(c00, c10, f.x), lerp(c01, c11, f.x), f.y);
    return lerp(1.0, map, params.coverage_map);
}

// ---- The density (004 §3.1). Noise samples come in as arguments, so a march can take them from
// the 3D textures (repeat addressing, at `cloud_shape_uvw` / `cloud_detail_uvw`) and the CPU
// mirror from `shape_voxel` / `detail_voxel`.

// World point `p_m` in the layer's box as fractions: x and z across the layer (where a coverage
// map is sampled), y the height fraction p_h of 004 §3.1.3. Inside the layer all three are 0..1.
fn cloud_layer_point(p_m: vec3<f32>, params: CloudParams) -> vec3<f32> {
    return vec3<f32>(
        (p_m.x - params.origin_xz_m.x) / params.size_xz_m.x,
        (p_m.y - params.altitude_m) / params.thickness_m,
        (p_m.z - params.origin_xz_m.y) / params.size_xz_m.y,
    );
}

fn cloud_shape_uvw(p_m: vec3<f32>, params: CloudParams) -> vec3<f32> {
    return p_m / params.shape_period_m;
}

fn cloud_detail_uvw(p_m: vec3<f32>, params: CloudParams) -> vec3<f32> {
    return p_m / params.detail_period_m;
}

// SN_sample (004 eq. 11, B.4): the Perlin–Worley channel remapped by the G B A Worley FBM, which
// carves the edges without eating the cloud's core as a plain FBM would (Schneider 2017).
fn cloud_shape_noise(shape: vec4<f32>) -> f32 {
    let low_frequency_fbm = shape.y * 0.625 + shape.z * 0.25 + shape.w * 0.125;
    return remap(shape.x, low_frequency_fbm - 1.0, 1.0, 0.0, 1.0);
}

// SA (004 eq. 5–7, B.2 without the anvil): 0 at the base, 1 from 7 % of the layer, back to 0 from
// 20 % of the tops to the tops.
fn cloud_shape_height(height_fraction: f32, top_fraction: f32) -> f32 {
    let bottom = saturate(remap(height_fraction, 0.0, 0.07, 0.0, 1.0));
    let top = saturate(remap(height_fraction, top_fraction * 0.2, top_fraction, 1.0, 0.0));
    return bottom * top;
}

// DA / g_d (004 eq. 8–10; the weather map's density w_d taken as 0.5, so its "× 2" is 1): density
// rising with height, softened at the base, faded out over the top tenth.
fn cloud_density_height(height_fraction: f32) -> f32 {
    let bottom = height_fraction * saturate(remap(height_fraction, 0.0, 0.15, 0.0, 1.0));
    let top = saturate(remap(height_fraction, 0.9, 1.0, 1.0, 0.0));
    return bottom * top;
}

// SN_nd (004 eq. 15): the shaped noise with the coverage remap. `coverage` is the coverage map's
// value at p_layer.xz (WM_c, 0..1; 1 without a map); the threshold falls as g_c × WM_c rises.
fn cloud_base_coverage(p_layer: vec3<f32>, shape: vec4<f32>, coverage: f32, params: CloudParams) -> f32 {
    let local_coverage = params.coverage * coverage;
    // Outside the layer there is no cloud; no coverage is no cloud, and also the remap below
    // would divide by zero.
    if any(p_layer < vec3<f32>(0.0)) || any(p_layer > vec3<f32>(1.0)) || local_coverage <= 0.0 {
        return 0.0;
    }
    let shaped = cloud_shape_noise(shape) * cloud_shape_height(p_layer.y, params.top_fraction);
    return saturate(remap(shaped, 1.0 - local_coverage, 1.0, 0.0, 1.0));
}

// The base shape's extinction, 1/m (004 eq. 12): no detail erosion. The final cloud lies inside it
// (`cloud_density` <= this), so a march can take long steps on it alone (004 §3.2).
fn cloud_base_density(p_layer: vec3<f32>, shape: vec4<f32>, coverage: f32, params: CloudParams) -> f32 {
    return cloud_base_coverage(p_layer, shape, coverage, params) * cloud_density_height(p_layer.y)
        * params.density_per_m;
}

// The cloud's extinction, 1/m (004 eq. 13, 14, 16): the base shape eroded by the detail FBM,
// inverted near the base (wispy) and upright above (billowy), by at most 0.35 and less as the
// coverage grows; then the density height gradient and the density scale.
fn cloud_density(p_layer: vec3<f32>, shape: vec4<f32>, detail: vec3<f32>, coverage: f32, params: CloudParams) -> f32 {
    let base = cloud_base_coverage(p_layer, shape, coverage, params);
    if base <= 0.0 {
        return 0.0;
    }
    let detail_fbm = detail.x * 0.625 + detail.y * 0.25 + detail.z * 0.125;
    let erosion = 0.35 * exp(-params.coverage * 0.75)
        * lerp(detail_fbm, 1.0 - detail_fbm, saturate(p_layer.y * 5.0));
    return saturate(remap(base, erosion, 1.0, 0.0, 1.0)) * cloud_density_height(p_layer.y)
        * params.density_per_m;
}
