//! `esm`: the exponential shadow map for volumes (Annen et al. 2008, as Bauer 2019 uses it for
//! clouds; the 2022 dissertation's chapter 3.2.4).
//!
//! One channel, whatever the budget: the light depth where the smoke starts along each texel's
//! ray (each particle fragment's chord entry, MIN-blended). Behind it transmittance falls off
//! exponentially, V = clamp(exp(-c·(d - z)), 0, 1): the map knows where the smoke begins but not
//! how dense it is, so `c` (`esm_exponent_per_m`) stands for a typical extinction. Shaders:
//! `shaders/shadow/esm.wgsl` (lookup) and `esm_build.wgsl`; the passes are shared in
//! [`super::light_maps`].

use super::layered::MIN_BLEND;
use super::light_maps::{LightMaps, LightMapsSpec, MapSpec};
use super::{MapKind, MemoryUse, ParamSpec, Role, TechniqueEntry};

/// `esm_exponent_per_m`: the exponent c of the fall-off, 1/m.
pub const EXPONENT: ParamSpec = ParamSpec {
    key: "esm_exponent_per_m",
    unit: "1/m",
    doc: "exponent c of V = exp(-c (d - z)) behind the smoke's start: a typical extinction; \
          larger darkens sooner behind the front",
    min: 0.01,
    max: 1000.0,
    default: Some(ESM_DEFAULT_EXPONENT),
    choices: &[],
    integer: false,
    tuned: true,
};

/// Chosen by `smokeshadow tune` on the training scenes (docs/tuned_params.toml).
const ESM_DEFAULT_EXPONENT: f32 = 2.62;

pub const SPEC: LightMapsSpec = LightMapsSpec {
    name: "esm",
    build_shader: "shadow/esm_build.wgsl",
    maps: &[MapSpec {
        name: "start depth",
        format: wgpu::TextureFormat::R16Float,
        blend: MIN_BLEND,
        clear: 1.0,
        kind: MapKind::Depth01,
    }],
    lookup_params: &[&EXPONENT],
};

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: SPEC.name,
    description: "exponential shadow map: the smoke's start depth, exp(-c(d - z)) behind it",
    role: Role::Contender,
    budget_caption: |_| "1 start depth (any budget)".to_owned(),
    min_channels: 1,
    max_channels: super::MAX_CHANNELS,
    in_default_sweep: true,
    in_default_compare: true,
    build_reads_back: false,
    params: &[EXPONENT],
    order_independent: true,
    converges_with_budget: false,
    converges_from: 1,
    compresses_captured_lists: false,
    // An R16F start depth and a 16-byte uniform.
    memory: |c| MemoryUse {
        channels: 1,
        bytes: c.texels() * 2 + 16,
        transient_bytes: 0,
    },
    lookup_shader: "shadow/esm.wgsl",
    lookup_constants: super::no_lookup_constants,
    extra_shaders: || SPEC.build_shaders(),
    create: |ctx, params| Ok(Box::new(LightMaps::new(ctx, &SPEC, params)?)),
    uses_splat: false,
    uses_budget: false,
    owns_particle_pass: false,
    volume: super::VolumeSupport::Shadows,
    shadows_particles: true,
};
