//! `dom`: deep opacity maps (Yuksel & Keyser 2008; thesis 3.3.3.4).
//!
//! One channel holds, per shadow-map texel, the light depth where the smoke starts (a first pass
//! min-blends each fragment's start depth); the other B - 1 channels are opacity layers that
//! begin there and so follow the shape of the smoke. Layer spacing is uniform
//! (`dom_layer_growth` = 1) or geometric, the last layer G times as thick as the first whatever
//! the budget (so that every layer thins as layers are added; G chosen by `smokeshadow tune`).
//! By default the layers of each texel span from its own
//! start to the far bound of the smoke, so no layer is wasted in front of the smoke and no point
//! lies beyond the last one; with a fixed `dom_thickness_m`, points beyond the last layer map to
//! the last layer, as the paper recommends (the smoke farther along the ray is then lost).
//! The start depth is each ray's entry into the first particle sphere, in both splat modes, or,
//! with `dom_start_dilation` > 1, into the first of the spheres enlarged by that factor: a
//! smoother proxy of the smoke's front (the thesis' future work, chapter 5: "a mesh or some
//! other approximation of clouds ... to render the front-most depths from the light").
//! Between boundaries the lookup interpolates linearly, or with `dom_interp = cubic` the
//! monotone cubic on the layers' own spacing ([`super::slice_interp`]).
//! Shaders: `shaders/shadow/dom.wgsl` and `dom_build.wgsl`.

use super::layered::{
    ChannelPlan, INTERP_CUBIC, Layered, LayeredSpec, PARAMS_BYTES, Precision, PrecisionSpec,
    interp_param, precision_param,
};
use super::{MapKind, MemoryUse, ParamSpec, Role, TechniqueEntry, packed_bytes_per_texel};

/// `dom_precision`: half-float layers (the paper's) or single.
pub const PRECISION: ParamSpec = precision_param(
    "dom_precision",
    Precision::Half,
    "storage of the layers: half floats (2 bytes a layer; the paper's), which hold optical \
     depths, sums of positive terms, to about 3 significant digits; or single floats (4 bytes). \
     The start-depth channel stays a half float",
);

/// `dom_thickness_m`: the depth range the layers cover.
pub const THICKNESS: ParamSpec = ParamSpec {
    key: "dom_thickness_m",
    unit: "m",
    doc: "the depth range the layers cover from where the smoke starts along each texel's ray; \
          unset: from each texel's start to the far bound of the smoke",
    min: 1e-3,
    max: 1e3,
    default: None,
    choices: &[],
    integer: false,
    tuned: true,
};

/// `dom_layer_growth`: geometric layer spacing.
pub const LAYER_GROWTH: ParamSpec = ParamSpec {
    key: "dom_layer_growth",
    unit: "-",
    doc: "the last layer's thickness over the first's, the layers between growing geometrically \
          (each G^(1/(L-1)) times the one before); 1 spaces them uniformly, more packs them \
          towards the lit side where transmittance changes fastest. Fixed whatever the budget, \
          so that more layers make every layer thinner: the ratio between successive layers \
          falls towards 1 and the lookup converges (a fixed ratio leaves the back layers a \
          fixed share of the depth at every budget)",
    min: 1.0,
    max: 1000.0,
    // chosen by `smokeshadow tune` on the training scenes (docs/tuned_params.toml).
    default: Some(3.27),
    choices: &[],
    integer: false,
    tuned: true,
};

/// `dom_interp`: linear or monotone cubic between layer boundaries.
/// The cubic, chosen by `smokeshadow tune` on the training scenes (docs/tuned_params.toml).
pub const INTERP: ParamSpec = interp_param("dom_interp", INTERP_CUBIC);

/// `dom_start_dilation`: the start depth from enlarged spheres.
pub const START_DILATION: ParamSpec = ParamSpec {
    key: "dom_start_dilation",
    unit: "-",
    doc: "factor on every particle's radius when finding where the smoke starts along each \
          texel's ray: 1 takes the particles' own spheres (the paper); more takes the entry \
          into the first enlarged sphere, a smoother proxy of the smoke's front that starts at \
          or before it",
    min: 1.0,
    max: 4.0,
    // chosen by `smokeshadow tune` on the training scenes (docs/tuned_params.toml): the
    // particles' own spheres.
    default: Some(1.0),
    choices: &[],
    integer: false,
    tuned: true,
};

pub const SPEC: LayeredSpec = LayeredSpec {
    name: "dom",
    max_channels: super::layered::MAX_MULTI_PASS_CHANNELS,
    build_shader: "shadow/dom_build.wgsl",
    // One channel is the depth where the smoke starts; the rest are layers (24 -> 23).
    plan: |channels| ChannelPlan {
        count: channels - 1,
        packed: channels - 1,
        used: channels,
    },
    depth_channel: true,
    layer_thickness: Some(&THICKNESS),
    layer_growth: Some(&LAYER_GROWTH),
    interp: Some(&INTERP),
    start_dilation: Some(&START_DILATION),
    sigma: false,
    moments: None,
    precision: PrecisionSpec::Param(&PRECISION),
    channel_name: |c, plan| {
        format!(
            "layer {} of {}: optical depth in front of it",
            c + 1,
            plan.count
        )
    },
    map_kind: MapKind::OpticalDepth,
};

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: SPEC.name,
    description: "deep opacity maps: a start-depth channel and B-1 layers that follow the smoke",
    role: Role::Contender,
    budget_caption: |channels| format!("1 depth + {} layers", channels.saturating_sub(1)),
    min_channels: 2,
    max_channels: SPEC.max_channels,
    in_default_sweep: true,
    in_default_compare: true,
    build_reads_back: false,
    params: &[THICKNESS, LAYER_GROWTH, INTERP, START_DILATION, PRECISION],
    order_independent: true,
    converges_with_budget: true,
    converges_from: 1,
    compresses_captured_lists: false,
    // One R16F start-depth channel, B - 1 layers of `dom_precision` and the uniform parameters.
    memory: |c| MemoryUse {
        channels: c.channels().into(),
        bytes: c.texels()
            * (packed_bytes_per_texel(u64::from(c.channels()) - 1, SPEC.channel_bytes(c.params))
                + 2)
            + PARAMS_BYTES,
        transient_bytes: 0,
    },
    lookup_shader: "shadow/dom.wgsl",
    lookup_constants: |p| super::layered::lookup_constants(&SPEC, p),
    extra_shaders: || SPEC.all_build_shaders(),
    create: |ctx, params| Ok(Box::new(Layered::new(ctx, &SPEC, params)?)),
    uses_splat: true,
    uses_budget: true,
    owns_particle_pass: false,
    volume: super::VolumeSupport::Shadows,
    shadows_particles: true,
};
