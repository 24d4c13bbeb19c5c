//! `fom` and `fom_sigma`: Fourier opacity maps (Jansen & Bavoil 2010; thesis 3.3.3.5).
//!
//! The extinction along each light ray, over the depth normalised to the frame's tight bounds,
//! is stored as a truncated Fourier series: a budget of B channels holds n = floor((B - 1) / 2)
//! harmonics as a0, a1..an, b1..bn (24 -> 11, 8 -> 3, 6 -> 2). Every light-space fragment adds
//! its −ln(1 − α)-weighted cos/sin terms (additive, no sort); a segment splat adds them
//! integrated analytically over its chord. The lookup reconstructs the optical depth with the
//! thesis' formula and clamps T to [0, 1]. `fom_sigma` damps harmonic k by the Lanczos σ-factor
//! sinc(k / (n + 1)) to suppress ringing. By default the coefficients are 32-bit floats (`fom_precision`): they are sums of
//! terms of both signs that largely cancel, and in half floats the rounding of the partial sums
//! made T depend on the order the particles were drawn in by up to 0.2. Shaders: `shaders/shadow/fom.wgsl`, `fom_build.wgsl`.

use super::layered::{
    ChannelPlan, Layered, LayeredSpec, PARAMS_BYTES, Precision, PrecisionSpec, precision_param,
};
use super::{
    MapKind, MemoryCase, MemoryUse, ParamSpec, Role, TechniqueEntry, packed_bytes_per_texel,
};

const PRECISION_DOC: &str = "storage of the coefficients: single floats (4 bytes a channel, \
    the default) or half floats (2 bytes; Jansen & Bavoil's 16-bit targets). The coefficients are \
    sums of terms of both signs that largely cancel: in half floats the partial sums' rounding \
    makes T depend on the order the particles are drawn in (measured: by up to 0.2)";

/// `fom_precision` and `fom_sigma_precision`: single (default) or half-float coefficients.
pub const PRECISION: ParamSpec = precision_param("fom_precision", Precision::Single, PRECISION_DOC);
pub const SIGMA_PRECISION: ParamSpec =
    precision_param("fom_sigma_precision", Precision::Single, PRECISION_DOC);

/// 2n + 1 coefficients of the spec's precision and the parameter uniform.
fn coefficient_memory(spec: &LayeredSpec, c: &MemoryCase<'_>) -> MemoryUse {
    let used = u64::from(plan(c.channels()).used);
    MemoryUse {
        channels: used,
        bytes: c.texels() * packed_bytes_per_texel(used, spec.channel_bytes(c.params))
            + PARAMS_BYTES,
        transient_bytes: 0,
    }
}

/// "11 harmonics (23 channels)".
fn harmonics_caption(channels: u32) -> String {
    let plan = plan(channels.max(3));
    format!("{} harmonics ({} channels)", plan.count, plan.used)
}

/// a0, a1..an, b1..bn: n = floor((B - 1) / 2) harmonics in 2n + 1 channels.
fn plan(channels: u32) -> ChannelPlan {
    let n = (channels - 1) / 2;
    ChannelPlan {
        count: n,
        packed: 2 * n + 1,
        used: 2 * n + 1,
    }
}

pub const FOM: LayeredSpec = LayeredSpec {
    name: "fom",
    max_channels: super::MAX_CHANNELS,
    build_shader: "shadow/fom_build.wgsl",
    plan,
    depth_channel: false,
    layer_thickness: None,
    layer_growth: None,
    interp: None,
    start_dilation: None,
    sigma: false,
    moments: None,
    precision: PrecisionSpec::Param(&PRECISION),
    channel_name: |c, plan| match c {
        0 => "a0 (twice the total optical depth)".to_owned(),
        c if c <= plan.count => format!("a{c} (cosine coefficient)"),
        c => format!("b{} (sine coefficient)", c - plan.count),
    },
    map_kind: MapKind::Signed,
};

pub const FOM_SIGMA: LayeredSpec = LayeredSpec {
    name: "fom_sigma",
    max_channels: super::MAX_CHANNELS,
    sigma: true,
    precision: PrecisionSpec::Param(&SIGMA_PRECISION),
    ..FOM
};

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: FOM.name,
    description: "Fourier opacity maps: floor((B-1)/2) harmonics of the extinction along each ray",
    role: Role::Contender,
    budget_caption: harmonics_caption,
    min_channels: 3,
    max_channels: FOM.max_channels,
    in_default_sweep: true,
    in_default_compare: true,
    build_reads_back: false,
    params: &[PRECISION],
    order_independent: true,
    converges_with_budget: true,
    // From 3 harmonics on: below, adding a harmonic need not shrink the truncated series'
    // ringing (measured on plume_65k, RMS T 0.092 at 6 channels, 2 harmonics, and 0.109 at 8).
    converges_from: 8,
    compresses_captured_lists: false,
    memory: |c| coefficient_memory(&FOM, c),
    lookup_shader: "shadow/fom.wgsl",
    lookup_constants: |p| super::layered::lookup_constants(&FOM, p),
    extra_shaders: || FOM.all_build_shaders(),
    create: |ctx, params| Ok(Box::new(Layered::new(ctx, &FOM, params)?)),
    uses_splat: true,
    uses_budget: true,
    owns_particle_pass: false,
    volume: super::VolumeSupport::Shadows,
    shadows_particles: true,
};

pub const SIGMA_ENTRY: TechniqueEntry = TechniqueEntry {
    name: FOM_SIGMA.name,
    description: "Fourier opacity maps with Lanczos sigma-factors damping the ringing",
    role: Role::Contender,
    budget_caption: harmonics_caption,
    min_channels: 3,
    max_channels: FOM_SIGMA.max_channels,
    in_default_sweep: true,
    in_default_compare: true,
    build_reads_back: false,
    params: &[SIGMA_PRECISION],
    order_independent: true,
    converges_with_budget: true,
    converges_from: 1,
    compresses_captured_lists: false,
    memory: |c| coefficient_memory(&FOM_SIGMA, c),
    lookup_shader: "shadow/fom.wgsl",
    lookup_constants: |p| super::layered::lookup_constants(&FOM_SIGMA, p),
    // Same build shaders as `fom`: the σ-factors apply at lookup.
    extra_shaders: Vec::new,
    create: |ctx, params| Ok(Box::new(Layered::new(ctx, &FOM_SIGMA, params)?)),
    uses_splat: true,
    uses_budget: true,
    owns_particle_pass: false,
    volume: super::VolumeSupport::Shadows,
    shadows_particles: true,
};
