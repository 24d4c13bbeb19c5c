//! `exact`: the reference every technique is measured against. It evaluates the particle
//! model's transmittance in closed form at each point that asks for it, with no shadow map:
//!
//! T(p) = exp(−Σ_i τ_i (1 − d_i/r_i) ℓ_i(p)),
//!
//! d_i the distance from particle i's centre to the segment light→p and ℓ_i(p) the part of its
//! chord between the light and p — the density model of the spherical billboards and the chord
//! splat, and the same arithmetic as the CPU mirror [`super::closed_form`]. There are no texels,
//! so a technique's error against `exact` includes its shadow-map resolution error.
//!
//! Finding the particles a segment can cross: a light-space tile grid (the light-occlusion tile
//! lists of Yusov's slides, seeds/001). One compute pass counts, for every tile, the particles
//! whose footprint in the light's image plane covers it; a scan turns the counts into offsets; a
//! second pass appends each particle's index to the lists of the tiles it covers. A query sums
//! its list's terms in 2^-26 fixed point: integer addition is associative, so T does not depend
//! on the order the atomics filled a list in.
//!
//! **Stopping early, exactly.** Two stops spare a query most of its list without changing its
//! result by more than the bound below:
//! - *Beyond the point.* The spheres are uploaded in order of their nearest distance from the
//!   light, |c − light| − r, and filled slice by slice of that order (`SLICES` fill passes,
//!   run in order), so a list holds its spheres slice by slice. Each slice's lowest distance is
//!   kept (rounded down); once a query meets an entry whose slice starts beyond its point, no
//!   later sphere can reach the segment and the walk stops: each sphere it skips adds exactly
//!   0. (Sorting each list on the GPU was tried once; on lavapipe the sort was cut short by the
//!   loop limit and its unsorted tails made such a stop skip spheres in front of the point.
//!   Slices need no sort: the fill's passes order them.)
//! - *Below what the image shows.* The sum saturates at an optical depth of
//!   [`super::closed_form::OPTICAL_DEPTH_CUT`] (12): T = exp(−min(τ, 12)), within
//!   exp(−12) = 6.1e-6 of exp(−τ), and the walk stops once the saturated sum is reached. The
//!   terms are not negative, so the clamped running sum is min(partial sum, 12) at every step
//!   and the result does not depend on the list's order either. The CPU mirror saturates alike
//!   ([`super::closed_form::transmittance_of`]).
//!
//! At 65,536 particles of the reduced plume the two stops and the unrolled walk below took the
//! lighting's lookups from 2.6 s to 0.6 s a frame.
//!
//! **The loop limit.** llvmpipe ends every shader loop after 65,535 iterations of an invocation
//! group, all its loops together. Each invocation of the particle lighting pass, the opaque pass
//! and the probe makes one lookup, and the walk takes `UNROLL` entries per iteration, so a
//! list may hold up to `UNROLL` times the loop budget ([`Gpu::loop_budget`], 60,000) less the
//! shares of the lookup's other loops (the march through a density volume, 2,048, and the exact
//! occluder test over at most 1,024 boxes, 1,025), about 455,000 entries: only a list beyond
//! that is refused ([`ShadowError::TileListTooLong`])
//! rather than summed short. The build reads the per-tile counts back; the counter
//! `max_tile_list` reports the longest list on every adapter. The count and the fill loop
//! over each particle's footprint, so on llvmpipe the grid is also halved while the largest
//! footprint would take more than 60,000 iterations (a particle beside the light covers the
//! whole image: 240² tiles at most).
//!
//! **Textures, and the order the particles are lit in.** The lists and the spheres are textures
//! ([`ROW_TEXELS`] texels a row), fetched with `textureLoad`, not storage buffers: llvmpipe
//! loads a storage buffer's words one SIMD lane at a time and fetches texels for all its lanes
//! in one gather, and the walk is nothing but such loads (at 65,536 particles the walk with
//! storage buffers took 14.0 s, with textures 5.0 s). And the technique hands the renderer a
//! lighting order ([`ShadowTechnique::lighting_order`]): the particles by the light-space tile
//! of their centres (a Morton order of their light-view position), so that the lanes lit
//! together walk the same or neighbouring lists (5.0 s -> 2.1 s). Neither changes a sum.
//!
//! Memory grows with particles × tiles covered, not with a map resolution: the grid is sized so
//! that a typical particle spans about four tiles across, and when the lists would exceed the
//! adapter's largest texture the grid is halved until they fit (coarser tiles, longer lists,
//! the same result). The entries are counted first in a submission of their own and read back
//! (a CPU–GPU sync: this is the reference, not a contender).
//!
//! The budget and the shadow resolution do not apply: `channels_used` reports 0.

use super::GpuFuture;
use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;

use super::{
    BuildInputs, LOOKUP_STAGES, MemoryUse, Role, ShadowError, ShadowTechnique, TechniqueContext,
    TechniqueEntry, TechniqueParams,
};
use crate::gpu::uniform_entry;
use crate::gpu::{
    AllocationError, Gpu, MemoryLedger, ROW_TEXELS, bind_entry, read_buffer,
    row_texture_descriptor, storage_descriptor, storage_entry, storage_texture_entry,
    texture_binding, texture_entry,
};
use crate::shaders;

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: "exact",
    description: "reference: closed-form T at every point, particles found through light-space tile lists",
    role: Role::Reference,
    budget_caption: |_| "no budget (closed form)".to_owned(),
    min_channels: 1,
    max_channels: super::MAX_CHANNELS,
    in_default_sweep: false,
    in_default_compare: false,
    build_reads_back: true,
    params: &[],
    order_independent: true,
    converges_with_budget: false,
    converges_from: 1,
    compresses_captured_lists: false,
    // The uniform, the per-tile counts and offsets (+1 for the total), the row sums (+1), 4
    // bytes per list entry of capacity, per particle of capacity its sphere (32 bytes: the
    // lists index this copy, so a frame that reuses them after the renderer re-sorted its
    // instances still reads the spheres they were built from), and per slice its lowest light
    // distance (4 bytes) and its fill range (one uniform offset alignment). Both capacities
    // fill whole texture rows. Nothing is reported as transient: the counts are scratch, but
    // small.
    memory: |c| {
        let side = c.counter("tiles_per_side");
        let tiles = side * side;
        MemoryUse {
            channels: 0,
            bytes: std::mem::size_of::<ExactParams>() as u64
                + (tiles + 2) * 4
                + ((tiles + 1) * 4).max(16)
                + ((side + 1) * 4).max(16)
                + c.counter("entry_capacity") * ENTRY_BYTES
                + c.counter("sphere_capacity") * SPHERE_BYTES
                + u64::from(SLICES) * (4 + c.counter("slice_stride")),
            transient_bytes: 0,
        }
    },
    lookup_shader: "shadow/exact.wgsl",
    lookup_constants: super::no_lookup_constants,
    extra_shaders: || {
        vec![(
            "exact.build".to_owned(),
            shaders::compose("shadow/exact_build.wgsl", &[]),
        )]
    },
    create: |ctx, params| Ok(Box::new(Exact::new(ctx, params)?)),
    uses_splat: false,
    uses_budget: false,
    owns_particle_pass: false,
    volume: super::VolumeSupport::Shadows,
    shadows_particles: true,
};

/// Keep in sync with `ExactParams` in shaders/shadow/exact.wgsl and exact_build.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct ExactParams {
    view_from_world: [[f32; 4]; 4],
    tan_half_fov: f32,
    tiles: u32,
    particle_count: u32,
    capacity: u32,
    slice_size: u32,
    _pad: [u32; 3],
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    ["shadow/exact.wgsl", "shadow/exact_build.wgsl"]
        .into_iter()
        .map(|path| {
            crate::mirror_layout!(
                ExactParams,
                path,
                "ExactParams",
                [
                    view_from_world,
                    tan_half_fov,
                    tiles,
                    particle_count,
                    capacity,
                    slice_size
                ]
            )
        })
        .collect()
}

/// Bytes per list entry: the particle's index (an `R32Uint` texel).
const ENTRY_BYTES: u64 = 4;
/// The fewest spheres the sphere texture holds (one row: two texels a sphere). The entry and
/// sphere textures are row textures ([`ROW_TEXELS`] a row); their capacities are whole rows.
const MIN_SPHERES: u32 = ROW_TEXELS / 2;
/// Bytes per sphere (one `ParticleInstance`, two `Rgba32Float` texels).
const SPHERE_BYTES: u64 = std::mem::size_of::<crate::frame::gpu_data::ParticleInstance>() as u64;
/// Bounds on the tiles per side (the scan of the row sums is one invocation over the rows).
const MIN_TILES: u32 = 8;
const MAX_TILES: u32 = 512;
/// Tiles across a typical particle's footprint.
const TILES_PER_FOOTPRINT: f32 = 4.0;
/// Slices of the light-distance order the lists are filled in (see the module's comment).
const SLICES: u32 = 32;
/// The lookup's entries per loop iteration (`EXACT_UNROLL` in shaders/shadow/exact.wgsl; a test
/// holds the two, and the lookup's `EXACT_CUT` to [`super::closed_form::OPTICAL_DEPTH_CUT`]).
const UNROLL: u32 = 8;

/// The longest list the lookup walks within `loop_budget` iterations: whole groups of
/// [`UNROLL`] entries, then fewer than [`UNROLL`] one at a time.
fn longest_walk(loop_budget: u32) -> u32 {
    UNROLL * loop_budget.saturating_sub(UNROLL)
}

/// The instances by their nearest distance from the light, |c - light| - r, and the lowest such
/// distance in each slice of `slice_size` of them, rounded down (the lookup stops at a slice
/// that starts beyond its point, so the bound must never be above a sphere's true distance:
/// f64, then less a relative 1e-5 and 1 µm, far more than the lookup's f32 rounding).
fn by_light_distance(
    light: glam::Vec3,
    instances: &[crate::frame::gpu_data::ParticleInstance],
) -> (Vec<crate::frame::gpu_data::ParticleInstance>, Vec<f32>, u32) {
    let light = light.as_dvec3();
    let near = |instance: &crate::frame::gpu_data::ParticleInstance| {
        let [x, y, z, r] = instance.center_radius;
        let d = glam::DVec3::new(f64::from(x), f64::from(y), f64::from(z)).distance(light)
            - f64::from(r);
        (d - 1e-5 * d.abs() - 1e-6) as f32
    };
    let keyed = sorted_by_key(instances, near);
    let slice_size = (instances.len() as u32).div_ceil(SLICES).max(1);
    let mut slice_near = vec![f32::INFINITY; SLICES as usize];
    for (slice, chunk) in keyed.chunks(slice_size as usize).enumerate() {
        // `as f32` rounds to nearest: step down once more where that rounded up.
        slice_near[slice] = chunk[0].0.next_down();
    }
    // On every core: at a million particles a GPU frame waits for this gather (the `upload`
    // pass of `bench`, docs/studies.md "The frame's clock on a real GPU").
    let sorted = keyed
        .par_iter()
        .map(|&(_, i)| instances[i as usize])
        .collect();
    (sorted, slice_near, slice_size)
}

/// The tiles per side for this frame's light space: a typical particle (mean radius at the mean
/// distance) spans about [`TILES_PER_FOOTPRINT`] tiles of the light's image plane.
fn tiles_for(light: &super::LightSpace) -> u32 {
    if light.mean_radius_m <= 0.0 {
        return MIN_TILES;
    }
    // The footprint's width in uv: 2r / (2 · dist · tan(fov/2)).
    let footprint_uv = light.mean_radius_m / (light.mean_dist_m.max(1e-3) * light.tan_half_fov);
    let tiles = (TILES_PER_FOOTPRINT / footprint_uv).ceil();
    (tiles as u32).clamp(MIN_TILES, MAX_TILES)
}

/// The per-tile buffers for one grid size.
struct Grid {
    tiles: u32,
    counts: wgpu::Buffer,
    offsets: wgpu::Buffer,
    /// Per-row sums for the scan (+1 for the total).
    row_sums: wgpu::Buffer,
}

pub struct Exact {
    params_buffer: wgpu::Buffer,
    grid: Grid,
    /// The lists' particle indices (`R32Uint`, [`ROW_TEXELS`] a row), and the entries it holds.
    entries: wgpu::Texture,
    capacity: u32,
    /// The spheres the lists index (a copy of the instances, `Rgba32Float`, two texels a
    /// sphere), and the particles it holds.
    spheres: wgpu::Texture,
    sphere_capacity: u32,
    /// The lowest light distance of each slice of the spheres (`SLICES` f32, storage).
    slice_near: wgpu::Buffer,
    /// Each slice's (first sphere, count) for the fill, one per `slice_stride` bytes (a
    /// uniform bound with a dynamic offset), and the slices this frame fills.
    fill_slices: wgpu::Buffer,
    slice_stride: u32,
    slice_size: u32,
    slices: u32,
    /// The instances in the order the lighting pass should light them (by light-space tile).
    lighting_order: Vec<u32>,
    /// The longest tile list last frame.
    max_list: u32,
    /// The adapter's loop budget, which bounds the lists and the footprints.
    loop_budget: Option<u32>,
    build_layout: wgpu::BindGroupLayout,
    count: wgpu::ComputePipeline,
    scan_rows: wgpu::ComputePipeline,
    scan_total: wgpu::ComputePipeline,
    scan_write: wgpu::ComputePipeline,
    fill: wgpu::ComputePipeline,
    lookup_layout: wgpu::BindGroupLayout,
    lookup_bind_group: wgpu::BindGroup,
    memory: MemoryLedger,
    /// Entries stored last frame.
    last_entries: u32,
}

/// A row texture (see [`ROW_TEXELS`]) of `texels` (a multiple of it) texels of `format`.
fn row_texture(
    memory: &mut MemoryLedger,
    device: &wgpu::Device,
    label: &str,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
    texels: u64,
) -> Result<wgpu::Texture, AllocationError> {
    memory.forget(label);
    memory.texture(
        device,
        &row_texture_descriptor(label, format, usage, texels),
    )
}

fn entry_texture(
    memory: &mut MemoryLedger,
    device: &wgpu::Device,
    capacity: u32,
) -> Result<wgpu::Texture, AllocationError> {
    row_texture(
        memory,
        device,
        "exact.entries",
        wgpu::TextureFormat::R32Uint,
        wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
        u64::from(capacity),
    )
}

fn sphere_texture(
    memory: &mut MemoryLedger,
    device: &wgpu::Device,
    capacity: u32,
) -> Result<wgpu::Texture, AllocationError> {
    row_texture(
        memory,
        device,
        "exact.spheres",
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        2 * u64::from(capacity),
    )
}

/// The instances in a Morton order of their centres' light-view position (1024² cells over the
/// light's image plane), so that consecutive particles sit in the same or neighbouring tiles.
fn lighting_order(
    light: &super::LightSpace,
    instances: &[crate::frame::gpu_data::ParticleInstance],
) -> Vec<u32> {
    const CELLS: f32 = 1024.0;
    let key = |instance: &crate::frame::gpu_data::ParticleInstance| {
        let [x, y, z, _] = instance.center_radius;
        let view = light
            .view_from_world
            .transform_point3(glam::Vec3::new(x, y, z));
        let ndc = glam::Vec2::new(view.x, view.y) / ((-view.z).max(1e-6) * light.tan_half_fov);
        let cell =
            ((ndc * 0.5 + 0.5) * CELLS).clamp(glam::Vec2::ZERO, glam::Vec2::splat(CELLS - 1.0));
        morton(cell.x as u32, cell.y as u32)
    };
    sorted_by_key(instances, key)
        .into_iter()
        .map(|(_, i)| i)
        .collect()
}

/// Every instance's (key, index), sorted by key (a radix sort: instances with equal keys stay in
/// their order); the keys are computed on every core.
fn sorted_by_key<K: radsort::Key + Send>(
    instances: &[crate::frame::gpu_data::ParticleInstance],
    key: impl Fn(&crate::frame::gpu_data::ParticleInstance) -> K + Sync,
) -> Vec<(K, u32)> {
    let mut keyed: Vec<(K, u32)> = instances
        .par_iter()
        .enumerate()
        .map(|(i, instance)| (key(instance), i as u32))
        .collect();
    radsort::sort_by_key(&mut keyed, |&(k, _)| k);
    keyed
}

/// `x` and `y` (below 2^16) with their bits interleaved, x in the even bits.
fn morton(x: u32, y: u32) -> u32 {
    fn spread(v: u32) -> u32 {
        let mut v = v & 0xffff;
        v = (v | (v << 8)) & 0x00ff_00ff;
        v = (v | (v << 4)) & 0x0f0f_0f0f;
        v = (v | (v << 2)) & 0x3333_3333;
        (v | (v << 1)) & 0x5555_5555
    }
    spread(x) | (spread(y) << 1)
}

fn storage_buffer(
    memory: &mut MemoryLedger,
    device: &wgpu::Device,
    label: &str,
    size: u64,
) -> Result<wgpu::Buffer, AllocationError> {
    memory.forget(label);
    memory.buffer(device, &storage_descriptor(label, size))
}

impl Grid {
    fn new(
        memory: &mut MemoryLedger,
        device: &wgpu::Device,
        tiles: u32,
    ) -> Result<Self, AllocationError> {
        let n = u64::from(tiles) * u64::from(tiles);
        Ok(Self {
            tiles,
            // The counts, then the widest and tallest footprint.
            counts: storage_buffer(memory, device, "exact.tile_counts", (n + 2) * 4)?,
            offsets: storage_buffer(memory, device, "exact.tile_offsets", (n + 1) * 4)?,
            row_sums: storage_buffer(memory, device, "exact.row_sums", (u64::from(tiles) + 1) * 4)?,
        })
    }
}

impl Exact {
    pub fn new(ctx: &TechniqueContext<'_>, params: &TechniqueParams) -> Result<Self, ShadowError> {
        let device = &ctx.gpu.device;
        let mut memory = MemoryLedger::for_technique(&ctx.gpu.limits, params.memory_limit_bytes);
        let params_buffer = memory.buffer(
            device,
            &wgpu::BufferDescriptor {
                label: Some("exact.params"),
                size: std::mem::size_of::<ExactParams>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            },
        )?;
        let grid = Grid::new(&mut memory, device, MIN_TILES)?;
        let slice_near = storage_buffer(
            &mut memory,
            device,
            "exact.slice_near",
            u64::from(SLICES) * 4,
        )?;
        let slice_stride = ctx.gpu.limits.min_uniform_buffer_offset_alignment.max(8);
        let fill_slices = memory.buffer(
            device,
            &wgpu::BufferDescriptor {
                label: Some("exact.fill_slices"),
                size: u64::from(SLICES) * u64::from(slice_stride),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            },
        )?;
        let sphere_capacity = MIN_SPHERES;
        let spheres = sphere_texture(&mut memory, device, sphere_capacity)?;
        let capacity = 1u32 << 16;
        let entries = entry_texture(&mut memory, device, capacity)?;

        let compute = wgpu::ShaderStages::COMPUTE;
        let unfilterable = wgpu::TextureSampleType::Float { filterable: false };
        let build_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("exact.build.layout"),
            entries: &[
                uniform_entry(0, compute),
                storage_entry(1, compute, false),
                storage_entry(2, compute, false),
                storage_texture_entry(
                    3,
                    compute,
                    wgpu::StorageTextureAccess::WriteOnly,
                    wgpu::TextureFormat::R32Uint,
                ),
                texture_entry(4, compute, unfilterable),
                storage_entry(6, compute, false),
                wgpu::BindGroupLayoutEntry {
                    binding: 7,
                    visibility: compute,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: true,
                        min_binding_size: wgpu::BufferSize::new(8),
                    },
                    count: None,
                },
            ],
        });
        let lookup_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("exact.lookup.layout"),
            entries: &[
                uniform_entry(0, LOOKUP_STAGES),
                storage_entry(1, LOOKUP_STAGES, true),
                texture_entry(2, LOOKUP_STAGES, wgpu::TextureSampleType::Uint),
                texture_entry(3, LOOKUP_STAGES, unfilterable),
                storage_entry(4, LOOKUP_STAGES, true),
            ],
        });
        let module = shaders::module(
            device,
            "exact.build",
            &shaders::compose("shadow/exact_build.wgsl", &[]),
        );
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("exact.build.pipeline_layout"),
            bind_group_layouts: &[Some(ctx.frame_layout), Some(&build_layout)],
            immediate_size: 0,
        });
        let pipeline = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(&format!("exact.{entry}")),
                layout: Some(&layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let lookup_bind_group = lookup_bind_group(
            device,
            &lookup_layout,
            [&params_buffer, &grid.offsets, &slice_near],
            [&entries, &spheres],
        );
        Ok(Self {
            count: pipeline("count"),
            scan_rows: pipeline("scan_rows"),
            scan_total: pipeline("scan_total"),
            scan_write: pipeline("scan_write"),
            fill: pipeline("fill"),
            params_buffer,
            grid,
            entries,
            capacity,
            spheres,
            sphere_capacity,
            slice_near,
            fill_slices,
            slice_stride,
            slice_size: 1,
            slices: 0,
            lighting_order: Vec::new(),
            max_list: 0,
            // The lookup's march through a density volume and the exact occluder test over the
            // boxes take their shares first.
            loop_budget: ctx.gpu.loop_budget().map(|b| {
                b.saturating_sub(crate::medium::frame::REFERENCE_LOOP_RESERVE)
                    .saturating_sub(crate::frame::occluders::OCCLUDER_LOOP_RESERVE)
            }),
            build_layout,
            lookup_layout,
            lookup_bind_group,
            memory,
            last_entries: 0,
        })
    }

    fn write_params(&self, gpu: &Gpu, light: &super::LightSpace, particle_count: u32) {
        gpu.queue.write_buffer(
            &self.params_buffer,
            0,
            bytemuck::bytes_of(&ExactParams {
                view_from_world: light.view_from_world.to_cols_array_2d(),
                tan_half_fov: light.tan_half_fov,
                tiles: self.grid.tiles,
                particle_count,
                capacity: self.capacity,
                slice_size: self.slice_size,
                _pad: [0; 3],
            }),
        );
    }

    fn build_bind_group(&self, device: &wgpu::Device) -> wgpu::BindGroup {
        let entries = self.entries.create_view(&Default::default());
        let spheres = self.spheres.create_view(&Default::default());
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("exact.build.bind_group"),
            layout: &self.build_layout,
            entries: &[
                bind_entry(0, &self.params_buffer),
                bind_entry(1, &self.grid.counts),
                bind_entry(2, &self.grid.offsets),
                texture_binding(3, &entries),
                texture_binding(4, &spheres),
                bind_entry(6, &self.grid.row_sums),
                wgpu::BindGroupEntry {
                    binding: 7,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &self.fill_slices,
                        offset: 0,
                        size: wgpu::BufferSize::new(8),
                    }),
                },
            ],
        })
    }

    /// Records the count and scan passes: afterwards the last offset holds the entries total.
    fn record_count(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &mut BuildInputs<'_>,
        bind_group: &wgpu::BindGroup,
    ) {
        encoder.clear_buffer(&self.grid.counts, 0, None);
        let rows = self.grid.tiles.div_ceil(64);
        let steps = [
            (&self.count, inputs.particle_count.div_ceil(64)),
            (&self.scan_rows, rows),
            (&self.scan_total, 1),
            (&self.scan_write, rows),
        ];
        self.dispatch_each(encoder, inputs, bind_group, &steps);
    }

    /// Records each (pipeline, workgroups) dispatch in a compute pass of its own, so that each
    /// one sees the previous one's writes whatever the backend's barriers within a pass.
    fn dispatch_each(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &mut BuildInputs<'_>,
        bind_group: &wgpu::BindGroup,
        steps: &[(&wgpu::ComputePipeline, u32)],
    ) {
        for &(pipeline, groups) in steps {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("exact.build"),
                timestamp_writes: inputs.timer.compute_pass("shadow"),
            });
            pass.set_bind_group(0, inputs.frame_bind_group, &[]);
            pass.set_bind_group(1, bind_group, &[0]);
            pass.set_pipeline(pipeline);
            // No smoke, no groups: the pass stays (its timestamps), its dispatch does not.
            if groups > 0 {
                pass.dispatch_workgroups(groups, 1, 1);
            }
        }
    }

    /// Slice `slice` of `particles` spheres: its first sphere and its count (the fill's range).
    fn slice_range(&self, slice: u32, particles: u32) -> [u32; 2] {
        let first = slice * self.slice_size;
        [first, self.slice_size.min(particles - first)]
    }

    /// Records the fill, a pass per slice in slice order (timed as one pass).
    fn record_fill(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &mut BuildInputs<'_>,
        bind_group: &wgpu::BindGroup,
    ) {
        let particle_count = inputs.instances.len() as u32;
        let span = inputs.timer.compute_span("shadow");
        for slice in 0..self.slices {
            let [_, count] = self.slice_range(slice, particle_count);
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("exact.fill"),
                timestamp_writes: inputs.timer.span_writes(
                    span,
                    slice == 0,
                    slice + 1 == self.slices,
                ),
            });
            pass.set_bind_group(0, inputs.frame_bind_group, &[]);
            pass.set_bind_group(1, bind_group, &[slice * self.slice_stride]);
            pass.set_pipeline(&self.fill);
            pass.dispatch_workgroups(count.div_ceil(64), 1, 1);
        }
    }

    /// Counts this frame's entries at the current grid (a submission and a readback of the
    /// per-tile counts): the total, the longest list, and the count's and fill's loop
    /// iterations for the largest footprint, height × (width + 1).
    async fn count_entries(
        &self,
        gpu: &Gpu,
        inputs: &mut BuildInputs<'_>,
        bind_group: &wgpu::BindGroup,
    ) -> Result<(u64, u32, u64), ShadowError> {
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("exact.count.encoder"),
            });
        self.record_count(&mut encoder, inputs, bind_group);
        gpu.queue.submit([encoder.finish()]);
        let tiles = u64::from(self.grid.tiles).pow(2);
        let words: Vec<u32> = read_buffer(gpu, &self.grid.counts, 0, (tiles + 2) * 4)
            .await
            .map_err(|err| ShadowError::Gpu(err.to_string()))?
            .chunks_exact(4)
            .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
            .collect();
        let (counts, footprint) = words.split_at(tiles as usize);
        let (total, max) = counts.iter().fold((0u64, 0u32), |(sum, max), &c| {
            (sum + u64::from(c), max.max(c))
        });
        let footprint_loops = u64::from(footprint[1]) * (u64::from(footprint[0]) + 1);
        Ok((total, max, footprint_loops))
    }
}

impl Exact {
    /// Uploads the spheres the lists index, in order of their nearest distance from the light,
    /// with their slices' bounds (the lookup's stop) and ranges (the fill's dispatches).
    fn upload_spheres(
        &mut self,
        gpu: &Gpu,
        light: glam::Vec3,
        instances: &[crate::frame::gpu_data::ParticleInstance],
    ) -> Result<(), ShadowError> {
        let (instances, slice_near, slice_size) = by_light_distance(light, instances);
        let instances = &instances[..];
        self.slice_size = slice_size;
        self.slices = (instances.len() as u32).div_ceil(slice_size);
        gpu.queue
            .write_buffer(&self.slice_near, 0, bytemuck::cast_slice(&slice_near));
        let mut ranges = vec![0u8; (SLICES * self.slice_stride) as usize];
        for slice in 0..self.slices {
            let at = (slice * self.slice_stride) as usize;
            let range = self.slice_range(slice, instances.len() as u32);
            ranges[at..at + 8].copy_from_slice(bytemuck::cast_slice(&range));
        }
        gpu.queue.write_buffer(&self.fill_slices, 0, &ranges);
        let needed = instances.len() as u32;
        if needed > self.sphere_capacity {
            // A power of two of at least one row: whole rows.
            // (More than one row: whole tiles of rows, `ROW_TILE`, as the texture holds them.)
            self.sphere_capacity = needed
                .next_power_of_two()
                .max(ROW_TEXELS / 2 * crate::gpu::ROW_TILE as u32);
            self.spheres = sphere_texture(&mut self.memory, &gpu.device, self.sphere_capacity)?;
        }
        // Whole rows: the last one padded with zeros (spheres no list indexes).
        let row_bytes = u64::from(ROW_TEXELS) * 16;
        let bytes: &[u8] = bytemuck::cast_slice(instances);
        let rows = (bytes.len() as u64).div_ceil(row_bytes);
        if rows == 0 {
            return Ok(());
        }
        let mut padded;
        let data = if bytes.len() as u64 == rows * row_bytes {
            bytes
        } else {
            padded = Vec::with_capacity((rows * row_bytes) as usize);
            padded.extend_from_slice(bytes);
            padded.resize((rows * row_bytes) as usize, 0);
            &padded[..]
        };
        gpu.queue.write_texture(
            self.spheres.as_image_copy(),
            data,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row_bytes as u32),
                rows_per_image: None,
            },
            wgpu::Extent3d {
                width: ROW_TEXELS,
                height: rows as u32,
                depth_or_array_layers: 1,
            },
        );
        Ok(())
    }
}

fn lookup_bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    [params, offsets, slice_near]: [&wgpu::Buffer; 3],
    [entries, spheres]: [&wgpu::Texture; 2],
) -> wgpu::BindGroup {
    let entries = entries.create_view(&Default::default());
    let spheres = spheres.create_view(&Default::default());
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("exact.lookup.bind_group"),
        layout,
        entries: &[
            bind_entry(0, params),
            bind_entry(1, offsets),
            texture_binding(2, &entries),
            texture_binding(3, &spheres),
            bind_entry(4, slice_near),
        ],
    })
}

impl ShadowTechnique for Exact {
    fn name(&self) -> &'static str {
        ENTRY.name
    }
    fn channels_used(&self) -> u32 {
        0
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

    /// `tiles_per_side`: the light-space grid; `tile_entries`: (particle, tile) pairs stored
    /// last frame; `entry_capacity`: what the list buffer holds; `max_tile_list`: the longest
    /// list last frame; `slice_stride`: bytes per slice of the fill's ranges (the adapter's
    /// uniform offset alignment).
    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![
            ("tiles_per_side", u64::from(self.grid.tiles)),
            ("tile_entries", u64::from(self.last_entries)),
            ("entry_capacity", u64::from(self.capacity)),
            ("sphere_capacity", u64::from(self.sphere_capacity)),
            ("max_tile_list", u64::from(self.max_list)),
            ("slice_stride", u64::from(self.slice_stride)),
        ]
    }

    fn lighting_order(&self) -> Option<&[u32]> {
        Some(&self.lighting_order)
    }

    fn build<'a>(
        &'a mut self,
        gpu: &'a Gpu,
        inputs: BuildInputs<'a>,
    ) -> GpuFuture<'a, Result<(), ShadowError>> {
        Box::pin(async move {
            let mut inputs = inputs;
            let device = &gpu.device;
            // The entries one texture holds: whole rows, as many as the adapter allows.
            let max_entries = u64::from(ROW_TEXELS)
                * crate::gpu::max_texture_rows(gpu.limits.max_texture_dimension_2d);
            let limit = max_entries * ENTRY_BYTES;
            let fits = |entries: u64| entries <= max_entries;
            self.upload_spheres(gpu, inputs.light.position, inputs.instances)?;
            self.lighting_order = lighting_order(inputs.light, inputs.instances);

            // Count at the grid this frame's particles ask for, halving it while the lists would not
            // fit one binding or, on llvmpipe, while some particle's footprint covers more tiles
            // than the count's and fill's loops may visit.
            let mut tiles = tiles_for(inputs.light);
            let total = loop {
                if self.grid.tiles != tiles {
                    self.grid = Grid::new(&mut self.memory, device, tiles)?;
                }
                self.write_params(gpu, inputs.light, inputs.particle_count);
                let bind_group = self.build_bind_group(device);
                let (total, max_list, footprint_loops) =
                    self.count_entries(gpu, &mut inputs, &bind_group).await?;
                // On llvmpipe a footprint of more tiles than a loop may visit would be binned short.
                // The walk over one footprint loops its tile rows × (tiles per row + 1) times; a
                // grid too fine for the budget is halved (8² tiles need at most 72).
                let loops_fit = self
                    .loop_budget
                    .is_none_or(|budget| footprint_loops <= u64::from(budget));
                if fits(total) && (loops_fit || tiles == MIN_TILES) {
                    self.max_list = max_list;
                    break total;
                }
                if tiles == MIN_TILES && !fits(total) {
                    return Err(ShadowError::TileListsTooLarge {
                        particles: inputs.particle_count,
                        bytes: total * ENTRY_BYTES,
                        limit,
                    });
                }
                tiles = (tiles / 2).max(MIN_TILES);
            };
            // One lookup per invocation (particle lighting, opaque pass, probe): a list may take
            // the whole loop budget.
            if let Some(limit) = self.loop_budget.map(longest_walk)
                && self.max_list > limit
            {
                return Err(ShadowError::TileListTooLong {
                    particles: inputs.particle_count,
                    tiles: self.grid.tiles,
                    longest: self.max_list,
                    limit,
                });
            }
            if total > u64::from(self.capacity) {
                // Headroom so that a slowly changing scene does not reallocate every frame; whole
                // tiles of texture rows (`ROW_TILE`), as the texture holds them.
                let whole_rows =
                    |n: u64| n.next_multiple_of(u64::from(ROW_TEXELS) * crate::gpu::ROW_TILE);
                let mut capacity = whole_rows((total + total / 4).max(1 << 16));
                if !fits(capacity) {
                    capacity = whole_rows(total);
                }
                self.capacity = capacity as u32;
                self.entries = entry_texture(&mut self.memory, device, self.capacity)?;
            }
            self.last_entries = total as u32;
            self.write_params(gpu, inputs.light, inputs.particle_count);
            let bind_group = self.build_bind_group(device);
            self.lookup_bind_group = lookup_bind_group(
                device,
                &self.lookup_layout,
                [&self.params_buffer, &self.grid.offsets, &self.slice_near],
                [&self.entries, &self.spheres],
            );

            // The counts, cleared, become the fill's cursors.
            let mut encoder = std::mem::replace(
                inputs.encoder,
                device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default()),
            );
            encoder.clear_buffer(&self.grid.counts, 0, None);
            self.record_fill(&mut encoder, &mut inputs, &bind_group);
            *inputs.encoder = encoder;
            Ok(())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn light(mean_radius_m: f32, mean_dist_m: f32) -> super::super::LightSpace {
        super::super::LightSpace {
            position: glam::Vec3::ZERO,
            clip_from_world: glam::Mat4::IDENTITY,
            view_from_world: glam::Mat4::IDENTITY,
            tan_half_fov: 0.5,
            near_m: 1.0,
            far_m: 2.0,
            max_radius_m: mean_radius_m,
            mean_radius_m,
            mean_dist_m,
            face: None,
            cone_view_from_world: glam::Mat4::IDENTITY,
            cone_tan_half_fov: 0.5,
        }
    }

    #[test]
    fn morton_interleaves_x_into_the_even_bits() {
        assert_eq!(morton(0, 0), 0);
        assert_eq!(morton(1, 0), 1);
        assert_eq!(morton(0, 1), 2);
        assert_eq!(morton(3, 3), 15);
        assert_eq!(morton(0b1010, 0b0101), 0b0110_0110);
        assert_eq!(morton(1023, 1023), (1 << 20) - 1);
    }

    #[test]
    fn the_lighting_order_is_a_permutation_that_keeps_light_space_neighbours_together() {
        use crate::frame::gpu_data::ParticleInstance;
        use rand::SeedableRng;
        use rand::seq::SliceRandom;
        // A light at the origin looking down -z (tan 0.5): particles on a 16x16 grid of its
        // image plane at z = -10 (0.6 m apart), in a shuffled order.
        let light = light(0.1, 10.0);
        let mut cells: Vec<(f32, f32)> = (0..256)
            .map(|i| ((i % 16) as f32, (i / 16) as f32))
            .collect();
        cells.shuffle(&mut rand_pcg::Pcg64::seed_from_u64(1));
        let instances: Vec<ParticleInstance> = cells
            .iter()
            .map(|&(x, y)| ParticleInstance {
                center_radius: [(x - 7.5) * 0.6, (y - 7.5) * 0.6, -10.0, 0.1],
                albedo_density: [1.0; 4],
            })
            .collect();
        let order = lighting_order(&light, &instances);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..256).collect::<Vec<u32>>());
        // The path through the grid in that order, in grid steps: a Morton curve's is under
        // twice the 255 of a perfect walk (397 here); the shuffled order's is about 2,100.
        let path = |order: &mut dyn Iterator<Item = usize>| {
            let points: Vec<glam::Vec2> = order.map(|i| glam::Vec2::from(cells[i])).collect();
            points.windows(2).map(|w| w[0].distance(w[1])).sum::<f32>()
        };
        let ordered = path(&mut order.iter().map(|&i| i as usize));
        let shuffled = path(&mut (0..256));
        assert!(ordered < 2.0 * 255.0, "{ordered}");
        assert!(shuffled > 4.0 * ordered, "{shuffled} vs {ordered}");
    }

    #[test]
    fn the_lookups_constants_are_the_ones_the_build_and_the_cpu_mirror_use() {
        let wgsl = crate::shaders::source("shadow/exact.wgsl").unwrap();
        let unroll = format!("const EXACT_UNROLL: u32 = {UNROLL}u;");
        assert!(wgsl.contains(&unroll), "{unroll}");
        let cut = format!(
            "const EXACT_CUT: f32 = {:.1};",
            super::super::closed_form::OPTICAL_DEPTH_CUT
        );
        assert!(wgsl.contains(&cut), "{cut}");
    }

    #[test]
    fn a_typical_particle_spans_four_tiles_within_the_bounds() {
        // Footprint 2r / (2 · 10 · 0.5) = 0.05 of the image: 4 / 0.05 = 80 tiles.
        assert_eq!(tiles_for(&light(0.25, 10.0)), 80);
        assert_eq!(tiles_for(&light(5.0, 10.0)), MIN_TILES);
        assert_eq!(tiles_for(&light(1e-4, 10.0)), MAX_TILES);
        assert_eq!(tiles_for(&light(0.0, 0.0)), MIN_TILES);
    }
}
