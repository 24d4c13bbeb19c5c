//! `bsm`: the Beer shadow map (Hillaire 2016 and 2020; the 2022 dissertation's chapter 3.2.5).
//!
//! Three values per texel, whatever the budget: the light depth where the smoke starts (MIN
//! blend) and ends (MAX blend) along the texel's ray, and the ray's whole optical depth (ADD).
//! The lookup assumes the mean extinction between front and back, so it knows both where the
//! smoke is and how much of it there is, but not how it is distributed inside. Shaders:
//! `shaders/shadow/bsm.wgsl` (lookup) and `bsm_build.wgsl`; the passes are shared in
//! [`super::light_maps`].

use super::layered::{ADDITIVE, MAX_BLEND, MIN_BLEND};
use super::light_maps::{LightMaps, LightMapsSpec, MapSpec};
use super::{MapKind, MemoryUse, Role, TechniqueEntry};

pub const SPEC: LightMapsSpec = LightMapsSpec {
    name: "bsm",
    build_shader: "shadow/bsm_build.wgsl",
    maps: &[
        MapSpec {
            name: "front depth",
            format: wgpu::TextureFormat::R16Float,
            blend: MIN_BLEND,
            clear: 1.0,
            kind: MapKind::Depth01,
        },
        MapSpec {
            name: "back depth",
            format: wgpu::TextureFormat::R16Float,
            blend: MAX_BLEND,
            clear: 0.0,
            kind: MapKind::Depth01,
        },
        MapSpec {
            name: "optical depth",
            format: wgpu::TextureFormat::R16Float,
            blend: ADDITIVE,
            clear: 0.0,
            kind: MapKind::OpticalDepth,
        },
    ],
    lookup_params: &[],
};

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: SPEC.name,
    description: "Beer shadow map: front and back depth and the ray's optical depth, mean extinction between",
    role: Role::Contender,
    budget_caption: |_| "front, back, optical depth (any budget)".to_owned(),
    min_channels: 3,
    max_channels: super::MAX_CHANNELS,
    in_default_sweep: true,
    in_default_compare: true,
    build_reads_back: false,
    params: &[],
    order_independent: true,
    converges_with_budget: false,
    converges_from: 1,
    compresses_captured_lists: false,
    // Three R16F maps and a 16-byte uniform.
    memory: |c| MemoryUse {
        channels: 3,
        bytes: c.texels() * 3 * 2 + 16,
        transient_bytes: 0,
    },
    lookup_shader: "shadow/bsm.wgsl",
    lookup_constants: super::no_lookup_constants,
    extra_shaders: || SPEC.build_shaders(),
    create: |ctx, params| Ok(Box::new(LightMaps::new(ctx, &SPEC, params)?)),
    uses_splat: false,
    uses_budget: false,
    owns_particle_pass: false,
    volume: super::VolumeSupport::Shadows,
    shadows_particles: true,
};
