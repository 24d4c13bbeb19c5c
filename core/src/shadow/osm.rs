//! `osm`: opacity shadow maps (Kim & Neumann 2001; thesis 3.3.3.2).
//!
//! A budget of B channels is B slices, uniformly spaced over the light-space depth range that is
//! fitted to the particles each frame. Slice k stores the optical depth Ω in front of boundary
//! k/B; every light-space particle fragment adds its optical depth to each boundary at or beyond
//! its depth (additive blending, no sort). Lookup interpolates linearly between the two
//! boundaries around the point (or, with `osm_interp = cubic`, with the monotone cubic through
//! the four around it, [`super::slice_interp`]) and returns T = exp(-Ω). Shaders:
//! `shaders/shadow/osm.wgsl` (lookup) and `osm_build.wgsl`; the packing and passes are shared
//! in [`super::layered`].

use super::layered::{
    ChannelPlan, INTERP_CUBIC, Layered, LayeredSpec, PARAMS_BYTES, Precision, PrecisionSpec,
    interp_param, precision_param,
};
use super::{MapKind, MemoryUse, ParamSpec, Role, TechniqueEntry, packed_bytes_per_texel};

/// `osm_interp`: linear or monotone cubic between slice boundaries.
/// The cubic, chosen by `smokeshadow tune` on the training scenes (docs/tuned_params.toml).
pub const INTERP: ParamSpec = interp_param("osm_interp", INTERP_CUBIC);

/// `osm_precision`: half floats (Kim & Neumann's and the thesis' maps) or single.
pub const PRECISION: ParamSpec = precision_param(
    "osm_precision",
    Precision::Half,
    "storage of the slices: half floats (2 bytes a slice; the thesis' maps), which hold \
     optical depths, sums of positive terms, to about 3 significant digits; or single floats \
     (4 bytes), which buy twice the bytes per slice",
);

pub const SPEC: LayeredSpec = LayeredSpec {
    name: "osm",
    max_channels: super::layered::MAX_MULTI_PASS_CHANNELS,
    build_shader: "shadow/osm_build.wgsl",
    plan: |channels| ChannelPlan {
        count: channels,
        packed: channels,
        used: channels,
    },
    depth_channel: false,
    layer_thickness: None,
    layer_growth: None,
    interp: Some(&INTERP),
    start_dilation: None,
    sigma: false,
    moments: None,
    precision: PrecisionSpec::Param(&PRECISION),
    channel_name: |c, plan| {
        format!(
            "slice {} of {}: optical depth in front of it",
            c + 1,
            plan.count
        )
    },
    map_kind: MapKind::OpticalDepth,
};

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: SPEC.name,
    description: "opacity shadow maps: B uniform depth slices of accumulated optical depth",
    role: Role::Contender,
    budget_caption: |channels| format!("{channels} slices"),
    min_channels: 1,
    max_channels: SPEC.max_channels,
    in_default_sweep: true,
    in_default_compare: true,
    build_reads_back: false,
    params: &[INTERP, PRECISION],
    order_independent: true,
    converges_with_budget: true,
    converges_from: 1,
    compresses_captured_lists: false,
    // B slices of `osm_precision` and the uniform parameters.
    memory: |c| MemoryUse {
        channels: c.channels().into(),
        bytes: c.texels()
            * packed_bytes_per_texel(c.channels().into(), SPEC.channel_bytes(c.params))
            + PARAMS_BYTES,
        transient_bytes: 0,
    },
    lookup_shader: "shadow/osm.wgsl",
    lookup_constants: |p| super::layered::lookup_constants(&SPEC, p),
    extra_shaders: || SPEC.all_build_shaders(),
    create: |ctx, params| Ok(Box::new(Layered::new(ctx, &SPEC, params)?)),
    uses_splat: true,
    uses_budget: true,
    owns_particle_pass: false,
    volume: super::VolumeSupport::Shadows,
    shadows_particles: true,
};
