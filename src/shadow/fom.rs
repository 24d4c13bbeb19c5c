//! `fom` and `fom_sigma`: Fourier opacity maps (Jansen & Bavoil 2010; thesis 3.3.3.5).
//!
//! The extinction along each light ray, over the depth normalised to the frame's tight bounds,
//! is stored as a truncated Fourier series: a budget of B channels holds n = floor((B - 1) / 2)
//! harmonics as a0, a1..an, b1..bn (24 -> 11, 8 -> 3, 6 -> 2). Every light-space fragment adds
//! its −ln(1 − α)-weighted cos/sin terms (additive, no sort); a segment splat adds them
//! integrated analytically over its chord. The lookup reconstructs the optical depth with the
//! thesis' formula and clamps T to [0, 1]. `fom_sigma` damps harmonic k by the Lanczos σ-factor
//! sinc(k / (n + 1)) to suppress ringing. The coefficients are 32-bit floats: they are sums of
//! terms of both signs that largely cancel, and in half floats the rounding of the partial sums
//! made T depend on the order the particles were drawn in by up to 0.2. Shaders: `shaders/shadow/fom.wgsl`, `fom_build.wgsl`.

use super::layered::{ChannelPlan, Layered, LayeredSpec, PARAMS_BYTES, Precision};
use super::{MapKind, MemoryCase, MemoryUse, Role, TechniqueEntry, packed_bytes_per_texel};

/// 2n + 1 coefficients in 32-bit floats and the parameter uniform.
fn coefficient_memory(c: &MemoryCase<'_>) -> MemoryUse {
    let used = u64::from(plan(c.channels).used);
    MemoryUse {
        channels: used,
        bytes: c.texels() * packed_bytes_per_texel(used, 4) + PARAMS_BYTES,
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
    build_shader: "shadow/fom_build.wgsl",
    plan,
    depth_channel: false,
    layer_thickness: None,
    layer_ratio: None,
    interp: None,
    start_dilation: None,
    sigma: false,
    moments: None,
    precision: Precision::Float,
    channel_name: |c, plan| match c {
        0 => "a0 (twice the total optical depth)".to_owned(),
        c if c <= plan.count => format!("a{c} (cosine coefficient)"),
        c => format!("b{} (sine coefficient)", c - plan.count),
    },
    map_kind: MapKind::Signed,
};

pub const FOM_SIGMA: LayeredSpec = LayeredSpec {
    name: "fom_sigma",
    sigma: true,
    ..FOM
};

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: FOM.name,
    description: "Fourier opacity maps: floor((B-1)/2) harmonics of the extinction along each ray",
    role: Role::Contender,
    budget_caption: harmonics_caption,
    min_channels: 3,
    in_default_sweep: true,
    in_default_compare: true,
    build_reads_back: false,
    params: &[],
    order_independent: true,
    converges_with_budget: true,
    compresses_captured_lists: false,
    memory: coefficient_memory,
    lookup_shader: "shadow/fom.wgsl",
    extra_shaders: || FOM.all_build_shaders(),
    create: |ctx, params| Ok(Box::new(Layered::new(ctx, &FOM, params)?)),
    uses_splat: true,
    uses_budget: true,
    owns_particle_pass: false,
};

pub const SIGMA_ENTRY: TechniqueEntry = TechniqueEntry {
    name: FOM_SIGMA.name,
    description: "Fourier opacity maps with Lanczos sigma-factors damping the ringing",
    role: Role::Contender,
    budget_caption: harmonics_caption,
    min_channels: 3,
    in_default_sweep: true,
    in_default_compare: true,
    build_reads_back: false,
    params: &[],
    order_independent: true,
    converges_with_budget: true,
    compresses_captured_lists: false,
    memory: coefficient_memory,
    lookup_shader: "shadow/fom.wgsl",
    // Same build shaders as `fom`: the σ-factors apply at lookup.
    extra_shaders: Vec::new,
    create: |ctx, params| Ok(Box::new(Layered::new(ctx, &FOM_SIGMA, params)?)),
    uses_splat: true,
    uses_budget: true,
    owns_particle_pass: false,
};
