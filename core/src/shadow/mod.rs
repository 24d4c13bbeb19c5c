//! Shadow techniques: the shared interface and the registry (thesis 3.3.3).
//!
//! A technique turns the particles, seen from the spotlight, into something the lighting shaders
//! can ask "how much light reaches world point p?" — the transmittance T(p). Every technique
//! works under a **channel budget** (render-target components), as in the thesis' chapter 4.
//!
//! Shape of a technique (see `osm.rs`, or `half_angle.rs` for one that draws the particles):
//! - `new` builds its pipelines, layouts and maps once, recording every allocation in a
//!   [`MemoryLedger`] so the bytes it reports are the bytes it owns;
//! - [`ShadowTechnique::build`] records its passes into the frame's encoder each frame;
//! - its registry entry names the lookup shader (`shaders/shadow/<name>.wgsl`) that defines
//!   `fn shadow_transmittance(p: vec3<f32>) -> f32` and its bindings in group 1; the renderer
//!   composes it into the opaque and particle shaders (`#import shadow_technique`).
//!
//! Adding a technique: a new `src/shadow/<name>.rs` with a `pub const ENTRY`, its shaders under
//! `shaders/shadow/`, and one line in [`REGISTRY`].

pub mod avsm;
pub mod bsm;
pub mod closed_form;
pub mod deep_capture;
pub mod deep_compress;
pub mod deep_nodes;
pub mod dom;
pub mod dsm;
pub mod esm;
pub mod exact;
pub mod fom;
pub mod half_angle;
pub mod layered;
pub mod light_maps;
pub mod light_space;
pub mod moment_math;
pub mod msm;
pub mod none;
pub mod osm;
pub mod probe;
pub mod slice_interp;
pub mod srm;
pub mod volume;

pub use light_space::LightSpace;

use crate::frame::CameraMatrices;
use crate::gpu::{Gpu, GpuTimer, MemoryLedger};
use crate::sim::Particle;

/// Stages that call `shadow_transmittance`: the particle pass lights per vertex, the opaque pass
/// per fragment. Lookup bind group layouts use this visibility.
/// The transmittance probe calls it from a compute shader.
pub const LOOKUP_STAGES: wgpu::ShaderStages =
    wgpu::ShaderStages::VERTEX_FRAGMENT.union(wgpu::ShaderStages::COMPUTE);

/// Channel budgets every technique accepts up to (one RGBA target carries 4 channels; 8 targets
/// a pass). Some go further (their registry line's `max_channels`): `osm` and `dom` in several
/// passes, `has` in more slices.
pub const MAX_CHANNELS: u32 = 32;

/// Errors in choosing or configuring a technique. Each renders as one line.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ShadowError {
    #[error("{technique} cannot shadow this scene's density volume: {why}")]
    VolumeUnsupported {
        technique: &'static str,
        why: &'static str,
    },
    #[error("{0}")]
    Volume(String),
    #[error(
        "{technique} lights its particles in its own pass, which the shadow's temporal history \
         ([shadow] history = {weight}) does not filter: set it to 0 for {technique}"
    )]
    HistoryUnsupported {
        technique: &'static str,
        weight: f32,
    },
    #[error(
        "{technique} cannot shadow this scene's {particles} particles: it marches a density \
         volume only"
    )]
    ParticlesUnsupported {
        technique: &'static str,
        particles: usize,
    },
    #[error("unknown technique \"{name}\"; valid techniques: {valid}")]
    UnknownTechnique { name: String, valid: String },
    #[error("--channels {channels} is out of range for {technique}: allowed {min}..={max}")]
    ChannelsOutOfRange {
        technique: &'static str,
        channels: u32,
        min: u32,
        max: u32,
    },
    #[error(
        "{technique} at {channels} channels needs {needed} colour attachments of \
         {bytes_per_sample} bytes per sample, but the adapter allows {allowed_attachments} \
         attachments and {allowed_bytes} bytes per sample"
    )]
    AdapterLimit {
        technique: &'static str,
        channels: u32,
        needed: u32,
        bytes_per_sample: u32,
        allowed_attachments: u32,
        allowed_bytes: u32,
    },
    #[error(
        "exact's tile lists for {particles} particles need {bytes} bytes even at its coarsest \
         grid, but the adapter's largest texture holds {limit} bytes of them"
    )]
    TileListsTooLarge {
        particles: u32,
        bytes: u64,
        limit: u64,
    },
    #[error(
        "exact: {particles} particles put {longest} spheres in one of its {tiles}x{tiles} light \
         tiles, but llvmpipe ends shader loops after 65,535 iterations, which allows {limit} per \
         list: use fewer particles, or a hardware adapter"
    )]
    TileListTooLong {
        particles: u32,
        tiles: u32,
        longest: u32,
        limit: u32,
    },
    #[error(
        "{technique}: {longest} particle fragments fall in one texel of its \
         {resolution_px}x{resolution_px} capture, but llvmpipe ends shader loops after 65,535 \
         iterations, which allows {limit} per texel (the count along a light ray, whatever the \
         resolution): use fewer particles, or a hardware adapter"
    )]
    TexelListTooLong {
        technique: &'static str,
        resolution_px: u32,
        longest: u32,
        limit: u32,
    },
    #[error(
        "{technique} at {resolution_px}x{resolution_px} captures {segments} segments in row \
         {row} of its map alone this frame, but one band of its lists holds at most {limit} \
         segments on this adapter (its largest storage binding or texture) within its memory \
         limit: use a lower --shadow-res or a larger budget"
    )]
    CaptureTooLarge {
        technique: &'static str,
        resolution_px: u32,
        row: u32,
        segments: u64,
        limit: u64,
    },
    #[error(
        "volume: {particles} particles cover {rows} voxel rows of its {side}³ grid this frame, \
         more than one scatter dispatch numbers ({limit}): use fewer particles or a smaller \
         budget"
    )]
    VoxelRowsTooMany {
        particles: u32,
        side: u32,
        rows: u64,
        limit: u64,
    },
    #[error(
        "unknown technique parameter \"{key}\"; valid parameters: {valid} (`smokeshadow info` \
         describes them)"
    )]
    UnknownParam { key: String, valid: String },
    #[error(transparent)]
    Param(#[from] ParamError),
    #[error(
        "{technique} slices the particles along one light direction, from the point light to \
         the smoke's centroid, but {behind} of the {particles} particles lie behind the light \
         along it: move the light out of the smoke, or use another technique"
    )]
    PointLightBehind {
        technique: &'static str,
        behind: u32,
        particles: u32,
    },
    #[error("{technique} needs the adapter feature {feature}, which this adapter lacks")]
    MissingFeature {
        technique: &'static str,
        feature: &'static str,
    },
    #[error(transparent)]
    Allocation(#[from] crate::gpu::AllocationError),
    #[error("{0}")]
    Gpu(String),
    /// A technique that draws its own particle pass (`has`) renders it at full resolution only.
    #[error(
        "--particle-res {res}: {technique} draws its own particle pass (its half-angle slices), which renders at full resolution only; use --particle-res 1"
    )]
    ParticleResUnsupported {
        technique: &'static str,
        res: &'static str,
    },
}

pub use crate::scene::technique::{
    OccluderMode, ParamError, ParamSpec, ParamValue, SplatMode, TechniqueParams,
};

/// Sets `key` to `value` in `params` after checking both against the registry (a choice is
/// kept by its name, whether given by name or by index).
pub fn set_param(
    params: &mut TechniqueParams,
    key: &str,
    value: &ParamValue,
) -> Result<(), ShadowError> {
    let spec = find_param(key)?;
    let value = spec.canonical(value)?;
    params.values.insert(spec.key.to_owned(), value);
    Ok(())
}

/// Checks every parameter value set in `params` against the registry: a scene's
/// `[shadow.params]` reaches a technique only through here.
pub fn check_params(params: &TechniqueParams) -> Result<(), ShadowError> {
    for (key, value) in &params.values {
        find_param(key)?.resolve(value)?;
    }
    Ok(())
}

/// What a technique is for, which decides where the program uses it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// No shadow at all: the frame time every overhead is measured against (one sweep row).
    FrameBaseline,
    /// The exact transmittance every error is measured against.
    Reference,
    /// A technique under comparison.
    Contender,
}

/// What a technique needs from the renderer to build its pipelines.
pub struct TechniqueContext<'a> {
    pub gpu: &'a Gpu,
    /// Layout of group 0 (`Frame` uniforms), shared by every pass.
    pub frame_layout: &'a wgpu::BindGroupLayout,
    /// Layout of the opaque depth the particle pass reads (group 2 of the particle pipelines),
    /// for techniques that draw the particles themselves.
    pub depth_layout: &'a wgpu::BindGroupLayout,
    /// Layouts of the per-particle lighting buffers, for the same.
    pub particle_layouts: &'a crate::frame::ParticleLayouts,
}

/// What a technique gets each frame to build its maps.
pub struct BuildInputs<'a> {
    pub encoder: &'a mut wgpu::CommandEncoder,
    pub timer: &'a mut GpuTimer,
    pub frame_bind_group: &'a wgpu::BindGroup,
    /// Particle instances (see `ParticleInstance`), `particle_count` of them, sorted back to
    /// front for the camera.
    pub particles: &'a wgpu::Buffer,
    pub particle_count: u32,
    /// The same instances on the CPU, in the buffer's order.
    pub instances: &'a [crate::frame::gpu_data::ParticleInstance],
    pub light: &'a LightSpace,
    /// The world box (min, max) of the scene's density volume, if it holds one (group 0's
    /// grid, `crate::medium::frame`): a technique that shadows it builds it into its maps too.
    pub volume: Option<(glam::Vec3, glam::Vec3)>,
}

/// What a technique that draws the particles itself (see [`ShadowTechnique::particle_pass`])
/// gets each frame, after the opaque pass.
pub struct ParticlePassInputs<'a> {
    pub encoder: &'a mut wgpu::CommandEncoder,
    pub timer: &'a mut GpuTimer,
    pub frame_bind_group: &'a wgpu::BindGroup,
    /// The particles in simulation order; the technique sorts them as it needs (timed).
    pub particles: &'a [Particle],
    pub camera: &'a CameraMatrices,
    pub light: &'a LightSpace,
    /// Unit axis of the spotlight's cone.
    pub light_axis: glam::Vec3,
    /// The frame's HDR target, holding the opaque pass; the technique composites the smoke
    /// over it with premultiplied "over" and leaves the smoke's opacity in its alpha.
    pub hdr_view: &'a wgpu::TextureView,
    pub hdr_size: (u32, u32),
    /// The opaque depth as a group-2 bind group (spherical billboards) and as an attachment
    /// (flat billboards' depth test).
    pub depth_bind_group: &'a wgpu::BindGroup,
    pub depth_view: &'a wgpu::TextureView,
    pub spherical: bool,
    /// The frame's one sort, when it ran along the half-angle
    /// ([`crate::render::SortOrder::HalfAngle`]): a technique that draws in that order uses
    /// it instead of sorting again.
    pub shared_order: Option<SharedOrder<'a>>,
    /// Under a point light, the technique in the other cube faces' light spaces (the owner is
    /// the first face's): it fills their maps and lights their points as it goes.
    pub other_faces: Vec<OtherFace<'a>>,
}

/// The technique in another face of a point light's cube, with that face's group 0.
pub struct OtherFace<'a> {
    pub frame_bind_group: &'a wgpu::BindGroup,
    pub technique: &'a mut dyn ShadowTechnique,
}

/// The particles as the frame sorted them along the half-angle.
#[derive(Clone, Copy)]
pub struct SharedOrder<'a> {
    pub slicing: half_angle::Slicing,
    /// The instances back to front for the eye along `slicing.axis`.
    pub eye_back_to_front: &'a [crate::frame::gpu_data::ParticleInstance],
}

/// What a technique with its own probe (see [`ShadowTechnique::probe_pass`]) gets: the frame's
/// encoder after its build pass, and the generic probe pipeline to dispatch with its bindings.
pub struct ProbeInputs<'a> {
    pub encoder: wgpu::CommandEncoder,
    pub frame_bind_group: &'a wgpu::BindGroup,
    pub particles: &'a [Particle],
    pub light: &'a LightSpace,
    pub light_axis: glam::Vec3,
    pub camera_forward: glam::Vec3,
    pub probe: &'a probe::Probe,
    pub points: &'a [glam::Vec3],
    /// For each point, the index in `particles` of the particle whose lighting point it is
    /// (`render::shaded::point_owners`), or [`NO_OWNER`] for an opaque surface's point: a
    /// technique whose frame lights a particle's points together (`has`, batch by batch) gives
    /// an owned point the T its particle's lighting sees, and an opaque one the T the frame's
    /// opaque pass reads. `None`: every point is free (in the smoke, as a particle there).
    pub owners: Option<&'a [u32]>,
    /// As [`ParticlePassInputs::other_faces`].
    pub other_faces: Vec<OtherFace<'a>>,
}

/// The owner of a probed point that is no particle's lighting point ([`ProbeInputs::owners`]).
pub const NO_OWNER: u32 = u32::MAX;

/// A technique whose transmittance depends on more than its maps after the build pass.
pub trait ProbePass {
    /// Submits `inputs.encoder` and whatever else it needs; returns T per point.
    fn probe<'a>(
        &'a mut self,
        gpu: &'a Gpu,
        inputs: ProbeInputs<'a>,
    ) -> GpuFuture<'a, anyhow::Result<Vec<f32>>>;
}

/// How the values in a map channel read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapKind {
    /// Optical depth (shown as the opacity 1 − e^−Ω).
    OpticalDepth,
    /// A light depth normalised to the smoke's bounds, in [0, 1].
    Depth01,
    /// A signed quantity (Fourier coefficients).
    Signed,
}

/// One texture of a technique's maps, for inspection.
pub struct DebugMap<'a> {
    /// A 2D view of the texture (one layer).
    pub view: &'a wgpu::TextureView,
    /// What each of its channels holds, e.g. "slice 5 of 24"; one entry per channel in use.
    pub channels: Vec<String>,
    pub kind: MapKind,
}

/// A technique's own particle pass.
pub trait ParticlePass {
    /// Records the eye pass; returns the CPU time of its own sort, milliseconds, or `None` when
    /// it drew in the frame's shared order instead. Fails only when a buffer it must grow
    /// cannot be held.
    fn record(
        &mut self,
        gpu: &Gpu,
        inputs: ParticlePassInputs<'_>,
    ) -> Result<Option<f64>, ShadowError>;
    /// Records `batch` of `instances` (all of it when `None`) into this face's light maps seen
    /// through `frame_bind_group`, cleared first when `clear`: how the owner of the particle
    /// pass fills a point light's other faces ([`ParticlePassInputs::other_faces`]).
    fn light_batch(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut GpuTimer,
        frame_bind_group: &wgpu::BindGroup,
        instances: &wgpu::Buffer,
        batch: Option<std::ops::Range<u32>>,
        clear: bool,
    );
    /// Every particle as the last frame's lighting lit it (its lighting buffer read back, in
    /// its own order), so that tests and the sweep see the T the frame rendered.
    fn lit_particles<'a>(
        &'a self,
        gpu: &'a Gpu,
    ) -> GpuFuture<'a, Result<Vec<crate::frame::particles::LitParticle>, crate::gpu::GpuError>>;
}

/// What an awaited trait method returns: boxed, so that the techniques stay trait objects; not
/// `Send`, since a frame is awaited on the thread that records it.
pub type GpuFuture<'a, T> = std::pin::Pin<Box<dyn std::future::Future<Output = T> + 'a>>;

/// The interface every shadow technique implements.
pub trait ShadowTechnique: Send {
    /// Registry name (snake_case), as used on the CLI and in file names.
    fn name(&self) -> &'static str;
    /// Channels of the budget this configuration actually uses.
    fn channels_used(&self) -> u32;
    /// Every GPU allocation the technique owns.
    fn memory(&self) -> &MemoryLedger;
    /// Layout of group 1 as the lookup shader declares it.
    fn bind_group_layout(&self) -> &wgpu::BindGroupLayout;
    /// The group-1 bind group for the lookup.
    fn bind_group(&self) -> &wgpu::BindGroup;
    /// Records this frame's shadow passes. Fails only when this frame's maps cannot be held
    /// (`exact`'s lists beyond the adapter's buffer limits).
    /// Awaited: a technique may read counts back mid-build to size its lists.
    fn build<'a>(
        &'a mut self,
        gpu: &'a Gpu,
        inputs: BuildInputs<'a>,
    ) -> GpuFuture<'a, Result<(), ShadowError>>;
    /// `Some` when the technique draws the particles to the eye itself (half-angle slicing
    /// interleaves eye and light passes). `None`, the default: the renderer draws the sorted
    /// particles, lit through `shadow_transmittance`.
    fn particle_pass(&mut self) -> Option<&mut dyn ParticlePass> {
        None
    }
    /// `Some` when T(p) at a point is not simply the lookup over the built maps (half-angle
    /// slicing: it depends on which slice the point falls in). `None`, the default: the probe
    /// dispatches `shadow_transmittance` with [`ShadowTechnique::bind_group`].
    fn probe_pass(&mut self) -> Option<&mut dyn ProbePass> {
        None
    }
    /// The order the lighting pass should light the last built frame's particles in: a
    /// permutation of the instance indices, or `None` (the default: instance order). Only speed
    /// depends on it, never a value: each particle's lighting is its own. `exact` orders them by
    /// light-space tile, so that the particles lit together walk the same tile lists.
    fn lighting_order(&self) -> Option<&[u32]> {
        None
    }
    /// Technique-specific counts from the last frame, for reports (e.g. `exact`'s segments).
    fn counters(&self) -> Vec<(&'static str, u64)> {
        Vec::new()
    }
    /// The maps this frame's lookups read, for inspection (the viewer shows each channel).
    fn debug_maps(&self) -> Vec<DebugMap<'_>> {
        Vec::new()
    }
}

/// What a technique's memory depends on.
pub struct MemoryCase<'a> {
    /// The technique's parameters: its channel budget and resolution, and technique-specific
    /// ones such as a layered map's `<technique>_precision`.
    pub params: &'a TechniqueParams,
    /// Particles drawn this frame.
    pub particles: u64,
    /// Pixels of the frame.
    pub frame_pixels: u64,
    /// The technique's [`ShadowTechnique::counters`] after the frame (list capacities).
    pub counters: &'a [(&'static str, u64)],
}

impl MemoryCase<'_> {
    /// The channel budget.
    pub fn channels(&self) -> u32 {
        self.params.channels
    }

    /// The shadow map's resolution (texels per side).
    pub fn resolution_px(&self) -> u32 {
        self.params.resolution_px
    }

    /// Texels of one shadow map.
    pub fn texels(&self) -> u64 {
        u64::from(self.resolution_px()) * u64::from(self.resolution_px())
    }

    /// A counter by name (0 when absent).
    pub fn counter(&self, name: &str) -> u64 {
        self.counters
            .iter()
            .find(|(n, _)| *n == name)
            .map_or(0, |(_, v)| *v)
    }
}

/// The channels a configuration uses and the bytes it allocates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryUse {
    pub channels: u64,
    /// Everything allocated, transient bytes included.
    pub bytes: u64,
    /// The part of `bytes` that is build scratch the lookup never reads (a deep capture's
    /// uncompressed lists; see `MemoryLedger::transient_bytes`).
    pub transient_bytes: u64,
}

/// Bytes of `packed` channels of `bytes_per_channel` per texel, packed 4 to a target, where a
/// remainder of 1 or 2 channels gets an R or RG target and a remainder of 3 a 4-channel one.
pub fn packed_bytes_per_texel(packed: u64, bytes_per_channel: u64) -> u64 {
    let rest = match packed % 4 {
        0 => 0,
        1 => 1,
        2 => 2,
        _ => 4,
    };
    (packed / 4 * 4 + rest) * bytes_per_channel
}

/// What `entry`'s memory formula gives for `params` before any frame (no counters: list
/// capacities, which only transient scratch depends on, read as 0), for `particles` particles in
/// a frame of `frame_pixels`.
pub fn planned_memory(
    entry: &TechniqueEntry,
    params: &TechniqueParams,
    particles: u64,
    frame_pixels: u64,
) -> MemoryUse {
    (entry.memory)(&MemoryCase {
        params,
        particles,
        frame_pixels,
        counters: &[],
    })
}

/// The bytes a configuration plans to hold (its memory formula before a build: what the lookup
/// reads and the least build scratch it can shed to, resident bytes) per texel of its shadow
/// map, for `particles` particles in a frame of `frame_pixels`: the measure a byte budget per
/// texel (`--bytes-per-texel`) fits configurations by. The build then holds itself to the
/// budget's bytes ([`TechniqueParams::memory_limit_bytes`]), shedding scratch to fit.
pub fn planned_bytes_per_texel(
    entry: &TechniqueEntry,
    params: &TechniqueParams,
    particles: u64,
    frame_pixels: u64,
) -> f64 {
    planned_use(entry, params, particles, frame_pixels).1
}

/// The channels a configuration uses and the bytes it plans to hold per texel
/// ([`planned_bytes_per_texel`]), from one evaluation of its memory formula: what tells two
/// configurations apart under a byte budget.
pub fn planned_use(
    entry: &TechniqueEntry,
    params: &TechniqueParams,
    particles: u64,
    frame_pixels: u64,
) -> (u64, f64) {
    let used = planned_memory(entry, params, particles, frame_pixels);
    let texels = u64::from(params.resolution_px).pow(2).max(1);
    (used.channels, used.bytes as f64 / texels as f64)
}

/// The configuration a technique takes under a byte budget per shadow-map texel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ByteFit {
    /// The channel budget: the largest whose configuration plans to hold at most the budget
    /// (resident bytes, uniforms and least scratch included), lowered to the smallest budget
    /// with the same memory (`fom` at 12 channels uses 11, so it runs at 11).
    pub channels: u32,
    /// The channels that configuration uses (its memory formula's): two budgets with the same
    /// channels used and bytes are the same configuration.
    pub channels_used: u64,
    /// Bytes per texel it plans to hold there.
    pub bytes_per_texel: f64,
}

/// The bytes a texel a memory budget of `total` bytes gives a `resolution`² map (what
/// [`fit_bytes_per_texel`] fits a technique into), or one line saying why it gives none: not a
/// whole number of bytes a texel there, or more than 4 GiB a texel.
pub fn memory_per_texel(total: u64, resolution: u32) -> Result<u32, String> {
    let area = u64::from(resolution).pow(2);
    if !total.is_multiple_of(area) {
        return Err(format!(
            "{} is not a whole number of bytes a texel at {resolution}² ({:.2})",
            crate::gpu::memory::bytes(total),
            total as f64 / area as f64
        ));
    }
    u32::try_from(total / area).map_err(|_| "more than 4 GiB a texel".to_owned())
}

/// Fits `entry`, with `base`'s parameters (its precision among them), into `budget` bytes per
/// texel at `base.resolution_px`. `Err`: one line saying why it fits no configuration.
pub fn fit_bytes_per_texel(
    entry: &TechniqueEntry,
    base: &TechniqueParams,
    budget: u32,
    particles: u64,
    frame_pixels: u64,
) -> Result<ByteFit, String> {
    // (channels used, bytes held per texel) at a channel budget.
    let at = |channels: u32| {
        let params = TechniqueParams {
            channels,
            ..base.clone()
        };
        planned_use(entry, &params, particles, frame_pixels)
    };
    let allowed = f64::from(budget);
    let Some(largest) = (entry.min_channels..=entry.max_channels)
        .rev()
        .find(|&c| at(c).1 <= allowed)
    else {
        let res = u64::from(base.resolution_px);
        let least = at(entry.min_channels).1;
        return Err(format!(
            "{} holds {least:.1} bytes a texel at its smallest budget ({}; {} bytes at {res}², \
             scratch and uniforms included), more than {budget} ({} bytes)",
            entry.name,
            (entry.budget_caption)(entry.min_channels),
            (least * (res * res) as f64).round() as u64,
            u64::from(budget) * res * res,
        ));
    };
    let fitted = at(largest);
    let channels = (entry.min_channels..=largest)
        .find(|&c| at(c) == fitted)
        .unwrap_or(largest);
    Ok(ByteFit {
        channels,
        channels_used: fitted.0,
        bytes_per_texel: fitted.1,
    })
}

/// Builds a technique from the GPU context and its (already range-checked) parameters.
pub type CreateFn =
    fn(&TechniqueContext<'_>, &TechniqueParams) -> Result<Box<dyn ShadowTechnique>, ShadowError>;

/// One registry line: everything the program asks about a technique.
pub struct TechniqueEntry {
    pub name: &'static str,
    pub description: &'static str,
    pub role: Role,
    /// What a budget of B channels buys, for captions ("24 slices", "1 depth + 23 layers").
    pub budget_caption: fn(u32) -> String,
    /// Smallest channel budget the technique can work with.
    pub min_channels: u32,
    /// Largest channel budget: [`MAX_CHANNELS`] where a channel is a map's (eight RGBA16F
    /// attachments); `has`'s budget is batches, each a set of passes and 256 bytes of ranges
    /// ([`half_angle::MAX_HAS_SLICES`]).
    pub max_channels: u32,
    /// Whether the default sweep and the default comparison include it.
    pub in_default_sweep: bool,
    pub in_default_compare: bool,
    /// Whether its build reads back from the GPU (and so stalls the frame): the viewer renders
    /// such a technique on its worker thread.
    pub build_reads_back: bool,
    /// Its own parameters.
    pub params: &'static [ParamSpec],
    /// Whether T(p) is independent of the order the particles are drawn in (additive, min or
    /// max blending); the order-independence test holds every such technique to it.
    pub order_independent: bool,
    /// Whether its error against `exact` shrinks as the budget grows (segment splats, where the
    /// splat mode applies); the convergence tests hold every such technique to it.
    pub converges_with_budget: bool,
    /// The smallest channel budget from which, where it converges, its error falls with every
    /// larger one on the default settings (1: from its smallest; `fom` 8, where three harmonics
    /// start: the tests over the gallery and the held-out scenes hold it from there).
    pub converges_from: u32,
    /// Whether it keeps each texel's captured segment list whole when the budget holds it and
    /// compresses it only beyond (`dsm`, `avsm`): on one particle every budget holds the lists,
    /// so the analytic-sphere test holds its T to be the same at every budget.
    pub compresses_captured_lists: bool,
    /// Its documented memory formula: the channels it uses and the bytes it allocates for a
    /// case. The tests check every technique's ledger against it.
    pub memory: fn(&MemoryCase<'_>) -> MemoryUse,
    /// Path (under `shaders/`) of the lookup shader defining group 1 and `shadow_transmittance`.
    pub lookup_shader: &'static str,
    /// Compile-time constants of the lookup for these parameters, composed before it as
    /// `const NAME: u32 = V;` (the layered maps' channel counts): bounds its `#unroll` blocks
    /// can write their loops out to, so that their arrays stay in registers on llvmpipe.
    pub lookup_constants: fn(&TechniqueParams) -> Vec<(&'static str, u32)>,
    /// Every other WGSL module the technique compiles, composed: (label, source). The naga test
    /// validates them all, for every budget.
    pub extra_shaders: fn() -> Vec<(String, String)>,
    /// Builds the technique; `params` has already been checked against the budget range.
    pub create: CreateFn,
    /// Whether [`TechniqueParams::splat`] changes its result (sweeps run the others once).
    pub uses_splat: bool,
    /// Whether the channel budget changes its result (sweeps run the others once, at the first
    /// budget they accept, and say so).
    pub uses_budget: bool,
    /// Whether it draws the eye image's particles itself ([`ShadowTechnique::particle_pass`]
    /// is `Some`): such a technique renders them at full resolution only, so the sweep skips
    /// it at a lower `--particle-res` (`tests/mixed_res.rs` holds the two to agree).
    pub owns_particle_pass: bool,
    /// Whether it shadows a density volume (`[volume]`, `crate::medium`), and if not, why.
    pub volume: VolumeSupport,
    /// Whether it shadows particles (`srm` marches the density volume only, and refuses a
    /// scene with particles).
    pub shadows_particles: bool,
}

/// Whether a technique's T(p) includes a scene's density volume.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VolumeSupport {
    /// Its maps or its lookup take the volume (`none`: no shadow at all, as for particles).
    Shadows,
    /// It does not: the reason, for the one-line refusal.
    Refuses(&'static str),
}

impl TechniqueEntry {
    /// Why it cannot shadow a scene whose smoke holds a density volume (`volume`) and
    /// `particles` particles, if it cannot: the renderer's one-line refusal, which the sweep
    /// notes instead of measuring.
    pub fn refusal(&self, volume: bool, particles: usize) -> Option<ShadowError> {
        if let (true, VolumeSupport::Refuses(why)) = (volume, self.volume) {
            return Some(ShadowError::VolumeUnsupported {
                technique: self.name,
                why,
            });
        }
        (particles > 0 && !self.shadows_particles).then_some(ShadowError::ParticlesUnsupported {
            technique: self.name,
            particles,
        })
    }

    /// Why it cannot run with the shadow's temporal history at `weight` (`[shadow] history`,
    /// [`crate::render::history`]): a technique that lights the particles in its own pass.
    pub fn history_refusal(&self, weight: f32) -> Option<ShadowError> {
        (weight > 0.0 && self.owns_particle_pass).then_some(ShadowError::HistoryUnsupported {
            technique: self.name,
            weight,
        })
    }

    /// Whether its lighting reads the occluders' filtered depth map: with `params.occluders`
    /// = map, and never for the reference, which tests the boxes and the ground exactly (so the
    /// frame draws no map for it).
    pub fn reads_occluder_map(&self, params: &TechniqueParams) -> bool {
        self.role != Role::Reference && params.occluders == crate::scene::OccluderMode::Map
    }

    /// The virtual imports the lighting shaders are composed with for this technique with
    /// `params`: its lookup (`shadow_transmittance`) after its constants
    /// ([`TechniqueEntry::lookup_constants`]), and the occluders' visibility, tested exactly
    /// against the boxes and the ground, or read from their filtered depth map
    /// ([`TechniqueEntry::reads_occluder_map`], `src/frame/occluders.rs`).
    pub fn frame_imports(&self, params: &TechniqueParams) -> FrameImports {
        let source = crate::shaders::source(self.lookup_shader)
            .expect("registered lookup shader is embedded");
        let mut lookup = crate::shaders::u32_constants(&(self.lookup_constants)(params));
        lookup.push_str(source);
        let occluders = if self.reads_occluder_map(params) {
            "common/occluders_map.wgsl"
        } else {
            "common/occluders_exact.wgsl"
        };
        let occluders = crate::shaders::source(occluders).expect("occluder shaders are embedded");
        FrameImports { lookup, occluders }
    }
}

/// A technique's lookup and occluder imports ([`TechniqueEntry::frame_imports`]).
pub struct FrameImports {
    lookup: String,
    occluders: &'static str,
}

impl FrameImports {
    /// As [`crate::shaders::compose`] takes virtual imports.
    pub fn pairs(&self) -> [(&'static str, &str); 2] {
        [
            (crate::shaders::SHADOW_TECHNIQUE, &self.lookup),
            (crate::shaders::OCCLUDERS, self.occluders),
        ]
    }
}

/// [`TechniqueEntry::lookup_constants`] for a lookup with none.
pub fn no_lookup_constants(_: &TechniqueParams) -> Vec<(&'static str, u32)> {
    Vec::new()
}

/// Every technique, in the order lists and reports show them.
pub static REGISTRY: &[TechniqueEntry] = &[
    none::ENTRY,
    osm::ENTRY,
    dom::ENTRY,
    fom::ENTRY,
    fom::SIGMA_ENTRY,
    half_angle::ENTRY,
    esm::ENTRY,
    bsm::ENTRY,
    srm::ENTRY,
    msm::ENTRY,
    msm::TRIG_ENTRY,
    dsm::ENTRY,
    avsm::ENTRY,
    volume::ENTRY,
    exact::ENTRY,
];

/// The techniques that shadow particles (every one but those that march a density volume only,
/// `srm`), in registry order: what a particle scene is rendered and tested with.
pub fn particle_techniques() -> impl Iterator<Item = &'static TechniqueEntry> {
    REGISTRY.iter().filter(|e| e.shadows_particles)
}

/// The technique with `role` (the first, for [`Role::Contender`]).
fn with_role(role: Role) -> &'static TechniqueEntry {
    REGISTRY
        .iter()
        .find(|e| e.role == role)
        .expect("the registry has a frame baseline, a reference and contenders")
}

/// The frame-time baseline (`none`).
pub fn frame_baseline() -> &'static TechniqueEntry {
    with_role(Role::FrameBaseline)
}

/// The exact reference (`exact`).
pub fn reference() -> &'static TechniqueEntry {
    with_role(Role::Reference)
}

/// The techniques under comparison, in registry order.
pub fn contenders() -> impl Iterator<Item = &'static TechniqueEntry> {
    REGISTRY.iter().filter(|e| e.role == Role::Contender)
}

/// A technique list as the user wrote it, with `all` standing for every contender (in registry
/// order, where it stands; a name given twice is kept once).
pub fn expand_all(names: &[String]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for name in names {
        let expanded: Vec<String> = if name == "all" {
            contenders().map(|e| e.name.to_owned()).collect()
        } else {
            vec![name.clone()]
        };
        for n in expanded {
            if !out.contains(&n) {
                out.push(n);
            }
        }
    }
    out
}

/// Names of the techniques the default sweep runs.
pub fn default_sweep() -> Vec<String> {
    REGISTRY
        .iter()
        .filter(|e| e.in_default_sweep)
        .map(|e| e.name.to_owned())
        .collect()
}

/// Names of the techniques the default comparison shows.
pub fn default_compare() -> Vec<String> {
    REGISTRY
        .iter()
        .filter(|e| e.in_default_compare)
        .map(|e| e.name.to_owned())
        .collect()
}

/// Every technique parameter of the registry, with the technique that declares it.
pub fn all_params() -> impl Iterator<Item = (&'static TechniqueEntry, &'static ParamSpec)> {
    REGISTRY
        .iter()
        .flat_map(|e| e.params.iter().map(move |p| (e, p)))
}

/// The parameter named `key`.
pub fn find_param(key: &str) -> Result<&'static ParamSpec, ShadowError> {
    all_params()
        .map(|(_, p)| p)
        .find(|p| p.key == key)
        .ok_or_else(|| ShadowError::UnknownParam {
            key: key.to_owned(),
            valid: all_params()
                .map(|(_, p)| p.key)
                .collect::<Vec<_>>()
                .join(", "),
        })
}

/// Parses `KEY=VALUE` for `--param`, checked against the registry: VALUE is a number, or for a
/// parameter with choices a choice's name (or index); a choice comes back by its name.
pub fn parse_param(s: &str) -> Result<(String, ParamValue), String> {
    let (key, value) = s
        .split_once('=')
        .ok_or_else(|| format!("\"{s}\" is not KEY=VALUE (e.g. dom_layer_growth=2)"))?;
    let spec = find_param(key.trim()).map_err(|e| e.to_string())?;
    let value = value.trim();
    let value = match value.parse::<f32>() {
        Ok(number) => ParamValue::Number(number),
        Err(_) if spec.choices.is_empty() => {
            return Err(format!("\"{value}\" in \"{s}\" is not a number"));
        }
        Err(_) => ParamValue::Choice(value.to_owned()),
    };
    let value = spec.canonical(&value).map_err(|e| e.to_string())?;
    Ok((spec.key.to_owned(), value))
}

/// The viewer's opening sides: A shows this technique (at 8 channels), B this one's 24-channel
/// image when switched from `exact`.
pub const VIEWER_SIDES: (&str, &str) = ("fom", "osm");

/// Comma-separated registry names.
pub fn technique_names() -> String {
    REGISTRY
        .iter()
        .map(|e| e.name)
        .collect::<Vec<_>>()
        .join(", ")
}

/// Looks a technique up by name.
pub fn find(name: &str) -> Result<&'static TechniqueEntry, ShadowError> {
    REGISTRY
        .iter()
        .find(|e| e.name == name)
        .ok_or_else(|| ShadowError::UnknownTechnique {
            name: name.to_owned(),
            valid: technique_names(),
        })
}

/// Checks the channel budget against the technique's range.
pub fn check_channels(entry: &TechniqueEntry, channels: u32) -> Result<(), ShadowError> {
    if (entry.min_channels..=entry.max_channels).contains(&channels) {
        Ok(())
    } else {
        Err(ShadowError::ChannelsOutOfRange {
            technique: entry.name,
            channels,
            min: entry.min_channels,
            max: entry.max_channels,
        })
    }
}

/// Looks up, checks and builds a technique.
pub async fn create(
    ctx: &TechniqueContext<'_>,
    name: &str,
    params: &TechniqueParams,
) -> Result<Box<dyn ShadowTechnique>, ShadowError> {
    let entry = find(name)?;
    check_channels(entry, params.channels)?;
    check_params(params)?;
    ctx.gpu
        .scoped(async { (entry.create)(ctx, params) })
        .await
        .map_err(|r| {
            let what = format!(
                "creating {name} at {} channels and {}x{}",
                params.channels, params.resolution_px, params.resolution_px
            );
            ShadowError::Gpu(r.during(what).to_string())
        })?
}

/// Every WGSL module the renderer and the techniques compile, composed: (label, source).
pub fn all_shader_modules() -> Vec<(String, String)> {
    use crate::shaders::compose;
    let mut out: Vec<(String, String)> = [
        "render/tonemap.wgsl",
        "render/particles.wgsl",
        "render/map_view.wgsl",
        "render/occluder_map.wgsl",
        // The bench's cheapest build (crate::bench::bound), drawn like a technique's build.
        "bench/cheapest_build.wgsl",
    ]
    .iter()
    .map(|f| ((*f).to_owned(), compose(f, &[])))
    .collect();
    for entry in REGISTRY {
        for occluders in [OccluderMode::Exact, OccluderMode::Map] {
            let params = TechniqueParams {
                occluders,
                ..TechniqueParams::new(24, 512)
            };
            let mode = occluders.name();
            for frame_shader in ["render/opaque.wgsl", "render/particle_lighting.wgsl"] {
                out.push((
                    format!("{frame_shader}[{}, {mode} occluders]", entry.name),
                    compose(frame_shader, &entry.frame_imports(&params).pairs()),
                ));
            }
            out.push((
                format!("probe[{}, {mode} occluders]", entry.name),
                probe::source(entry, &params),
            ));
            if entry.volume == VolumeSupport::Shadows {
                out.push((
                    format!("volume_eye[{}, {mode} occluders]", entry.name),
                    crate::medium::eye_pass::source(&entry.frame_imports(&params).pairs()),
                ));
            }
        }
        out.extend((entry.extra_shaders)());
    }
    out
}

/// A linear-filtering, edge-clamped sampler for shadow maps.
pub(crate) fn map_sampler(device: &wgpu::Device, label: &str) -> wgpu::Sampler {
    device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some(label),
        address_mode_u: wgpu::AddressMode::ClampToEdge,
        address_mode_v: wgpu::AddressMode::ClampToEdge,
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        ..Default::default()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn registry_names_are_unique_snake_case() {
        let mut names: Vec<_> = REGISTRY.iter().map(|e| e.name).collect();
        assert!(
            names
                .iter()
                .all(|n| n.chars().all(|c| c.is_ascii_lowercase() || c == '_'))
        );
        names.sort();
        names.dedup();
        assert_eq!(names.len(), REGISTRY.len());
    }

    #[test]
    fn all_expands_to_every_contender_once() {
        let names = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let all = expand_all(&names(&["all"]));
        assert_eq!(all.len(), contenders().count());
        assert!(all.iter().all(|n| find(n).unwrap().role == Role::Contender));
        assert_eq!(expand_all(&names(&["dsm", "all"]))[0], "dsm");
        assert_eq!(expand_all(&names(&["dsm", "all"])).len(), all.len());
        assert_eq!(expand_all(&names(&["osm", "dom"])), names(&["osm", "dom"]));
    }

    #[test]
    fn roles_and_parameters_are_consistent() {
        assert_eq!(frame_baseline().name, "none");
        assert_eq!(reference().name, "exact");
        let roles = |r| REGISTRY.iter().filter(|e| e.role == r).count();
        assert_eq!(roles(Role::FrameBaseline), 1);
        assert_eq!(roles(Role::Reference), 1);
        for entry in REGISTRY {
            // Defaults list contenders only, and every contender's budget reads as something.
            if entry.in_default_sweep || entry.in_default_compare {
                assert_eq!(entry.role, Role::Contender, "{}", entry.name);
            }
            assert!(!(entry.budget_caption)(24).is_empty(), "{}", entry.name);
            for p in entry.params {
                assert!(
                    p.key.starts_with(entry.name),
                    "{} owns {}",
                    entry.name,
                    p.key
                );
                assert!(p.min <= p.max && !p.doc.is_empty(), "{}", p.key);
                // A choice's value is its index: the range is exactly the indices.
                if !p.choices.is_empty() {
                    assert_eq!(
                        (p.min, p.max, p.unit),
                        (0.0, (p.choices.len() - 1) as f32, "-"),
                        "{}",
                        p.key
                    );
                }
                if let Some(d) = p.default {
                    assert!(
                        p.check(d).is_ok(),
                        "{}'s default is out of its range",
                        p.key
                    );
                }
            }
        }
        let mut keys: Vec<_> = all_params().map(|(_, p)| p.key).collect();
        let n = keys.len();
        keys.sort();
        keys.dedup();
        assert_eq!(keys.len(), n, "parameter keys are unique");
    }

    #[test]
    fn parameters_parse_and_bad_ones_say_why() {
        let (key, value) = parse_param("dom_layer_growth=2").unwrap();
        assert_eq!(
            (key.as_str(), value),
            ("dom_layer_growth", ParamValue::Number(2.0))
        );
        let err = parse_param("dom_layer_growth=2000").unwrap_err();
        assert!(err.contains("1..=1000"), "{err}");
        let err = parse_param("fancy=1").unwrap_err();
        assert!(
            err.contains("\"fancy\"") && err.contains("dom_layer_growth"),
            "{err}"
        );
        assert!(
            parse_param("dom_layer_growth")
                .unwrap_err()
                .contains("KEY=VALUE")
        );
        assert!(
            parse_param("dom_layer_growth=x")
                .unwrap_err()
                .contains("not a number")
        );
        let mut params = TechniqueParams::new(8, 256);
        let ratio = find_param("dom_layer_growth").unwrap();
        assert_eq!(params.get(ratio), ratio.default, "unset: the default");
        set_param(&mut params, "dom_layer_growth", &3.0.into()).unwrap();
        assert_eq!(params.get(ratio), Some(3.0));
        assert!(set_param(&mut params, "dom_layer_growth", &0.5.into()).is_err());
        // A name where a number belongs says what the parameter takes.
        let err = set_param(
            &mut params,
            "dom_layer_growth",
            &ParamValue::Choice("big".into()),
        )
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("\"big\" is not a number") && err.contains("1..=1000"),
            "{err}"
        );
    }

    #[test]
    fn choices_parse_by_name_or_index_and_bad_ones_name_the_choices() {
        let cubic = ParamValue::Choice("cubic".to_owned());
        for key in ["osm_interp", "dom_interp"] {
            let spec = find_param(key).unwrap();
            assert_eq!(spec.choices, ["linear", "cubic"]);
            // By name or by index; either way kept by name.
            for text in ["cubic", " cubic", "1"] {
                let (k, v) = parse_param(&format!("{key}={text}")).unwrap();
                assert_eq!((k.as_str(), &v), (key, &cubic), "{text}");
            }
            let mut params = TechniqueParams::new(8, 256);
            assert_eq!(
                params.choice_index(spec),
                spec.default.unwrap() as usize,
                "unset: the default"
            );
            set_param(&mut params, key, &0.0.into()).unwrap();
            assert_eq!(params.values[key], ParamValue::Choice("linear".into()));
            set_param(&mut params, key, &1.0.into()).unwrap();
            assert_eq!(params.values[key], cubic);
            assert_eq!(
                (params.get(spec), params.choice_index(spec)),
                (Some(1.0), 1)
            );
            // A scene file may keep either form; both read as the index.
            params
                .values
                .insert(key.to_owned(), ParamValue::Number(1.0));
            assert!(check_params(&params).is_ok());
            assert_eq!(params.choice_index(spec), 1);
            // Anything else names the valid choices.
            for bad in ["quadratic", "2", "0.5", "-1", "Cubic"] {
                let err = parse_param(&format!("{key}={bad}")).unwrap_err();
                assert!(
                    err.contains(key)
                        && err.contains(bad)
                        && err.contains("not one of its choices: linear, cubic"),
                    "{err}"
                );
            }
            params
                .values
                .insert(key.to_owned(), ParamValue::Choice("spline".to_owned()));
            let err = check_params(&params).unwrap_err().to_string();
            assert_eq!(
                err,
                format!("parameter {key} = \"spline\" is not one of its choices: linear, cubic")
            );
        }
    }

    #[test]
    fn byte_budgets_buy_each_technique_the_channels_its_widths_allow() {
        let fit = |name: &str, budget: u32, precision: Option<&str>| {
            let entry = find(name).unwrap();
            let mut params = TechniqueParams::new(8, 512);
            if let Some(p) = precision {
                set_param(
                    &mut params,
                    &format!("{name}_precision"),
                    &ParamValue::Choice(p.to_owned()),
                )
                .unwrap();
            }
            fit_bytes_per_texel(entry, &params, budget, 10_000, 1280 * 720)
        };
        let channels = |name, budget, precision| fit(name, budget, precision).unwrap().channels;
        // Every byte counts, the uniform's too: a configuration of exactly the budget's texels'
        // worth does not fit. Half-float slices, 2 bytes each: 48 bytes buy 22 (23 and 24 take
        // 48, 23's last 3 in a 4-channel target), 12 bytes 5; single floats, 48 bytes 10.
        assert_eq!(channels("osm", 48, None), 22);
        assert_eq!(channels("osm", 12, None), 5);
        assert_eq!(channels("osm", 48, Some("single")), 10);
        // A start depth (2 bytes) and half-float layers: 48 bytes buy the depth and 22 layers
        // (23 would put their last 3 in a 4-channel target: 50 bytes).
        assert_eq!(channels("dom", 48, None), 23);
        // Single-float coefficients, 2n + 1 of them, the last target rounded to R, RG or RGBA:
        // 48 bytes hold 9 (8 + 1 in an R target; 11 take 48 and the uniform), 24 bytes 5 (4 + 1).
        let fom48 = fit("fom", 48, None).unwrap();
        assert_eq!((fom48.channels, fom48.channels_used), (9, 9));
        let uniform = layered::PARAMS_BYTES as f64;
        assert_eq!(fom48.bytes_per_texel, 36.0 + uniform / 262_144.0);
        assert_eq!(channels("fom", 24, None), 5);
        assert_eq!(channels("fom", 48, Some("half")), 21);
        // Below its smallest configuration (3 coefficients: 16 bytes) it fits nothing, and says so.
        let err = fit("fom", 12, None).unwrap_err();
        assert!(err.contains("16.0 bytes") && err.contains("12"), "{err}");
        // The moment maps stop at 9 channels, whatever the bytes.
        assert_eq!(fit("msm", 96, None).unwrap().channels_used, 9);
        // Two 4-byte words per node, beside the capture's 16 bytes a texel (counts, offsets,
        // raster target, texel order) and its first lists (65,536 segments of 64 bytes: 16
        // bytes a texel at 512²): 48 bytes hold not even its 2 nodes, 96 bytes 7.
        let err = fit("dsm", 48, None).unwrap_err();
        assert!(
            err.contains("dsm holds 48.") && err.contains("scratch"),
            "{err}"
        );
        assert_eq!(fit("dsm", 96, None).unwrap().channels_used, 14);
        // The volume's grid beside the least scratch its build sheds to (a z-slice's sums and
        // staging, a job a particle): under 48 bytes a texel, at most 23 channels.
        let volume = fit("volume", 48, None).unwrap();
        assert!(
            volume.bytes_per_texel <= 48.0 && volume.channels <= 23,
            "{volume:?}"
        );
    }

    #[test]
    fn unknown_technique_lists_the_valid_ones() {
        let err = find("fancy").err().unwrap().to_string();
        assert!(err.contains("\"fancy\""), "{err}");
        assert!(err.contains("none") && err.contains("osm"), "{err}");
    }

    #[test]
    fn budgets_outside_the_range_are_rejected_with_the_range() {
        let osm = find("osm").unwrap();
        assert!(check_channels(osm, 1).is_ok());
        // osm goes past one pass's 32 channels (several passes); fom weighs all its channels
        // at once and stops there.
        assert!(check_channels(osm, 128).is_ok());
        let err = check_channels(osm, 129).unwrap_err().to_string();
        assert!(err.contains("1..=128"), "{err}");
        assert!(check_channels(osm, 0).is_err());
        let fom = find("fom").unwrap();
        assert!(check_channels(fom, 32).is_ok());
        let err = check_channels(fom, 33).unwrap_err().to_string();
        assert!(err.contains("3..=32"), "{err}");
    }
}
