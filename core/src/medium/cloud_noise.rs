//! Procedural cloud noise and the cloud's density: the CPU mirror, operation for operation, of
//! `shaders/medium/cloud_noise.wgsl` (whose header gives the sources: the slides' texture table in
//! `003_...txt`, the 2022 dissertation's §3.2.1 in `000_...txt`, the 2018 thesis' §3.1 and
//! appendix B in `004_...txt`, and GPU Pro 7's common implementation where they are silent).
//!
//! Two tileable textures, generated from a seed:
//! - shape, [`SHAPE_SIZE`]³ texels of 4 channels: R Perlin–Worley, G B A Worley FBMs;
//! - detail, [`DETAIL_SIZE`]³ texels of 3 channels: Worley FBMs (stored with a fourth, 0, float).
//!
//! and [`cloud_density`], the extinction of a layer of cloud from samples of the two, a coverage
//! value and the layer's [`CloudParams`].
//!
//! Every noise is a function of integers (voxel × cells per period, divided by the texture size),
//! so cells and fractions are exact; the hash is integer-only; the float operations are the
//! shader's in the shader's order (`lerp` spelled out rather than `mix`). What may still differ
//! from a GPU is the last bits of `/`, `sqrt` and `exp`, and fused multiply–adds: about 1e-6 on
//! values of order 1, so a GPU test can hold the two within ~1e-5 per texel.
//!
//! To add a noise: give it a salt of its own (see the `SALT_*` constants), write it in both files,
//! and add it to the tiling and determinism tests in `tests/cloud_noise.rs`. The GPU generators
//! are in [`super::cloud`].

use std::fmt;

use bytemuck::{Pod, Zeroable};
use glam::{UVec3, Vec3, Vec4};

/// The shape texture's size in texels along each axis (its period).
pub const SHAPE_SIZE: u32 = 128;
/// The detail texture's size in texels along each axis (its period).
pub const DETAIL_SIZE: u32 = 32;
/// Floats per texel in the generators' buffers (both textures), so that a buffer copies into an
/// `Rgba32Float` 3D texture.
pub const FLOATS_PER_TEXEL: u32 = 4;

const SALT_SHAPE_WORLEY: u32 = 0x100;
const SALT_PERLIN: u32 = 0x200;
const SALT_DETAIL_WORLEY: u32 = 0x300;

const SALT_COVERAGE: u32 = 0x400;
/// The coverage map's texels along x and z, and its Perlin noise's coarsest cells.
pub const COVERAGE_SIZE: u32 = 256;
const COVERAGE_CELLS: u32 = 4;

const PERLIN_BASE_CELLS: u32 = 8;
const PERLIN_OCTAVES: u32 = 3;

/// The generators' uniform. Keep in sync with `CloudNoiseParams` in shaders/medium/cloud_noise.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct CloudNoiseParams {
    pub seed: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

impl CloudNoiseParams {
    pub fn new(seed: u32) -> Self {
        Self {
            seed,
            ..Self::default()
        }
    }
}

/// The cloud layer: a box in the world (+y up) and how cloudy it is; the scene's fields.
/// Keep in sync with `CloudParams` in shaders/medium/cloud_noise.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct CloudParams {
    /// The layer's smallest x and z, metres.
    pub origin_xz_m: [f32; 2],
    /// The layer's width along x and z, metres; > 0.
    pub size_xz_m: [f32; 2],
    /// The layer's base (world y), metres.
    pub altitude_m: f32,
    /// The layer's thickness along y, metres; > 0.
    pub thickness_m: f32,
    /// The global coverage g_c, 0..1 (004 §3.1.1): 0 no cloud, 1 overcast.
    pub coverage: f32,
    /// Extinction of the densest cloud, 1/m (004's global density g_d, given a unit); >= 0.
    pub density_per_m: f32,
    /// The height fraction the cloud tops reach, (0, 1] (004's weather-map w_h, eq. 6).
    pub top_fraction: f32,
    /// World metres one period of the shape texture spans; > 0.
    pub shape_period_m: f32,
    /// World metres one period of the detail texture spans; > 0.
    pub detail_period_m: f32,
    /// How much the coverage map shapes the layer, 0..1: 0 the layer's coverage everywhere, 1
    /// the map's fields of cloud and clear sky ([`cloud_coverage_map`]).
    pub coverage_map: f32,
}

/// A [`CloudParams`] field out of its range.
#[derive(Clone, Debug, PartialEq)]
pub struct CloudParamsError {
    pub field: &'static str,
    pub value: f32,
    pub allowed: &'static str,
}

impl fmt::Display for CloudParamsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "cloud layer: {} = {} is outside {}",
            self.field, self.value, self.allowed
        )
    }
}

impl std::error::Error for CloudParamsError {}

impl CloudParams {
    /// Checks every field's range: the density functions divide by the sizes, the thickness,
    /// the periods and the top fraction, and assume the coverage in 0..1.
    pub fn validate(&self) -> Result<(), CloudParamsError> {
        let positive = "(0, inf)";
        let checks = [
            (
                "size_xz_m.x",
                self.size_xz_m[0],
                self.size_xz_m[0] > 0.0,
                positive,
            ),
            (
                "size_xz_m.z",
                self.size_xz_m[1],
                self.size_xz_m[1] > 0.0,
                positive,
            ),
            (
                "thickness_m",
                self.thickness_m,
                self.thickness_m > 0.0,
                positive,
            ),
            (
                "coverage",
                self.coverage,
                (0.0..=1.0).contains(&self.coverage),
                "[0, 1]",
            ),
            (
                "coverage_map",
                self.coverage_map,
                (0.0..=1.0).contains(&self.coverage_map),
                "[0, 1]",
            ),
            (
                "density_per_m",
                self.density_per_m,
                self.density_per_m >= 0.0,
                "[0, inf)",
            ),
            (
                "top_fraction",
                self.top_fraction,
                self.top_fraction > 0.0 && self.top_fraction <= 1.0,
                "(0, 1]",
            ),
            (
                "shape_period_m",
                self.shape_period_m,
                self.shape_period_m > 0.0,
                positive,
            ),
            (
                "detail_period_m",
                self.detail_period_m,
                self.detail_period_m > 0.0,
                positive,
            ),
            ("origin_xz_m.x", self.origin_xz_m[0], true, "finite"),
            ("origin_xz_m.z", self.origin_xz_m[1], true, "finite"),
            ("altitude_m", self.altitude_m, true, "finite"),
        ];
        for (field, value, in_range, allowed) in checks {
            // `is_finite` also rejects NaN, which every comparison above lets through as false.
            if !in_range || !value.is_finite() {
                return Err(CloudParamsError {
                    field,
                    value,
                    allowed,
                });
            }
        }
        Ok(())
    }
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![
        crate::mirror_layout!(
            CloudNoiseParams,
            "medium/cloud_noise_gen.wgsl",
            "CloudNoiseParams",
            [seed]
        ),
        crate::mirror_layout!(
            CloudParams,
            "medium/cloud_noise_gen.wgsl",
            "CloudParams",
            [
                origin_xz_m,
                size_xz_m,
                altitude_m,
                thickness_m,
                coverage,
                density_per_m,
                top_fraction,
                shape_period_m,
                detail_period_m,
                coverage_map
            ]
        ),
    ]
}

/// pcg3d (Jarzynski & Olano, JCGT 2020), wrapping as WGSL's u32 does.
fn pcg3d(v: UVec3) -> UVec3 {
    let mut v = v
        .wrapping_mul(UVec3::splat(1664525))
        .wrapping_add(UVec3::splat(1013904223));
    v.x = v.x.wrapping_add(v.y.wrapping_mul(v.z));
    v.y = v.y.wrapping_add(v.z.wrapping_mul(v.x));
    v.z = v.z.wrapping_add(v.x.wrapping_mul(v.y));
    v = UVec3::new(v.x ^ (v.x >> 16), v.y ^ (v.y >> 16), v.z ^ (v.z >> 16));
    v.x = v.x.wrapping_add(v.y.wrapping_mul(v.z));
    v.y = v.y.wrapping_add(v.z.wrapping_mul(v.x));
    v.z = v.z.wrapping_add(v.x.wrapping_mul(v.y));
    v
}

fn noise_key(seed: u32, salt: u32) -> UVec3 {
    pcg3d(UVec3::new(seed, salt, 0x9e3779b9))
}

fn unit_from_bits(bits: u32) -> f32 {
    (bits >> 8) as f32 * (1.0 / 16777216.0)
}

/// A voxel's cell (not yet wrapped) and exact position in it, in a lattice of `cells` per period.
fn lattice_point(voxel: UVec3, cells: u32, size: u32) -> (UVec3, Vec3) {
    let q = voxel * cells;
    let r = q % size;
    let frac = Vec3::new(r.x as f32, r.y as f32, r.z as f32) / size as f32;
    (q / size, frac)
}

fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

fn saturate(v: f32) -> f32 {
    v.clamp(0.0, 1.0)
}

/// Remap `v` from [lo, hi] to [new_lo, new_hi], unclamped (004 eq. 1, appendix B.1).
pub fn remap(v: f32, lo: f32, hi: f32, new_lo: f32, new_hi: f32) -> f32 {
    new_lo + (v - lo) * (new_hi - new_lo) / (hi - lo)
}

/// Inverted Worley noise 1 − F1, F1 clamped to 1 (see the shader's `worley_inverted`).
fn worley_inverted(voxel: UVec3, cells: u32, size: u32, key: UVec3) -> f32 {
    let (cell0, frac) = lattice_point(voxel, cells, size);
    let mut nearest_sq = 1.0f32;
    for dz in 0..3u32 {
        for dy in 0..3u32 {
            for dx in 0..3u32 {
                let offset = UVec3::new(dx, dy, dz);
                let cell = (cell0 + offset + UVec3::splat(cells - 1)) % cells;
                let h = pcg3d(cell.wrapping_add(key));
                let jitter = Vec3::new(
                    unit_from_bits(h.x),
                    unit_from_bits(h.y),
                    unit_from_bits(h.z),
                );
                let d = offset.as_vec3() - Vec3::ONE + jitter - frac;
                nearest_sq = nearest_sq.min(d.x * d.x + d.y * d.y + d.z * d.z);
            }
        }
    }
    1.0 - nearest_sq.sqrt()
}

fn perlin_gradient_dot(bits: u32, d: Vec3) -> f32 {
    let g = bits >> 28;
    let u = if g < 8 { d.x } else { d.y };
    let v = if g < 4 {
        d.y
    } else if g == 12 || g == 14 {
        d.x
    } else {
        d.z
    };
    (if g & 1 == 0 { u } else { -u }) + (if g & 2 == 0 { v } else { -v })
}

fn perlin_corner(c: UVec3, key: UVec3, d: Vec3) -> f32 {
    perlin_gradient_dot(pcg3d(c.wrapping_add(key)).x, d)
}

fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

fn perlin_periodic(voxel: UVec3, cells: u32, size: u32, key: UVec3) -> f32 {
    let (cell, f) = lattice_point(voxel, cells, size);
    let c0 = cell % cells;
    let c1 = (cell + UVec3::ONE) % cells;
    let g = f - Vec3::ONE;
    let corner = |x: u32, y: u32, z: u32, d: Vec3| perlin_corner(UVec3::new(x, y, z), key, d);
    let n000 = corner(c0.x, c0.y, c0.z, Vec3::new(f.x, f.y, f.z));
    let n100 = corner(c1.x, c0.y, c0.z, Vec3::new(g.x, f.y, f.z));
    let n010 = corner(c0.x, c1.y, c0.z, Vec3::new(f.x, g.y, f.z));
    let n110 = corner(c1.x, c1.y, c0.z, Vec3::new(g.x, g.y, f.z));
    let n001 = corner(c0.x, c0.y, c1.z, Vec3::new(f.x, f.y, g.z));
    let n101 = corner(c1.x, c0.y, c1.z, Vec3::new(g.x, f.y, g.z));
    let n011 = corner(c0.x, c1.y, c1.z, Vec3::new(f.x, g.y, g.z));
    let n111 = corner(c1.x, c1.y, c1.z, Vec3::new(g.x, g.y, g.z));
    let (wx, wy, wz) = (fade(f.x), fade(f.y), fade(f.z));
    let x00 = lerp(n000, n100, wx);
    let x10 = lerp(n010, n110, wx);
    let x01 = lerp(n001, n101, wx);
    let x11 = lerp(n011, n111, wx);
    lerp(lerp(x00, x10, wy), lerp(x01, x11, wy), wz)
}

fn perlin_fbm(seed: u32, voxel: UVec3, size: u32) -> f32 {
    let mut sum = 0.0f32;
    let mut amplitude = 1.0f32;
    let mut cells = PERLIN_BASE_CELLS;
    for _ in 0..PERLIN_OCTAVES {
        sum +=
            amplitude * perlin_periodic(voxel, cells, size, noise_key(seed, SALT_PERLIN + cells));
        amplitude *= 0.5;
        cells *= 2;
    }
    (0.5 + 0.5 * (sum / 1.75)).clamp(0.0, 1.0)
}

fn shape_worley(seed: u32, voxel: UVec3, cells: u32) -> f32 {
    worley_inverted(
        voxel,
        cells,
        SHAPE_SIZE,
        noise_key(seed, SALT_SHAPE_WORLEY + cells),
    )
}

fn detail_worley(seed: u32, voxel: UVec3, cells: u32) -> f32 {
    worley_inverted(
        voxel,
        cells,
        DETAIL_SIZE,
        noise_key(seed, SALT_DETAIL_WORLEY + cells),
    )
}

/// Shape texel (x, y, z) for `seed`: [Perlin–Worley, Worley FBM at 8, 16, 32 cells, at 16, 32,
/// 64, at 32, 64], each in 0..1. Periodic with period [`SHAPE_SIZE`] on every axis; any
/// coordinate is accepted (x · 64 must fit a u32: x below 67 million).
pub fn shape_voxel(seed: u32, x: u32, y: u32, z: u32) -> [f32; 4] {
    let voxel = UVec3::new(x, y, z);
    let perlin = perlin_fbm(seed, voxel, SHAPE_SIZE);
    let w8 = shape_worley(seed, voxel, 8);
    let w16 = shape_worley(seed, voxel, 16);
    let w32 = shape_worley(seed, voxel, 32);
    let w56 = shape_worley(seed, voxel, 56);
    let w64 = shape_worley(seed, voxel, 64);
    let perlin_worley = remap(perlin, 0.0, 1.0, w8 * 0.625 + w32 * 0.25 + w56 * 0.125, 1.0);
    [
        perlin_worley,
        w8 * 0.625 + w16 * 0.25 + w32 * 0.125,
        w16 * 0.625 + w32 * 0.25 + w64 * 0.125,
        w32 * 0.75 + w64 * 0.25,
    ]
}

/// Detail texel (x, y, z) for `seed`: Worley FBMs at 2, 4, 8 cells, at 4, 8, 16, at 8, 16; each
/// in 0..1. Periodic with period [`DETAIL_SIZE`] on every axis.
pub fn detail_voxel(seed: u32, x: u32, y: u32, z: u32) -> [f32; 3] {
    let voxel = UVec3::new(x, y, z);
    let w2 = detail_worley(seed, voxel, 2);
    let w4 = detail_worley(seed, voxel, 4);
    let w8 = detail_worley(seed, voxel, 8);
    let w16 = detail_worley(seed, voxel, 16);
    [
        w2 * 0.625 + w4 * 0.25 + w8 * 0.125,
        w4 * 0.625 + w8 * 0.25 + w16 * 0.125,
        w8 * 0.75 + w16 * 0.25,
    ]
}

/// The whole shape texture in `shape_main`'s buffer layout (x fastest, 4 floats a texel): what
/// a GPU test compares against, or what to upload where compute is unavailable.
pub fn shape_texels(seed: u32) -> Vec<f32> {
    texels(SHAPE_SIZE, |x, y, z| shape_voxel(seed, x, y, z))
}

/// The whole detail texture in `detail_main`'s buffer layout (x fastest, 4 floats a texel, the
/// fourth 0).
pub fn detail_texels(seed: u32) -> Vec<f32> {
    texels(DETAIL_SIZE, |x, y, z| {
        let [r, g, b] = detail_voxel(seed, x, y, z);
        [r, g, b, 0.0]
    })
}

fn texels(size: u32, texel: impl Fn(u32, u32, u32) -> [f32; 4]) -> Vec<f32> {
    let mut out = Vec::with_capacity((size * size * size * FLOATS_PER_TEXEL) as usize);
    for z in 0..size {
        for y in 0..size {
            for x in 0..size {
                out.extend_from_slice(&texel(x, y, z));
            }
        }
    }
    out
}

/// World point `p_m` in the layer's box as fractions: x and z across the layer (where a coverage
/// map is sampled), y the height fraction. Inside the layer all three are in 0..1.
pub fn cloud_layer_point(p_m: Vec3, params: &CloudParams) -> Vec3 {
    Vec3::new(
        (p_m.x - params.origin_xz_m[0]) / params.size_xz_m[0],
        (p_m.y - params.altitude_m) / params.thickness_m,
        (p_m.z - params.origin_xz_m[1]) / params.size_xz_m[1],
    )
}

/// The shape texture's coordinates (repeat addressing) at world point `p_m`.
pub fn cloud_shape_uvw(p_m: Vec3, params: &CloudParams) -> Vec3 {
    p_m / params.shape_period_m
}

/// The detail texture's coordinates (repeat addressing) at world point `p_m`.
pub fn cloud_detail_uvw(p_m: Vec3, params: &CloudParams) -> Vec3 {
    p_m / params.detail_period_m
}

/// SN_sample (004 eq. 11): the Perlin–Worley channel remapped by the G B A Worley FBM.
pub fn cloud_shape_noise(shape: Vec4) -> f32 {
    let low_frequency_fbm = shape.y * 0.625 + shape.z * 0.25 + shape.w * 0.125;
    remap(shape.x, low_frequency_fbm - 1.0, 1.0, 0.0, 1.0)
}

/// SA (004 eq. 5–7): the shape's height gradient, 0 at the base and from the tops up.
pub fn cloud_shape_height(height_fraction: f32, top_fraction: f32) -> f32 {
    let bottom = saturate(remap(height_fraction, 0.0, 0.07, 0.0, 1.0));
    let top = saturate(remap(
        height_fraction,
        top_fraction * 0.2,
        top_fraction,
        1.0,
        0.0,
    ));
    bottom * top
}

/// DA / g_d (004 eq. 8–10, w_d = 0.5): the density's height gradient, 0 at base and top.
pub fn cloud_density_height(height_fraction: f32) -> f32 {
    let bottom = height_fraction * saturate(remap(height_fraction, 0.0, 0.15, 0.0, 1.0));
    let top = saturate(remap(height_fraction, 0.9, 1.0, 1.0, 0.0));
    bottom * top
}

/// SN_nd (004 eq. 15): the shaped noise after the coverage remap, 0..1; 0 outside the layer
/// and where `params.coverage × coverage` is 0. `coverage` is the coverage map at p_layer.xz.
pub fn cloud_base_coverage(p_layer: Vec3, shape: Vec4, coverage: f32, params: &CloudParams) -> f32 {
    let local_coverage = params.coverage * coverage;
    if p_layer.cmplt(Vec3::ZERO).any() || p_layer.cmpgt(Vec3::ONE).any() || local_coverage <= 0.0 {
        return 0.0;
    }
    let shaped = cloud_shape_noise(shape) * cloud_shape_height(p_layer.y, params.top_fraction);
    saturate(remap(shaped, 1.0 - local_coverage, 1.0, 0.0, 1.0))
}

/// The base shape's extinction, 1/m (004 eq. 12), before detail erosion; bounds
/// [`cloud_density`] from above.
pub fn cloud_base_density(p_layer: Vec3, shape: Vec4, coverage: f32, params: &CloudParams) -> f32 {
    cloud_base_coverage(p_layer, shape, coverage, params)
        * cloud_density_height(p_layer.y)
        * params.density_per_m
}

/// The cloud's extinction, 1/m (004 eq. 13, 14, 16), at layer point `p_layer`
/// ([`cloud_layer_point`]) from a shape sample (RGBA), a detail sample (RGB) and the coverage
/// map's value there (0..1; 1 without a map). In 0..`params.density_per_m`.
pub fn cloud_density(
    p_layer: Vec3,
    shape: Vec4,
    detail: Vec3,
    coverage: f32,
    params: &CloudParams,
) -> f32 {
    let base = cloud_base_coverage(p_layer, shape, coverage, params);
    if base <= 0.0 {
        return 0.0;
    }
    let detail_fbm = detail.x * 0.625 + detail.y * 0.25 + detail.z * 0.125;
    let erosion = 0.35
        * (-params.coverage * 0.75).exp()
        * lerp(detail_fbm, 1.0 - detail_fbm, saturate(p_layer.y * 5.0));
    saturate(remap(base, erosion, 1.0, 0.0, 1.0))
        * cloud_density_height(p_layer.y)
        * params.density_per_m
}

/// The coverage map's texel (x, z): the mirror of `coverage_texel` in
/// shaders/medium/cloud_noise.wgsl (004's weather map WM_c, fields of cloud and clear sky).
pub fn coverage_texel(seed: u32, x: u32, z: u32) -> f32 {
    let voxel = UVec3::new(x, 0, z);
    let coarse = perlin_periodic(
        voxel,
        COVERAGE_CELLS,
        COVERAGE_SIZE,
        noise_key(seed, SALT_COVERAGE),
    );
    let fine = perlin_periodic(
        voxel,
        2 * COVERAGE_CELLS,
        COVERAGE_SIZE,
        noise_key(seed, SALT_COVERAGE + 1),
    );
    let v = (0.5 + 0.5 * (coarse + 0.5 * fine) / 1.5).clamp(0.0, 1.0);
    let t = saturate((v - 0.45) / 0.1);
    t * t * (3.0 - 2.0 * t)
}

/// The coverage map at the layer point's x and z, bilinear and repeating, blended towards 1 by
/// `params.coverage_map`: the mirror of `cloud_coverage_map`.
pub fn cloud_coverage_map(seed: u32, p_layer: Vec3, params: &CloudParams) -> f32 {
    let fract = |v: f32| v - v.floor();
    let x = glam::Vec2::new(fract(p_layer.x), fract(p_layer.z)) * COVERAGE_SIZE as f32;
    let base = x.floor();
    let f = x - base;
    let i = base.as_uvec2();
    let j = (i + glam::UVec2::ONE) % COVERAGE_SIZE;
    let c00 = coverage_texel(seed, i.x, i.y);
    let c10 = coverage_texel(seed, j.x, i.y);
    let c01 = coverage_texel(seed, i.x, j.y);
    let c11 = coverage_texel(seed, j.x, j.y);
    let map = lerp(lerp(c00, c10, f.x), lerp(c01, c11, f.x), f.y);
    lerp(1.0, map, params.coverage_map)
}

/// The noise at `uvw` (one period per unit, repeating) from a texture of `size`³ texels given by
/// `texel(x, y, z)`, trilinear between texels: texel i holds the noise at i / size. The mirror
/// of `sample_repeat` in shaders/medium/cloud_bake.wgsl, operation for operation.
pub fn sample_repeat(uvw: Vec3, size: u32, texel: impl Fn(u32, u32, u32) -> Vec4) -> Vec4 {
    let x = uvw * size as f32;
    let base = x.floor();
    let f = x - base;
    let n = size as i32;
    let i = base.as_ivec3();
    let at = |dx: i32, dy: i32, dz: i32| {
        let w = |v: i32| (((v % n) + n) % n) as u32;
        texel(w(i.x + dx), w(i.y + dy), w(i.z + dz))
    };
    let x00 = at(0, 0, 0) + (at(1, 0, 0) - at(0, 0, 0)) * f.x;
    let x10 = at(0, 1, 0) + (at(1, 1, 0) - at(0, 1, 0)) * f.x;
    let x01 = at(0, 0, 1) + (at(1, 0, 1) - at(0, 0, 1)) * f.x;
    let x11 = at(0, 1, 1) + (at(1, 1, 1) - at(0, 1, 1)) * f.x;
    let y0 = x00 + (x10 - x00) * f.y;
    let y1 = x01 + (x11 - x01) * f.y;
    y0 + (y1 - y0) * f.z
}

/// The cloud's extinction (1/m) at world point `p_m`, as `bake_main` in
/// shaders/medium/cloud_bake.wgsl computes it from the seed's noise textures and coverage map:
/// the CPU mirror a baked voxel is checked against.
pub fn baked_density(seed: u32, p_m: Vec3, params: &CloudParams) -> f32 {
    baked_density_drifted(seed, p_m, params, Vec3::ZERO)
}

/// [`baked_density`] with the noise and the coverage map carried by `drift_m` (the wind's, at
/// some time): sampled at `p_m − drift_m`, inside the layer's box where it stands.
pub fn baked_density_drifted(seed: u32, p_m: Vec3, params: &CloudParams, drift_m: Vec3) -> f32 {
    let q = p_m - drift_m;
    let shape = sample_repeat(cloud_shape_uvw(q, params), SHAPE_SIZE, |x, y, z| {
        Vec4::from_array(shape_voxel(seed, x, y, z))
    });
    let detail = sample_repeat(cloud_detail_uvw(q, params), DETAIL_SIZE, |x, y, z| {
        Vec3::from_array(detail_voxel(seed, x, y, z)).extend(0.0)
    });
    let coverage = cloud_coverage_map(seed, cloud_layer_point(q, params), params);
    cloud_density(
        cloud_layer_point(p_m, params),
        shape,
        detail.truncate(),
        coverage,
        params,
    )
}

#[cfg(test)]
mod tests {
    //! The raw noises, below the texture channels: Worley against a brute-force periodic search
    //! and its range, Perlin on its lattice and its bound.

    use super::*;

    fn voxels(size: u32, count: usize, mut state: u64) -> Vec<UVec3> {
        let mut below = move |n: u32| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 33) as u32) % n
        };
        (0..count)
            .map(|_| UVec3::new(below(size), below(size), below(size)))
            .collect()
    }

    /// 1 − F1 by brute force: every cell's feature point in the period, each at its nearest
    /// periodic image. Independent of the 27-cell search's neighbour offsets and wrapping.
    fn worley_brute(voxel: UVec3, cells: u32, size: u32, key: UVec3) -> f32 {
        let p = voxel.as_vec3() * cells as f32 / size as f32;
        let period = cells as f32;
        let mut nearest_sq = f32::MAX;
        for z in 0..cells {
            for y in 0..cells {
                for x in 0..cells {
                    let c = UVec3::new(x, y, z);
                    let h = pcg3d(c.wrapping_add(key));
                    let feature = c.as_vec3()
                        + Vec3::new(
                            unit_from_bits(h.x),
                            unit_from_bits(h.y),
                            unit_from_bits(h.z),
                        );
                    let d = feature - p;
                    let d = d - period * (d / period).round();
                    nearest_sq = nearest_sq.min(d.length_squared());
                }
            }
        }
        1.0 - nearest_sq.min(1.0).sqrt()
    }

    /// The 27-cell search finds the true nearest feature point almost always: it can only miss
    /// one (so it is never above the brute force), and only where the nearest point lies two
    /// cells away, a few voxels in a thousand for a jittered grid. 1e-5: the two compute the
    /// same distance by different float paths (fraction vs. scaled position).
    #[test]
    fn worley_agrees_with_a_brute_force_periodic_search() {
        // Up to 16 cells: brute force costs cells³ per voxel.
        for (cells, size) in [
            (2, DETAIL_SIZE),
            (4, DETAIL_SIZE),
            (8, SHAPE_SIZE),
            (16, DETAIL_SIZE),
        ] {
            let key = noise_key(9, SALT_DETAIL_WORLEY + cells);
            let vs = voxels(size, 1500, u64::from(cells));
            let mut agree = 0;
            for &v in &vs {
                let (fast, brute) = (
                    worley_inverted(v, cells, size, key),
                    worley_brute(v, cells, size, key),
                );
                assert!(
                    fast <= brute + 1e-5,
                    "{cells} cells at {v}: {fast} > {brute}"
                );
                agree += usize::from((fast - brute).abs() < 1e-5);
            }
            assert!(
                agree * 100 >= vs.len() * 99,
                "{cells} cells: {agree} of {} agree",
                vs.len()
            );
        }
    }

    /// Worley's F1 covers most of 0..1 over a texture: near 1 at the feature points, near 0 in
    /// the far corners between them (measured over these samples: about 0.02..0.99).
    #[test]
    fn worley_covers_most_of_the_unit_interval() {
        for cells in [4, 8, 16] {
            let key = noise_key(1, SALT_SHAPE_WORLEY + cells);
            let values: Vec<f32> = voxels(SHAPE_SIZE, 3000, 5)
                .into_iter()
                .map(|v| worley_inverted(v, cells, SHAPE_SIZE, key))
                .collect();
            let min = values.iter().copied().fold(f32::MAX, f32::min);
            let max = values.iter().copied().fold(f32::MIN, f32::max);
            assert!(min >= 0.0 && max <= 1.0, "{cells} cells: {min}..{max}");
            assert!(min < 0.2 && max > 0.9, "{cells} cells: {min}..{max}");
        }
    }

    /// Gradient noise is exactly 0 at its lattice points (every corner's offset is 0 or its
    /// weight is fade(0) = 0); improved noise stays within about ±1 (its bound, a little over 1
    /// in 3D; these samples reach 0.77), with a spread well above the FBM's needs (sd 0.26).
    #[test]
    fn perlin_vanishes_on_its_lattice_and_is_bounded() {
        let key = noise_key(3, SALT_PERLIN + 8);
        // 8 cells on 128 texels: a lattice point every 16 texels.
        for v in voxels(8, 200, 1) {
            assert_eq!(
                perlin_periodic(v * 16, 8, SHAPE_SIZE, key),
                0.0,
                "at {}",
                v * 16
            );
        }
        let values: Vec<f32> = voxels(SHAPE_SIZE, 4000, 2)
            .into_iter()
            .map(|v| perlin_periodic(v, 8, SHAPE_SIZE, key))
            .collect();
        let max_abs = values.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let n = values.len() as f32;
        let mean = values.iter().sum::<f32>() / n;
        let sd = (values.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / n).sqrt();
        assert!(max_abs <= 1.05, "max |n| {max_abs}");
        assert!(sd > 0.1, "sd {sd}");
    }
}
