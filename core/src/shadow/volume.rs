//! `volume`: an extinction volume marched towards the light — the secondary ray marching of the
//! 2022 dissertation (seeds/000, chapter 3.2.3, Algorithm 2; its ground truth was 1000-step
//! marching), and the world-space extinction volumes Frostbite and Unreal use for translucency.
//!
//! **Voxelise.** A world-space, axis-aligned grid of G³ half floats covers the smoke's bounds
//! (the particle spheres' AABB, computed on the CPU from the frame's instances), widened by one
//! voxel on every side so that the border voxels are empty: clamp-to-edge sampling then reads 0
//! outside the smoke. Voxels are G per axis over each axis' extent, so they are boxes, not
//! cubes. Each voxel holds the extinction at its centre ([`SUBSAMPLES_PER_AXIS`]³ = 1 point):
//! a point sample, as every shadow map's texel holds the chord through its centre, so no
//! technique prefilters (the report states the policy). The grid held a box-filtered mean of
//! 2×2×2 sub-samples until the policy was made one: on thesis_plume that measured FLIP 0.0016 /
//! 0.0021 / 0.0029 at 48 / 24 / 12 bytes a texel, the point samples 0.0016 / 0.0021 / 0.0027
//! (a particle smaller than a voxel may now fall between centres, as one smaller than a texel
//! may fall between a map's rays).
//!
//! **Which extinction.** The particle model (common/particle.wgsl, [`super::closed_form`]) is
//! not a field in space: a ray passing a particle's centre at distance d sees τ(1 − d/r),
//! constant along its chord, so the density at a point depends on the ray through it. Read as
//! a field of the distance from the centre, τ(1 − |x − c|/r) integrates to half the model's
//! optical depth through the centre (measured: RMS T error 0.135 on one sphere). The grid holds
//! one of two fields, `volume_light_aligned`:
//! - 0 (the design): [`radial_extinction`], the spherically symmetric field
//!   whose integral along *every* line through the sphere is the model's whole-chord optical
//!   depth 2τ(1 − d/r)√(r² − d²) (its inverse Abel transform, in complete elliptic integrals).
//!   It does not depend on the light, so one grid could serve several lights, and T behind a
//!   particle is the model's; inside one it differs (the field peaks at the centre and is 0 at
//!   the surface, where the model is constant along the chord).
//! - 1 (the default, chosen by `smokeshadow tune` on the training scenes): the model's
//!   extinction along this light's rays, τ(1 − d/r) with d the distance from the centre to the
//!   light ray through the point: T matches the model inside particles too, but the grid serves
//!   this light only.
//!
//! Measured on thesis_plume (512², K = 64; RMS T error against `exact` over the shaded points):
//! the light-independent field 0.0210-0.0213 at every budget 6-24 (the model difference inside
//! particles, not the grid, dominates, so it does not converge with the budget); the
//! light-aligned one 0.0042 (6), 0.0035 (8), 0.0023 (16), 0.0018 (24).
//!
//! The budget sets the grid: G = round(cbrt(res² · B)), so the grid's G³ · 2 bytes match the
//! B half-float channels of a res² map as closely as an integer G allows (185³ at 512² and 24
//! channels: 12.66 MB against 12.58 MB).
//!
//! **Build.** Scatter, then convert (shaders/shadow/volume_build.wgsl):
//! 1. The CPU finds the bounds, and per particle its box of voxels and the number of voxel rows
//!    (runs along x) the box holds; their prefix sum numbers every (particle, row) pair of the
//!    frame, and a table gives the particle of every 256th row ([`VoxelPlan::row_blocks`]). One
//!    invocation per pair finds its particle by binary search among those of its block of 256
//!    rows (at most 9 steps; the whole list's search took 21 ms of a 311 ms build), skips a row that
//!    misses the sphere, and walks only the voxels of its row that the sphere reaches, adding
//!    each voxel's sample in fixed point to a u32 scratch grid with `atomicAdd`. Integer addition
//!    is associative, so the grid does not depend on the order of the particles or of the
//!    atomics (`order_independent`). An invocation loops over at most G ≤ 1023 voxels of
//!    one sample each (under 10,250 iterations at the 8 sub-samples it once took with the search, every loop's exit counted),
//!    far inside llvmpipe's 65,535.
//!    Each field has its own entry point: llvmpipe evaluates both sides of a branch under a
//!    mask, even a uniform one, and evaluating both fields per sub-sample cost 1.6 times the
//!    CPU time per frame. (Cutting the rows into bricks of up to 4,096 voxels, one workgroup
//!    each with its lanes striding over the voxels, was 1.4 times slower than one row per
//!    invocation; a 4,096-entry table of the radial field read from a storage buffer took about
//!    twice the time of evaluating it.)
//!    The fixed-point scale is 2^14 units per 1/m, lowered by powers of two when the particle
//!    count times the largest τ (times the radial field's peak) could carry a voxel's sum past
//!    2^32, so no sum can wrap.
//! 2. A second pass converts the sums to half floats, two voxels a word, into a staging buffer
//!    with rows padded to 256 bytes, copied into the R16Float 3D texture. It adds the scene's
//!    density volume's sample where it has one, in an entry point of its own: sampling no volume
//!    under llvmpipe's mask took 75 ms of the 311 ms build at 185³ (thesis frame, now 230).
//!
//! The scratch and staging cover a slab of z-slices that fits one storage binding (the whole
//! grid up to G = 322 with 128 MiB bindings); a larger grid is built slab by slab. Both, the
//! per-particle jobs and the build uniforms are transient: counted and reported apart (at 512²
//! and 24 channels 43 MB beside the 12.7 MB grid). A grid above G = 1023 (voxel indices are
//! packed in 10 bits) or the adapter's 3D texture limit is refused in one line.
//!
//! **March.** The lookup (shaders/shadow/volume.wgsl) clips the segment from p to the light to
//! the grid's box and takes K (`volume_steps`) samples at the midpoints of K equal steps across
//! it, trilinear (R16Float is filterable), T = exp(−Σ σ_i Δs). The march beyond the box adds
//! nothing (there is no smoke), and a point outside the box on the far side still marches
//! through it. The steps are spread over the part of the segment inside the box, so every
//! occluder is sampled, but the longer that part, the longer the steps: an occluder far from
//! the receiver lies at the end of a long segment and is sampled at a coarse step, and a thin
//! one can fall between samples (the dissertation's finding that few samples miss distant
//! occluders; tests/volume.rs measures it). K = 64 by default: on thesis_plume at 24 channels
//! the RMS T error is 0.0507, 0.0259, 0.0220, 0.0212, 0.0211, 0.0210 at K = 8, 16, 32, 64, 128,
//! 256 (light-aligned: 0.0290, 0.0090, 0.0030, 0.0018, 0.0017, 0.0017), so 64 is within 6% of
//! the error of 256 steps in both fields, and 32 is not.
//!
//! The march loops K ≤ 512 times per lookup (four lookups per particle-lighting invocation: at
//! most 2,048 iterations). The viewer's inspector shows no channels: a 3D texture has no 2D view.
//!
//! **Cost** on lavapipe (thesis_plume at 1024x768, one of two shared CPU cores, median wall time
//! of a frame): `none` 290 ms, `osm` at 24 channels 336, `volume` 1,614 at 24 channels (185³)
//! and 588 at 6 (116³); the scatter grows with the voxels and is most of it, the march adds
//! 90 ms at K = 64 and 245 at K = 256. lavapipe runs the scatter before its pass's
//! own begin timestamp; the timer charges it to the pass all the same (gpu/timing.rs), so the
//! `shadow` time holds it.

use super::GpuFuture;
use bytemuck::{Pod, Zeroable};

use super::layered::sampler_entry;
use super::{
    BuildInputs, LOOKUP_STAGES, MemoryUse, ParamSpec, Role, ShadowError, ShadowTechnique,
    TechniqueContext, TechniqueEntry, TechniqueParams,
};
use crate::frame::gpu_data::ParticleInstance;
use crate::gpu::uniform_entry;
use crate::gpu::{
    AllocationError, Gpu, MemoryLedger, bind_entry, storage_descriptor, storage_entry,
};
use crate::shaders;

/// `volume_steps`: samples of the march.
pub const STEPS: ParamSpec = ParamSpec {
    key: "volume_steps",
    unit: "-",
    doc: "samples K of the march from the point towards the light across the grid (rounded to \
          an integer): more find thin and distant occluders, at K texture reads per lookup",
    min: 1.0,
    max: 512.0,
    default: Some(DEFAULT_STEPS as f32),
    choices: &[],
    integer: true,
    tuned: true,
};

/// `volume_light_aligned`: which field the grid holds.
pub const LIGHT_ALIGNED: ParamSpec = ParamSpec {
    key: "volume_light_aligned",
    unit: "-",
    doc: "no: a light-independent field whose every whole chord matches the particle model \
          (one grid could serve several lights); yes: the model's extinction along this \
          light's rays, τ(1 - d/r) with d from the light ray (exact inside particles too; the \
          grid serves this light only)",
    min: 0.0,
    max: 1.0,
    // Yes, chosen by `smokeshadow tune` on the training scenes (docs/tuned_params.toml).
    default: Some(1.0),
    choices: &["no", "yes"],
    integer: false,
    tuned: true,
};

/// The default K, chosen by `smokeshadow tune` on the training scenes (docs/tuned_params.toml).
const DEFAULT_STEPS: u32 = 164;

/// Sub-samples per axis of a voxel's value: 1, its centre (a point sample, as a map's texel is).
/// Keep in sync with `VOLUME_SUBSAMPLES` in shaders/shadow/volume_build.wgsl.
pub const SUBSAMPLES_PER_AXIS: u32 = 1;

/// Fixed-point units per 1/m of extinction in the scratch grid, at most.
pub const MAX_UNITS_PER_EXTINCTION: f32 = 16384.0;

/// The largest value of [`radial_extinction`] the shader evaluates: at ρ² = 1e-12 (its floor),
/// (π − 1.2274 + 27.631) / π = 9.40.
const RADIAL_PEAK: f64 = 9.5;

/// The particle model's extinction as a field in space, per unit τ, at `rho2` = (distance from
/// the centre / radius)²: f = 1 − (4E(m) − 2K(m))/π with m = 1 − ρ² (complete elliptic integrals
/// of the first and second kind), 0 outside. It is the inverse Abel transform of the model's
/// optical depth along a line at distance d from the centre, 2τ(1 − d/r)·sqrt(r² − d²), so every
/// line through the sphere, from any light, integrates it to exactly that. K and E are
/// Abramowitz & Stegun 17.3.34 and 17.3.36 (error ≤ 2e-8) in m1 = ρ², which carry the centre's
/// logarithmic peak explicitly. The CPU mirror of `radial_extinction` in volume_build.wgsl
/// (the same coefficients, in f64).
pub fn radial_extinction(rho2: f64) -> f64 {
    let m1 = rho2.clamp(1e-12, 1.0);
    let poly = |c: [f64; 5]| c.iter().rev().fold(0.0, |acc, &ci| acc * m1 + ci);
    // 4E − 2K = c(m1) − e(m1) ln m1, from A&S 17.3.36 (E) and 17.3.34 (K), coefficient by
    // coefficient: c_i = 4 a_i(E) − 2 a_i(K), e_i = 4 b_i(E) − 2 b_i(K).
    let c = poly([
        1.227_411_277_76,
        1.579_678_773_34,
        0.178_622_201_14,
        0.115_444_067_58,
        0.040_436_333_8,
    ]);
    let e = poly([
        -1.0,
        0.749_962_860_46,
        0.230_402_229_96,
        0.096_220_794_12,
        0.012_222_245_32,
    ]);
    (1.0 - (c - e * m1.ln()) / std::f64::consts::PI).max(0.0)
}

/// The smallest grid (one empty voxel each side of two).
const MIN_SIDE: u32 = 4;
/// The largest: voxel indices are packed in 10 bits.
const MAX_SIDE: u32 = 1023;

/// Bytes of one particle's job (`VolumeJob`).
const JOB_BYTES: u64 = std::mem::size_of::<VolumeJob>() as u64;
/// Bytes of the lookup's uniform (`VolumeParams`).
const LOOKUP_BYTES: u64 = std::mem::size_of::<VolumeParams>() as u64;
/// Bytes of one slab's build uniform (`VolumeBuild`).
const BUILD_BYTES: u64 = std::mem::size_of::<VolumeBuild>() as u64;
/// Jobs the buffer holds at first.
const MIN_JOB_CAPACITY: u32 = 1024;
/// Rows of the scatter per entry of the row-block table ([`VoxelPlan::row_blocks`]);
/// `VOLUME_ROWS_PER_BLOCK` in shaders/shadow/volume_build.wgsl.
pub const ROWS_PER_BLOCK: u32 = 256;
/// Entries the row-block table holds at first (u32 each).
const MIN_BLOCK_CAPACITY: u32 = 1024;

/// The build shader, composed.
fn build_shader() -> String {
    shaders::compose("shadow/volume_build.wgsl", &[])
}

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: "volume",
    description: "extinction volume: a world-space grid of res²·B half floats, marched towards \
                  the light in K trilinear steps",
    role: Role::Contender,
    budget_caption: |channels| {
        format!(
            "res²·{channels} voxels ({}³ at 512²)",
            grid_side(512, channels)
        )
    },
    min_channels: 1,
    max_channels: super::MAX_CHANNELS,
    in_default_sweep: true,
    in_default_compare: true,
    build_reads_back: false,
    params: &[STEPS, LIGHT_ALIGNED],
    order_independent: true,
    // The default light-aligned field converges (0.0042 at 6 channels to 0.0018 at 24 on
    // thesis_plume, see the header); the light-independent one stays at 0.021 from 6 to 24.
    converges_with_budget: true,
    converges_from: 1,
    compresses_captured_lists: false,
    // The R16F grid (G³ · 2 bytes, G = round(cbrt(res² · B))) and the 32-byte lookup uniform;
    // transient: per slab a 64-byte uniform, the u32 scratch and the padded f16 staging of one
    // slab (`slab_scratch_bytes`), 32 bytes per job of capacity and 4 per entry of the row-block
    // table's. Before a build (no counters) it plans the least the build can take: slabs of one
    // z-slice, a job a particle and the row-block table's first capacity (it grows by a few
    // bytes a particle where the limit leaves room; else every slab scatters by job, which
    // needs no table).
    memory: |c| {
        let g = grid_side(c.resolution_px(), c.channels());
        let planned = c.counters.is_empty();
        let depth = match planned {
            true => 1,
            false => c.counter("slab_depth") as u32,
        };
        let slabs = match depth {
            0 => 0,
            d => slab_scratch_bytes(g, d),
        };
        let (jobs, blocks) = match planned {
            true => (
                c.particles.max(MIN_JOB_CAPACITY.into()),
                MIN_BLOCK_CAPACITY.into(),
            ),
            false => (c.counter("job_capacity"), c.counter("block_capacity")),
        };
        let transient = slabs + jobs * JOB_BYTES + blocks * 4;
        let g = u64::from(g);
        MemoryUse {
            channels: c.channels().into(),
            bytes: g * g * g * 2 + LOOKUP_BYTES + transient,
            transient_bytes: transient,
        }
    },
    lookup_shader: "shadow/volume.wgsl",
    lookup_constants: super::no_lookup_constants,
    extra_shaders: || vec![("volume.build".to_owned(), build_shader())],
    create: |ctx, params| Ok(Box::new(Volume::new(ctx, params)?)),
    uses_splat: false,
    uses_budget: true,
    owns_particle_pass: false,
    volume: super::VolumeSupport::Shadows,
    shadows_particles: true,
};

/// Voxels per side for a `resolution_px`² map of `channels` half floats: G = round(cbrt(res² · B)),
/// at least 4.
pub fn grid_side(resolution_px: u32, channels: u32) -> u32 {
    let voxels = f64::from(resolution_px).powi(2) * f64::from(channels);
    (voxels.cbrt().round() as u32).max(MIN_SIDE)
}

/// Bytes per staging row of `side` half floats, padded to wgpu's copy alignment.
fn staging_pitch(side: u32) -> u64 {
    (u64::from(side) * 2).next_multiple_of(u64::from(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT))
}

/// The z-slices a slab may hold: its u32 scratch and its staging each fit one storage binding.
fn slab_depth(side: u32, binding_limit: u64) -> u32 {
    let side64 = u64::from(side);
    let per_slice = (side64 * side64 * 4).max(side64 * staging_pitch(side));
    (binding_limit / per_slice).clamp(1, side64) as u32
}

/// The build scratch of slabs of `depth` z-slices of a `side`³ grid: a uniform per slab, the
/// u32 sums and the padded f16 staging of one slab (reused by every slab in turn).
pub fn slab_scratch_bytes(side: u32, depth: u32) -> u64 {
    let (side64, depth64) = (u64::from(side), u64::from(depth.max(1)));
    side64.div_ceil(depth64) * BUILD_BYTES
        + side64 * side64 * depth64 * 4
        + depth64 * side64 * staging_pitch(side)
}

/// The deepest slab (at most `max_depth` z-slices) whose scratch fits `available` bytes: the
/// fewest passes the memory allows. `None` when not even one z-slice fits.
fn deepest_slab(side: u32, max_depth: u32, available: u64) -> Option<u32> {
    // The scratch grows with the depth (the per-slab uniforms shrink, by far less).
    crate::gpu::largest_that_fits(1..=max_depth.max(1), |d| {
        slab_scratch_bytes(side, d) <= available
    })
}

/// Keep in sync with `VolumeParams` in shaders/shadow/volume.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct VolumeParams {
    origin: [f32; 3],
    steps: u32,
    extent: [f32; 3],
    occupied: u32,
}

/// Keep in sync with `VolumeBuild` in shaders/shadow/volume_build.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct VolumeBuild {
    origin: [f32; 3],
    side: u32,
    voxel_size: [f32; 3],
    row_end: u32,
    slab_z0: u32,
    slab_depth: u32,
    words_per_row: u32,
    row_first: u32,
    light_pos: [f32; 3],
    units_per_extinction: f32,
    job_first: u32,
    job_end: u32,
    _pad1: [u32; 2],
}

/// One particle's share of the scatter. Keep in sync with `VolumeJob` in volume_build.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct VolumeJob {
    pub center: [f32; 3],
    pub radius: f32,
    pub tau: f32,
    /// The first of its rows in the frame's numbering (a prefix sum).
    pub row_start: u32,
    /// The first voxel of its box, x | y << 10 | z << 20.
    pub lo: u32,
    /// The voxels of its box per axis, packed the same way.
    pub size: u32,
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![
        crate::mirror_layout!(
            VolumeParams,
            "shadow/volume.wgsl",
            "VolumeParams",
            [origin, steps, extent, occupied]
        ),
        crate::mirror_layout!(
            VolumeBuild,
            "shadow/volume_build.wgsl",
            "VolumeBuild",
            [
                origin,
                side,
                voxel_size,
                row_end,
                slab_z0,
                slab_depth,
                words_per_row,
                row_first,
                light_pos,
                units_per_extinction,
                job_first,
                job_end
            ]
        ),
        crate::mirror_layout!(
            VolumeJob,
            "shadow/volume_build.wgsl",
            "VolumeJob",
            [center, radius, tau, row_start, lo, size]
        ),
    ]
}

fn pack3(v: [u32; 3]) -> u32 {
    v[0] | (v[1] << 10) | (v[2] << 20)
}

fn unpack3(v: u32) -> [u32; 3] {
    [v & 1023, (v >> 10) & 1023, v >> 20]
}

/// A frame's grid placement and scatter jobs, computed on the CPU.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelPlan {
    /// The grid's corner and size (m): the spheres' bounds widened by one voxel per side.
    pub origin: glam::Vec3,
    pub extent: glam::Vec3,
    /// One job per particle with a radius and an extinction, sorted by their boxes' first
    /// z-slice (ties in instance order).
    pub jobs: Vec<VolumeJob>,
    /// (particle, voxel row) pairs of the scatter.
    pub rows: u64,
    /// For each block of [`ROWS_PER_BLOCK`] rows, the job its first row belongs to, and after
    /// them the last job: the rows of block b belong to jobs `row_blocks[b] ..= row_blocks[b + 1]`,
    /// so the scatter finds a row's job among those alone.
    pub row_blocks: Vec<u32>,
    /// Fixed-point units per 1/m: [`MAX_UNITS_PER_EXTINCTION`], or a lower power of two where
    /// the particles' count times the largest τ could carry a voxel's sum past 2^32.
    pub units_per_extinction: f32,
}

/// What one slab's scatter runs over ([`VoxelPlan::slabs`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlabWork {
    /// The rows `[first, end)` of the run of jobs that can reach the slab (the scatter by row).
    pub rows: (u32, u32),
    /// That run of jobs `[first, end)` (the scatter by job).
    pub jobs: (u32, u32),
    /// The most rows one of them has within the slab.
    pub job_rows: u32,
}

impl SlabWork {
    /// Invocations of the scatter by row: every row of the run, in the slab or not.
    pub fn row_invocations(&self) -> u64 {
        u64::from(self.rows.1 - self.rows.0)
    }

    /// Invocations of the scatter by job: per job of the run, its largest part's rows in whole
    /// workgroups of 64.
    pub fn job_invocations(&self) -> u64 {
        u64::from(self.jobs.1 - self.jobs.0) * u64::from(self.job_rows.div_ceil(64)) * 64
    }

    /// Whether the scatter by job runs fewer invocations (thin slabs, where most of a run's
    /// rows lie outside the slab); both add the same integers to the same voxels.
    pub fn by_job(&self) -> bool {
        self.job_invocations() < self.row_invocations()
    }
}

impl VoxelPlan {
    /// What the scatter of each slab of `depth` z-slices of a `side`³ grid runs over: the run
    /// of jobs that can reach it (their boxes start before its end, and some box up to the
    /// run's first ends at or after its start), their rows, and the most rows one of them has
    /// in the slab. Rows of the run outside the slab are skipped by the shader; a slab no box
    /// reaches gets an empty run.
    pub fn slabs(&self, side: u32, depth: u32) -> Vec<SlabWork> {
        let z_range = |j: &VolumeJob| {
            let (lo, size) = (unpack3(j.lo)[2], unpack3(j.size)[2]);
            (lo, lo + size - 1)
        };
        // The furthest last z-slice of the jobs up to each: non-decreasing, so searchable.
        let reach: Vec<u32> = self
            .jobs
            .iter()
            .scan(0u32, |furthest, j| {
                *furthest = (*furthest).max(z_range(j).1);
                Some(*furthest)
            })
            .collect();
        let row_of = |job: usize| self.jobs.get(job).map_or(self.rows as u32, |j| j.row_start);
        (0..side.div_ceil(depth.max(1)))
            .map(|i| {
                let z0 = i * depth;
                let z_end = z0 + depth;
                let end = self.jobs.partition_point(|j| z_range(j).0 < z_end);
                let first = reach.partition_point(|&z| z < z0).min(end);
                let job_rows = self.jobs[first..end]
                    .iter()
                    .map(|j| {
                        let (lo, hi) = z_range(j);
                        let overlap = (hi + 1).min(z_end).saturating_sub(lo.max(z0));
                        unpack3(j.size)[1] * overlap
                    })
                    .max()
                    .unwrap_or(0);
                SlabWork {
                    rows: (row_of(first), row_of(end)),
                    jobs: (first as u32, end as u32),
                    job_rows,
                }
            })
            .collect()
    }
}

/// Places a `side`³ grid over `instances` and the density volume's box `volume` (min, max), if
/// the scene has one, and lists the particles' scatter jobs; `None` when there is neither a
/// particle with a radius and an extinction nor a volume.
pub fn plan(
    instances: &[ParticleInstance],
    side: u32,
    volume: Option<(glam::Vec3, glam::Vec3)>,
) -> Option<VoxelPlan> {
    use glam::Vec3;
    let live = |p: &&ParticleInstance| p.center_radius[3] > 0.0 && p.albedo_density[3] > 0.0;
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    let (mut count, mut max_tau) = (0u64, 0.0f32);
    for p in instances.iter().filter(live) {
        let c = Vec3::from_slice(&p.center_radius[..3]);
        let r = p.center_radius[3];
        lo = lo.min(c - r);
        hi = hi.max(c + r);
        count += 1;
        max_tau = max_tau.max(p.albedo_density[3]);
    }
    if let Some((vlo, vhi)) = volume {
        lo = lo.min(vlo);
        hi = hi.max(vhi);
    } else if count == 0 {
        return None;
    }
    let voxel = (hi - lo).max(Vec3::splat(1e-3)) / (side - 2) as f32;
    let origin = lo - voxel;
    let extent = voxel * side as f32;
    // A voxel's sum is at most Σ τ f_max over the particles, at most count × max τ × f_max (a
    // bound that does not depend on their order).
    let bound = count as f64 * f64::from(max_tau.min(65504.0)) * RADIAL_PEAK;
    let mut units = f64::from(MAX_UNITS_PER_EXTINCTION);
    while bound * units >= f64::from(u32::MAX) && units > 1e-6 {
        units /= 2.0;
    }
    // Every sphere lies inside the border voxels (a face on the bounds may round onto a border
    // voxel's edge, where no sub-sample lies inside it).
    let (inner_first, inner_last) = (Vec3::ONE, Vec3::splat((side - 2) as f32));
    let mut jobs = instances
        .iter()
        .filter(live)
        .map(|p| {
            let c = Vec3::from_slice(&p.center_radius[..3]);
            let r = p.center_radius[3];
            let first = ((c - r - origin) / voxel)
                .floor()
                .clamp(inner_first, inner_last);
            let end = ((c + r - origin) / voxel)
                .floor()
                .clamp(inner_first, inner_last);
            let first = first.as_uvec3();
            let size = end.as_uvec3() - first + glam::UVec3::ONE;
            VolumeJob {
                center: c.to_array(),
                radius: r,
                tau: p.albedo_density[3],
                row_start: 0,
                lo: pack3(first.to_array()),
                size: pack3(size.to_array()),
            }
        })
        .collect::<Vec<VolumeJob>>();
    // By first z-slice (stable: ties keep the instance order), so that the jobs that can reach
    // a slab are one run ([`VoxelPlan::slabs`]).
    jobs.sort_by_key(|j| unpack3(j.lo)[2]);
    let mut rows = 0u64;
    for job in &mut jobs {
        let size = unpack3(job.size);
        job.row_start = rows as u32;
        rows += u64::from(size[1]) * u64::from(size[2]);
    }
    let blocks = rows.div_ceil(u64::from(ROWS_PER_BLOCK));
    let mut row_blocks = Vec::with_capacity(blocks as usize + 1);
    let mut job = 0usize;
    for b in 0..blocks {
        let first_row = b * u64::from(ROWS_PER_BLOCK);
        while job + 1 < jobs.len() && u64::from(jobs[job + 1].row_start) <= first_row {
            job += 1;
        }
        row_blocks.push(job as u32);
    }
    row_blocks.push(jobs.len().saturating_sub(1) as u32);
    Some(VoxelPlan {
        origin,
        extent,
        jobs,
        rows,
        row_blocks,
        units_per_extinction: units as f32,
    })
}

/// The volume technique at one configuration.
pub struct Volume {
    channels: u32,
    side: u32,
    steps: u32,
    light_aligned: bool,
    grid: wgpu::Texture,
    lookup_params: wgpu::Buffer,
    /// The build's slab scratch, sized at the first build to what the memory limit leaves.
    slabs: Option<Slabs>,
    /// The frame's jobs, and its row-block table.
    jobs: GrowingBuffer,
    row_blocks: GrowingBuffer,
    build_layout: wgpu::BindGroupLayout,
    scatter: wgpu::ComputePipeline,
    /// The scatter by job, for slabs where it runs fewer invocations ([`SlabWork::by_job`]).
    scatter_jobs: wgpu::ComputePipeline,
    /// The conversion for scenes without a density volume, and with one.
    convert: wgpu::ComputePipeline,
    convert_with_medium: wgpu::ComputePipeline,
    lookup_layout: wgpu::BindGroupLayout,
    lookup_bind_group: wgpu::BindGroup,
    memory: MemoryLedger,
    /// The adapter's largest storage binding.
    binding_limit: u64,
    /// Whether the row-block table holds this frame's, so that slabs may scatter by row.
    by_row: bool,
    /// Last frame: jobs and (particle, voxel row) pairs.
    last_jobs: u32,
    last_rows: u64,
}

impl Volume {
    pub fn new(ctx: &TechniqueContext<'_>, params: &TechniqueParams) -> Result<Self, ShadowError> {
        let gpu = ctx.gpu;
        let device = &gpu.device;
        let side = grid_side(params.resolution_px, params.channels);
        let max_side = MAX_SIDE.min(gpu.limits.max_texture_dimension_3d);
        if side > max_side {
            return Err(AllocationError::TextureTooLarge {
                label: format!("volume.grid ({side}³ voxels)"),
                width: side,
                height: side,
                max: max_side,
            }
            .into());
        }
        let steps = params.get(&STEPS).unwrap_or(DEFAULT_STEPS as f32).round() as u32;
        let light_aligned = params.get(&LIGHT_ALIGNED).unwrap_or(0.0) >= 0.5;
        let mut memory = MemoryLedger::for_technique(&gpu.limits, params.memory_limit_bytes);
        let lookup_params = memory.buffer(
            device,
            &wgpu::BufferDescriptor {
                label: Some("volume.params"),
                size: LOOKUP_BYTES,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            },
        )?;
        let grid = memory.texture(
            device,
            &wgpu::TextureDescriptor {
                label: Some("volume.grid"),
                size: wgpu::Extent3d {
                    width: side,
                    height: side,
                    depth_or_array_layers: side,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D3,
                format: wgpu::TextureFormat::R16Float,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            },
        )?;
        let jobs = GrowingBuffer::new(
            &mut memory,
            device,
            "volume.jobs",
            JOB_BYTES,
            MIN_JOB_CAPACITY,
        )?;
        let row_blocks = GrowingBuffer::new(
            &mut memory,
            device,
            "volume.row_blocks",
            4,
            MIN_BLOCK_CAPACITY,
        )?;

        let compute = wgpu::ShaderStages::COMPUTE;
        let build_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("volume.build.layout"),
            entries: &[
                uniform_entry(0, compute),
                storage_entry(1, compute, true),
                storage_entry(2, compute, false),
                storage_entry(3, compute, false),
                storage_entry(4, compute, true),
            ],
        });
        let module = shaders::module(device, "volume.build", &build_shader());
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("volume.build.pipeline_layout"),
            // Group 0 the frame's (the scene's density volume), group 1 the build's own.
            bind_group_layouts: &[Some(ctx.frame_layout), Some(&build_layout)],
            immediate_size: 0,
        });
        let pipeline = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(&format!("volume.{entry}")),
                layout: Some(&layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };

        let lookup_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("volume.lookup.layout"),
            entries: &[
                uniform_entry(0, LOOKUP_STAGES),
                sampler_entry(1, LOOKUP_STAGES),
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: LOOKUP_STAGES,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D3,
                        multisampled: false,
                    },
                    count: None,
                },
            ],
        });
        let sampler = super::map_sampler(device, "volume.sampler");
        let grid_view = grid.create_view(&wgpu::TextureViewDescriptor::default());
        let lookup_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("volume.lookup.bind_group"),
            layout: &lookup_layout,
            entries: &[
                bind_entry(0, &lookup_params),
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(&sampler),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(&grid_view),
                },
            ],
        });
        // Nothing built yet: T = 1 until the first frame.
        gpu.queue.write_buffer(
            &lookup_params,
            0,
            bytemuck::bytes_of(&VolumeParams::default()),
        );
        Ok(Self {
            channels: params.channels,
            side,
            steps,
            light_aligned,
            // Each field has its own entry point (see scatter_row in volume_build.wgsl).
            scatter: pipeline(if light_aligned {
                "scatter_light_aligned"
            } else {
                "scatter_radial"
            }),
            scatter_jobs: pipeline(if light_aligned {
                "scatter_light_aligned_jobs"
            } else {
                "scatter_radial_jobs"
            }),
            convert: pipeline("convert"),
            convert_with_medium: pipeline("convert_with_medium"),
            grid,
            lookup_params,
            slabs: None,
            jobs,
            row_blocks,
            build_layout,
            lookup_layout,
            lookup_bind_group,
            memory,
            binding_limit: gpu.limits.max_storage_buffer_binding_size,
            by_row: true,
            last_jobs: 0,
            last_rows: 0,
        })
    }
}

impl Volume {
    /// The bytes of the slab scratch it holds now (0 before its first build).
    fn slab_bytes(&self) -> u64 {
        self.slabs
            .as_ref()
            .map_or(0, |s| slab_scratch_bytes(self.side, s.depth))
    }

    /// Sizes the slab scratch to the deepest slab the memory limit leaves room for (after the
    /// grid, the jobs and the row blocks), within one storage binding: the whole grid in one
    /// slab where it fits, else as few slabs as the limit allows (the grid is the same either
    /// way). Reallocates only when that depth changes.
    fn fit_slabs(&mut self, device: &wgpu::Device) -> Result<(), ShadowError> {
        let room = self.memory.remaining_bytes() + self.slab_bytes();
        let max_depth = slab_depth(self.side, self.binding_limit);
        // Not even one z-slice fits: allocate one anyway, for the ledger's one line.
        let depth = deepest_slab(self.side, max_depth, room).unwrap_or(1);
        if self.slabs.as_ref().is_some_and(|s| s.depth == depth) {
            return Ok(());
        }
        if let Some(old) = self.slabs.take() {
            old.release(&mut self.memory);
        }
        self.slabs = Some(Slabs::new(&mut self.memory, device, self.side, depth)?);
        Ok(())
    }
}

/// The build's scratch for slabs of `depth` z-slices: a uniform per slab, and the u32 sums and
/// the f16 staging of one slab, which every slab reuses in turn
/// ([`slab_scratch_bytes`]).
struct Slabs {
    depth: u32,
    params: Vec<wgpu::Buffer>,
    scratch: wgpu::Buffer,
    staging: wgpu::Buffer,
}

impl Slabs {
    fn new(
        memory: &mut MemoryLedger,
        device: &wgpu::Device,
        side: u32,
        depth: u32,
    ) -> Result<Self, ShadowError> {
        let params = (0..side.div_ceil(depth))
            .map(|i| {
                memory.buffer_transient(
                    device,
                    &wgpu::BufferDescriptor {
                        label: Some(&format!("volume.slab{i}")),
                        size: BUILD_BYTES,
                        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                        mapped_at_creation: false,
                    },
                )
            })
            .collect::<Result<Vec<_>, _>>()?;
        let (side64, depth64) = (u64::from(side), u64::from(depth));
        let scratch = memory.buffer_transient(
            device,
            &storage_descriptor("volume.scratch", side64 * side64 * depth64 * 4),
        )?;
        let staging = memory.buffer_transient(
            device,
            &storage_descriptor("volume.staging", depth64 * side64 * staging_pitch(side)),
        )?;
        Ok(Self {
            depth,
            params,
            scratch,
            staging,
        })
    }

    /// Forgets its allocations in `memory` and frees them.
    fn release(self, memory: &mut MemoryLedger) {
        for (i, buffer) in self.params.into_iter().enumerate() {
            memory.forget(&format!("volume.slab{i}"));
            buffer.destroy();
        }
        for (label, buffer) in [
            ("volume.scratch", self.scratch),
            ("volume.staging", self.staging),
        ] {
            memory.forget(label);
            buffer.destroy();
        }
    }
}

/// A transient storage buffer of elements that grows with the frame.
struct GrowingBuffer {
    label: &'static str,
    element_bytes: u64,
    buffer: wgpu::Buffer,
    /// Elements it holds.
    capacity: u32,
}

impl GrowingBuffer {
    fn new(
        memory: &mut MemoryLedger,
        device: &wgpu::Device,
        label: &'static str,
        element_bytes: u64,
        capacity: u32,
    ) -> Result<Self, ShadowError> {
        let buffer = memory.buffer_transient(
            device,
            &storage_descriptor(label, u64::from(capacity) * element_bytes),
        )?;
        Ok(Self {
            label,
            element_bytes,
            buffer,
            capacity,
        })
    }

    /// The bytes it holds.
    fn bytes(&self) -> u64 {
        u64::from(self.capacity) * self.element_bytes
    }

    /// Grows it to hold `count` elements (a power of two, or exactly `count` where a power of
    /// two would not fit one binding of `binding_limit` bytes, or would leave less than
    /// `keep_free` bytes of the memory limit).
    fn reserve(
        &mut self,
        memory: &mut MemoryLedger,
        device: &wgpu::Device,
        (binding_limit, keep_free): (u64, u64),
        count: u32,
    ) -> Result<(), ShadowError> {
        if count <= self.capacity {
            return Ok(());
        }
        // What the buffer may take: the limit's remaining bytes and its own, which it frees.
        let room = memory.remaining_bytes() + self.bytes();
        let mut capacity = count.next_power_of_two();
        let bytes = u64::from(capacity) * self.element_bytes;
        if bytes > binding_limit || bytes.saturating_add(keep_free) > room {
            capacity = count;
        }
        memory.forget(self.label);
        self.buffer.destroy();
        *self = Self::new(memory, device, self.label, self.element_bytes, capacity)?;
        Ok(())
    }
}

/// Workgroups of the scatter: 64 invocations each, laid out over x and y because one dimension
/// holds at most 65,535.
fn scatter_groups(rows: u32) -> (u32, u32) {
    let groups = rows.div_ceil(64);
    (groups.min(65_535), groups.div_ceil(65_535))
}

impl ShadowTechnique for Volume {
    fn name(&self) -> &'static str {
        ENTRY.name
    }
    fn channels_used(&self) -> u32 {
        self.channels
    }
    fn memory(&self) -> &MemoryLedger {
        &self.memory
    }
    fn bind_group_layout(&self) -> &wgpu::BindGroupLayout {
        &self.lookup_layout
    }
    fn bind_group(&self) -> &wgpu::BindGroup {
        &self.lookup_bind_group
    }

    /// `grid_side`: G; `slab_depth`: z-slices built per slab; `job_capacity`: jobs the buffer
    /// holds; `block_capacity`: entries the row-block table holds; `voxelised_particles` and `voxel_rows`: last frame's jobs and (particle, voxel
    /// row) pairs; `volume_steps`: K; `light_aligned`: 1 when the grid holds this light's field.
    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![
            ("grid_side", u64::from(self.side)),
            (
                "slab_depth",
                self.slabs.as_ref().map_or(0, |s| u64::from(s.depth)),
            ),
            ("job_capacity", u64::from(self.jobs.capacity)),
            ("block_capacity", u64::from(self.row_blocks.capacity)),
            ("voxelised_particles", u64::from(self.last_jobs)),
            ("voxel_rows", self.last_rows),
            ("volume_steps", u64::from(self.steps)),
            ("light_aligned", u64::from(self.light_aligned)),
        ]
    }

    fn build<'a>(
        &'a mut self,
        gpu: &'a Gpu,
        inputs: BuildInputs<'a>,
    ) -> GpuFuture<'a, Result<(), ShadowError>> {
        Box::pin(async move {
            let device = &gpu.device;
            let Some(plan) = plan(inputs.instances, self.side, inputs.volume) else {
                // No smoke: the lookup lets all light through and the grid is not read.
                (self.last_jobs, self.last_rows) = (0, 0);
                gpu.queue.write_buffer(
                    &self.lookup_params,
                    0,
                    bytemuck::bytes_of(&VolumeParams {
                        steps: self.steps,
                        ..VolumeParams::default()
                    }),
                );
                return Ok(());
            };
            // Rows are numbered in u32 (the jobs' row starts, the slabs' ranges).
            u32::try_from(plan.rows).map_err(|_| ShadowError::VoxelRowsTooMany {
                particles: inputs.particle_count,
                side: self.side,
                rows: plan.rows,
                limit: u64::from(u32::MAX),
            })?;
            let count = plan.jobs.len() as u32;
            // Room for one z-slice's scratch is kept beside the jobs and the row blocks.
            let limits = (self.binding_limit, slab_scratch_bytes(self.side, 1));
            self.jobs.reserve(&mut self.memory, device, limits, count)?;
            // The row-block table serves the scatter by row alone: where growing it would leave no
            // room for one z-slice's scratch under the memory limit, every slab scatters by job
            // (the same sums), and the table stays as it is.
            let blocks = plan.row_blocks.len() as u32;
            let room = self.memory.remaining_bytes() + self.row_blocks.bytes() + self.slab_bytes();
            self.by_row = blocks <= self.row_blocks.capacity
                || u64::from(blocks) * 4 + slab_scratch_bytes(self.side, 1) <= room;
            if self.by_row {
                self.row_blocks
                    .reserve(&mut self.memory, device, limits, blocks)?;
                gpu.queue.write_buffer(
                    &self.row_blocks.buffer,
                    0,
                    bytemuck::cast_slice(&plan.row_blocks),
                );
            }
            (self.last_jobs, self.last_rows) = (count, plan.rows);
            gpu.queue
                .write_buffer(&self.jobs.buffer, 0, bytemuck::cast_slice(&plan.jobs));
            gpu.queue.write_buffer(
                &self.lookup_params,
                0,
                bytemuck::bytes_of(&VolumeParams {
                    origin: plan.origin.to_array(),
                    steps: self.steps,
                    extent: plan.extent.to_array(),
                    occupied: 1,
                }),
            );

            let side = self.side;
            self.fit_slabs(device)?;
            let slabs = self.slabs.as_ref().expect("fit_slabs leaves slabs");
            let pitch = staging_pitch(side);
            let work = plan.slabs(side, slabs.depth);
            // One timed span over every slab's passes (and the copies between them).
            let span = inputs.timer.compute_span("shadow");
            let passes = 2 * slabs.params.len();
            let mut pass_index = 0;
            for (i, (slab, work)) in slabs.params.iter().zip(&work).enumerate() {
                let z0 = i as u32 * slabs.depth;
                let depth = slabs.depth.min(side - z0);
                gpu.queue.write_buffer(
                    slab,
                    0,
                    bytemuck::bytes_of(&VolumeBuild {
                        origin: plan.origin.to_array(),
                        side,
                        voxel_size: (plan.extent / side as f32).to_array(),
                        row_end: work.rows.1,
                        slab_z0: z0,
                        slab_depth: depth,
                        words_per_row: (pitch / 4) as u32,
                        row_first: work.rows.0,
                        light_pos: inputs.light.position.to_array(),
                        units_per_extinction: plan.units_per_extinction,
                        job_first: work.jobs.0,
                        job_end: work.jobs.1,
                        _pad1: [0; 2],
                    }),
                );
                let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("volume.build.bind_group"),
                    layout: &self.build_layout,
                    entries: &[
                        bind_entry(0, slab),
                        bind_entry(1, &self.jobs.buffer),
                        bind_entry(2, &slabs.scratch),
                        bind_entry(3, &slabs.staging),
                        bind_entry(4, &self.row_blocks.buffer),
                    ],
                });
                inputs.encoder.clear_buffer(&slabs.scratch, 0, None);
                // Each step in a pass of its own, so that each sees the previous one's writes
                // whatever the backend's barriers within a pass. A slab no particle reaches still
                // converts its zeros (and the density volume's share).
                // By row, or by job where that runs fewer invocations (thin slabs).
                let (scatter, scatter_dispatch) = match work.by_job() || !self.by_row {
                    false => {
                        let (x, y) = scatter_groups(work.rows.1 - work.rows.0);
                        (&self.scatter, [x, y, 1])
                    }
                    true => {
                        let jobs = work.jobs.1 - work.jobs.0;
                        (
                            &self.scatter_jobs,
                            [
                                work.job_rows.div_ceil(64),
                                jobs.min(65_535),
                                jobs.div_ceil(65_535),
                            ],
                        )
                    }
                };
                let words = side.div_ceil(2);
                let convert = match inputs.volume {
                    Some(_) => &self.convert_with_medium,
                    None => &self.convert,
                };
                for (pipeline, groups) in [
                    (scatter, scatter_dispatch),
                    (convert, [words.div_ceil(8), side.div_ceil(8), depth]),
                ] {
                    let timestamp_writes =
                        inputs
                            .timer
                            .span_writes(span, pass_index == 0, pass_index + 1 == passes);
                    pass_index += 1;
                    let mut pass =
                        inputs
                            .encoder
                            .begin_compute_pass(&wgpu::ComputePassDescriptor {
                                label: Some("volume.build"),
                                timestamp_writes,
                            });
                    pass.set_pipeline(pipeline);
                    pass.set_bind_group(0, inputs.frame_bind_group, &[]);
                    pass.set_bind_group(1, &bind_group, &[]);
                    if groups.iter().all(|&g| g > 0) {
                        pass.dispatch_workgroups(groups[0], groups[1], groups[2]);
                    }
                }
                inputs.encoder.copy_buffer_to_texture(
                    wgpu::TexelCopyBufferInfo {
                        buffer: &slabs.staging,
                        layout: wgpu::TexelCopyBufferLayout {
                            offset: 0,
                            bytes_per_row: Some(pitch as u32),
                            rows_per_image: Some(side),
                        },
                    },
                    wgpu::TexelCopyTextureInfo {
                        texture: &self.grid,
                        mip_level: 0,
                        origin: wgpu::Origin3d { x: 0, y: 0, z: z0 },
                        aspect: wgpu::TextureAspect::All,
                    },
                    wgpu::Extent3d {
                        width: side,
                        height: side,
                        depth_or_array_layers: depth,
                    },
                );
            }
            Ok(())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn instance(center: [f32; 3], radius: f32, tau: f32) -> ParticleInstance {
        ParticleInstance {
            center_radius: [center[0], center[1], center[2], radius],
            albedo_density: [1.0, 1.0, 1.0, tau],
        }
    }

    #[test]
    fn the_grid_matches_the_maps_of_the_budget() {
        // 512² × 24 = 6,291,456 half floats; 185³ = 6,331,625 is the nearest cube.
        assert_eq!(grid_side(512, 24), 185);
        assert_eq!(grid_side(512, 6), 116);
        assert_eq!(grid_side(128, 1), 25);
        assert_eq!(grid_side(1, 1), MIN_SIDE);
        for (res, b) in [(512u32, 24u32), (512, 16), (512, 8), (512, 6), (1024, 24)] {
            let maps = f64::from(res).powi(2) * f64::from(b);
            let g = f64::from(grid_side(res, b));
            // An integer G is within half a voxel per side of the cube root.
            assert!((g.powi(3) - maps).abs() <= 1.5 * g * g + 1.0, "{res} {b}");
        }
        assert_eq!((ENTRY.budget_caption)(24), "res²·24 voxels (185³ at 512²)");
    }

    #[test]
    fn slabs_fit_one_binding() {
        let mib128 = 128u64 << 20;
        assert_eq!(slab_depth(185, mib128), 185);
        assert_eq!(slab_depth(322, mib128), 322);
        let d = slab_depth(512, mib128);
        assert!(d < 512 && u64::from(d) * 512 * 512 * 4 <= mib128);
        assert!(u64::from(d) * 512 * staging_pitch(512) <= mib128);
        assert_eq!(slab_depth(1000, 16), 1);
        assert_eq!(staging_pitch(185), 512);
        assert_eq!(staging_pitch(128), 256);
    }

    #[test]
    fn the_plan_bounds_every_sphere_with_an_empty_border() {
        let particles = [
            instance([0.0, 0.0, 0.0], 1.0, 2.0),
            instance([3.0, 1.0, -1.0], 0.5, 1.0),
            // No radius or no extinction: no job, no influence on the bounds.
            instance([50.0, 0.0, 0.0], 0.0, 1.0),
            instance([-50.0, 0.0, 0.0], 1.0, 0.0),
        ];
        let side = 34;
        let plan = plan(&particles, side, None).unwrap();
        assert_eq!(plan.jobs.len(), 2);
        let voxel = plan.extent / side as f32;
        // The spheres span [-1, 3.5] x [-1, 1.5] x [-1.5, 1]: 32 voxels inside, one each side.
        let expected = glam::Vec3::new(4.5, 2.5, 2.5) / 32.0;
        assert!((voxel - expected).abs().max_element() < 1e-6, "{voxel}");
        assert!((plan.origin - (glam::Vec3::new(-1.0, -1.0, -1.5) - expected)).length() < 1e-5);
        // Jobs go by their first z-slice: the small sphere's box starts at the first inner one.
        assert_eq!(plan.jobs[0].radius, 0.5);
        // The big sphere's box starts in the first inner voxel along x and y, and 0.5 m (6.4
        // voxels) in along z, where the small sphere reaches further; it spans 2 m of x.
        assert_eq!(unpack3(plan.jobs[1].lo), [1, 1, 7]);
        let size = unpack3(plan.jobs[1].size);
        assert!((14..=16).contains(&size[0]), "{size:?}");
        // Row numbering is a prefix sum of size_y · size_z.
        let s0 = unpack3(plan.jobs[0].size);
        let rows0 = u64::from(s0[1] * s0[2]);
        assert_eq!(plan.jobs[1].row_start as u64, rows0);
        let s1 = unpack3(plan.jobs[1].size);
        assert_eq!(plan.rows, rows0 + u64::from(s1[1] * s1[2]));
        // Every box stays clear of the border voxels.
        for job in &plan.jobs {
            let (lo, size) = (unpack3(job.lo), unpack3(job.size));
            for a in 0..3 {
                assert!(lo[a] >= 1 && lo[a] + size[a] < side, "{lo:?} {size:?}");
            }
        }
        assert_eq!(plan.units_per_extinction, MAX_UNITS_PER_EXTINCTION);
        assert!(super::plan(&particles[2..], side, None).is_none());
    }

    #[test]
    fn the_row_blocks_hold_every_rows_job_between_their_bounds() {
        // Spheres from a voxel across to a third of the grid: jobs of 1 row to hundreds, so
        // blocks hold one job or many.
        let particles: Vec<_> = (0..300)
            .map(|i| {
                let radius = if i % 7 == 0 {
                    3.0
                } else {
                    0.05 + 0.01 * (i % 5) as f32
                };
                instance(
                    [(i % 17) as f32, (i % 11) as f32, (i % 13) as f32],
                    radius,
                    1.0,
                )
            })
            .collect();
        let plan = plan(&particles, 64, None).unwrap();
        let blocks = plan.rows.div_ceil(u64::from(ROWS_PER_BLOCK)) as usize;
        assert_eq!(plan.row_blocks.len(), blocks + 1);
        assert_eq!(
            *plan.row_blocks.last().unwrap() as usize,
            plan.jobs.len() - 1
        );
        let mut widest = 0;
        for row in 0..plan.rows {
            // The job of `row`: the last whose first row is at or before it.
            let job = plan
                .jobs
                .iter()
                .rposition(|j| u64::from(j.row_start) <= row)
                .unwrap() as u32;
            let block = (row / u64::from(ROWS_PER_BLOCK)) as usize;
            let (lo, hi) = (plan.row_blocks[block], plan.row_blocks[block + 1]);
            assert!(
                lo <= job && job <= hi,
                "row {row}: job {job} outside {lo}..={hi}"
            );
            widest = widest.max(hi - lo);
        }
        // Some block holds several jobs (the search has work), none more than its rows.
        assert!(widest > 1 && widest <= ROWS_PER_BLOCK, "{widest}");
    }

    #[test]
    fn each_slab_runs_over_every_row_that_reaches_it() {
        // Spheres of many sizes: some slabs are reached by few jobs, some by none.
        let particles: Vec<_> = (0..200)
            .map(|i| {
                let radius = if i % 9 == 0 { 2.0 } else { 0.1 };
                instance(
                    [(i % 7) as f32, (i % 5) as f32, (i % 23) as f32],
                    radius,
                    1.0,
                )
            })
            .collect();
        let side = 48;
        let plan = plan(&particles, side, None).unwrap();
        // Jobs are sorted by their first z-slice.
        assert!(plan.jobs.is_sorted_by_key(|j| unpack3(j.lo)[2]));
        for depth in [1, 2, 5, 16, side] {
            let work = plan.slabs(side, depth);
            assert_eq!(work.len(), side.div_ceil(depth) as usize);
            let mut run = 0u64;
            for (s, w) in work.iter().enumerate() {
                let (first, end) = w.rows;
                assert!(first <= end && u64::from(end) <= plan.rows);
                let (z0, z1) = (s as u32 * depth, (s as u32 + 1) * depth);
                for (index, j) in plan.jobs.iter().enumerate() {
                    let (lo, size) = (unpack3(j.lo), unpack3(j.size));
                    // Row `local` of the job is its z-slice lo.z + local / size.y.
                    let mut in_slab = 0;
                    for local in 0..size[1] * size[2] {
                        let z = lo[2] + local / size[1];
                        let row = j.row_start + local;
                        if (z0..z1).contains(&z) {
                            in_slab += 1;
                            assert!(
                                (first..end).contains(&row),
                                "slab {s} of {depth}: row {row} at z {z} outside {first}..{end}"
                            );
                        }
                    }
                    // The scatter by job reaches the same rows: the job is in the run, and
                    // its part of the slab within the rows it dispatches.
                    if in_slab > 0 {
                        assert!((w.jobs.0..w.jobs.1).contains(&(index as u32)));
                        assert!(
                            in_slab <= w.job_rows,
                            "slab {s}: {in_slab} > {}",
                            w.job_rows
                        );
                    }
                }
                run += u64::from(end - first);
            }
            // The runs cover every row at least once, and one slab is every row.
            assert!(run >= plan.rows);
            if depth == side {
                assert_eq!(work[0].rows, (0, plan.rows as u32));
                assert!(!work[0].by_job(), "{:?}", work[0]);
            }
            // Thin slabs go by job: most of a run's rows lie outside one z-slice.
            if depth == 1 {
                assert!(work.iter().any(SlabWork::by_job));
            }
        }
    }

    #[test]
    fn the_fixed_point_scale_keeps_every_sum_within_32_bits() {
        let many: Vec<_> = (0..100_000)
            .map(|i| instance([i as f32 * 0.01, 0.0, 0.0], 0.1, 50.0))
            .collect();
        let plan = plan(&many, 16, None).unwrap();
        let units = f64::from(plan.units_per_extinction);
        // The largest sum 100,000 particles of τ = 50 could give, peak included, fits; twice
        // the scale would not.
        let bound = 100_000.0 * 50.0 * RADIAL_PEAK;
        assert!(bound * units < f64::from(u32::MAX));
        assert!(bound * units * 2.0 >= f64::from(u32::MAX));
        assert_eq!(units.log2().fract(), 0.0, "a power of two: {units}");
    }

    #[test]
    fn the_radial_field_integrates_to_the_particle_model_along_every_line() {
        // The model: a line at distance d from the centre of a unit sphere (τ = 1) sees
        // 2 (1 - d) sqrt(1 - d²). Integrated along s in [0, w], w = sqrt(1 - d²), with
        // s = w sin θ (which tames the edge) or s = u² on the axis (which tames the centre's
        // logarithm), by the midpoint rule.
        let n = 100_000;
        for d in [0.0f64, 0.05, 0.2, 0.45, 0.7, 0.9, 0.99] {
            let w = (1.0 - d * d).sqrt();
            let half: f64 = (0..n)
                .map(|i| {
                    let x = (f64::from(i) + 0.5) / f64::from(n);
                    if d == 0.0 {
                        radial_extinction(x.powi(4)) * 2.0 * x / f64::from(n)
                    } else {
                        let theta = x * std::f64::consts::FRAC_PI_2;
                        let s = w * theta.sin();
                        radial_extinction(d * d + s * s)
                            * w
                            * theta.cos()
                            * std::f64::consts::FRAC_PI_2
                            / f64::from(n)
                    }
                })
                .sum();
            let model = 2.0 * (1.0 - d) * w;
            assert!(
                (2.0 * half - model).abs() < 2e-5,
                "d = {d}: the field integrates to {}, the model {model}",
                2.0 * half
            );
        }
        // Zero at the surface and beyond, positive inside, peaked (logarithmically) at the centre.
        assert!(radial_extinction(1.0) == 0.0 && radial_extinction(4.0) == 0.0);
        assert!(radial_extinction(0.999_999) < 1e-5);
        let mut last = 0.0;
        for i in (0..100).rev() {
            let f = radial_extinction(f64::from(i) / 100.0);
            assert!(f > last, "f rises towards the centre");
            last = f;
        }
        assert!(last < RADIAL_PEAK);
    }

    #[test]
    fn the_build_shader_samples_at_the_documented_rate() {
        let source = shaders::source("shadow/volume_build.wgsl").unwrap();
        assert!(source.contains(&format!(
            "const VOLUME_SUBSAMPLES: u32 = {SUBSAMPLES_PER_AXIS}u;"
        )));
        // And finds a row's particle in the blocks the CPU's table has.
        assert!(source.contains(&format!(
            "const VOLUME_ROWS_PER_BLOCK: u32 = {ROWS_PER_BLOCK}u;"
        )));
    }
}
