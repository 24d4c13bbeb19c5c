//! Shared machinery of the layered techniques (`osm`, `dom`, `fom`, `fom_sigma`): values packed
//! 4 to a half-float render target, written in one MRT pass of light-facing billboards with
//! additive blending (no sort), and read by a lookup shader from one array texture and one
//! remainder (`shaders/shadow/layered.wgsl`, `layered_build.wgsl`). A pass writes at most 8
//! targets (32 channels); a budget past them, or past the adapter's bytes per sample, draws the
//! particles once per group of targets ([`target_passes`]: the thesis' multi-pass opacity maps),
//! which the lookups that read a channel by index (`osm`, `dom`) allow up to
//! [`MAX_MULTI_PASS_CHANNELS`].
//!
//! Each technique is a [`LayeredSpec`] in its own module: how its budget maps to packed channels
//! and which build shader defines what each fragment writes: `prepare_values(splat, pixel)`
//! once per fragment, then `target_values(prepared, index)` per render target. The last target
//! has only as many components as it needs: R16F for 1, RG16F for 2, RGBA16F for 3 or 4 (there is
//! no 3-component render format, so a remainder of 3 allocates one unused channel, and the memory
//! ledger says so). Channels are half floats, or 32-bit floats where a technique needs them
//! ([`Precision`]). A spec with a depth channel (`dom`) gets a first pass that min-blends the
//! depth where the smoke starts into one more R16F channel.

use super::GpuFuture;
use std::ops::Range;

use bytemuck::{Pod, Zeroable};

use super::{
    BuildInputs, DebugMap, LOOKUP_STAGES, MapKind, ParamSpec, ShadowError, ShadowTechnique,
    SplatMode, TechniqueContext, TechniqueParams,
};
use crate::frame::gpu_data::{BILLBOARD_VERTICES, ParticleInstance};
use crate::gpu::{AllocationError, Gpu, MemoryLedger, TargetWrites, uniform_entry};
use crate::shaders;

/// Most render targets one build pass writes (8 x 4 = 32 channels).
pub const MAX_TARGETS: u32 = 8;
/// Largest budget of the layered maps whose lookups read each channel by index (`osm`, `dom`):
/// 32 targets, built in 4 passes. Those that weigh every channel at once (`fom`, `msm`, `tmsm`)
/// keep them in registers and stop at [`super::MAX_CHANNELS`].
pub const MAX_MULTI_PASS_CHANNELS: u32 = 128;
/// Binding of the depth channel in the lookup and layer-build groups.
const DEPTH_BINDING: u32 = 4;
/// Format of the depth channel (normalised light depth, min-blended).
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R16Float;

/// How a budget is spent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChannelPlan {
    /// Slices (osm), layers (dom) or harmonics (fom).
    pub count: u32,
    /// Channels in the packed targets.
    pub packed: u32,
    /// Channels used in all (packed + the depth channel, if any).
    pub used: u32,
}

/// One layered technique: everything that differs between `osm`, `dom` and `fom`.
pub struct LayeredSpec {
    pub name: &'static str,
    /// Its largest budget: [`MAX_MULTI_PASS_CHANNELS`] for a lookup that reads channels by
    /// index, [`super::MAX_CHANNELS`] for one that reads them all (`layered_channels`).
    pub max_channels: u32,
    /// Build shader (under `shaders/`) defining `target_values` (and `fs_depth` with a depth
    /// channel).
    pub build_shader: &'static str,
    /// How a budget (already >= the technique's minimum) is spent.
    pub plan: fn(u32) -> ChannelPlan,
    /// Whether a first pass writes the depth where the smoke starts (`dom`).
    pub depth_channel: bool,
    /// The parameters, if any, that set the depth range the layers cover (0 in the shader:
    /// from each texel's start to the far bound) and the last layer's thickness over the
    /// first's (1 when absent: uniform layers; [`layer_ratio`]).
    pub layer_thickness: Option<&'static ParamSpec>,
    pub layer_growth: Option<&'static ParamSpec>,
    /// The parameter, if any, choosing how Ω is interpolated between boundaries
    /// ([`interp_param`]: linear, or the monotone cubic); linear when absent.
    pub interp: Option<&'static ParamSpec>,
    /// The parameter, if any, enlarging each particle's sphere in the depth pass (1 when
    /// absent: the spheres themselves).
    pub start_dilation: Option<&'static ParamSpec>,
    /// Whether the lookup damps harmonics with Lanczos σ-factors (`fom_sigma`).
    pub sigma: bool,
    /// The parameters of a moment reconstruction (`msm`, `tmsm`), if the maps hold moments.
    pub moments: Option<MomentParams>,
    /// Storage precision of the packed channels: fixed, or a parameter ([`precision_param`]).
    pub precision: PrecisionSpec,
    /// What packed channel `c` holds under `plan`, for inspection.
    pub channel_name: fn(u32, &ChannelPlan) -> String,
    /// How the packed channels' values read.
    pub map_kind: MapKind,
}

/// The parameters a moment-based lookup reads (see [`super::moment_math`]).
#[derive(Clone, Copy, Debug)]
pub struct MomentParams {
    /// β, the pull towards the uniform distribution's moments.
    pub bias: &'static ParamSpec,
    /// Whether β and its target are `bias` and the uniform distribution's moments, or the
    /// authors' table ([`super::moment_math::PAPER_BIAS`]).
    pub bias_table: &'static ParamSpec,
    /// η, the share of the weight at the receiver's depth counted in front of it.
    pub overestimation: &'static ParamSpec,
    /// θ, the wrapping zone of trigonometric moments: set exactly for them
    /// ([`MomentParams::trigonometric`]).
    pub wrapping_zone: Option<&'static ParamSpec>,
}

impl MomentParams {
    /// Trigonometric moments (`tmsm`: n roots from n moments), the ones with a wrapping zone;
    /// else power moments (`msm`: n roots from 2n).
    pub fn trigonometric(&self) -> bool {
        self.wrapping_zone.is_some()
    }
}

impl LayeredSpec {
    /// Every build module for every target count of one pass, and its largest budget in
    /// passes of 8 targets and of 1, for the naga test.
    pub fn all_build_shaders(&self) -> Vec<(String, String)> {
        let most = self.max_channels.div_ceil(4);
        let one_pass = (1..=MAX_TARGETS)
            .map(|targets| (targets, std::iter::once(0..targets).collect::<Vec<_>>()));
        let passes = |per: u32| -> Vec<Range<u32>> {
            (0..most.div_ceil(per))
                .map(|p| p * per..((p + 1) * per).min(most))
                .collect()
        };
        one_pass
            .chain([(most, passes(MAX_TARGETS)), (most, passes(1))])
            .map(|(targets, passes)| {
                (
                    format!(
                        "{}.build[{targets} targets in {} passes]",
                        self.name,
                        passes.len()
                    ),
                    // (A budget that packs that many targets.)
                    build_shader_source(
                        self,
                        &passes,
                        &super::TechniqueParams::new(4 * targets, 512),
                    ),
                )
            })
            .collect()
    }
}

/// The choices of an `<technique>_interp` parameter, by index.
pub const INTERP_CHOICES: &[&str] = &["linear", "cubic"];
/// Index of the monotone cubic in [`INTERP_CHOICES`].
pub const INTERP_CUBIC: usize = 1;

/// The `<technique>_interp` parameter of a slice- or layer-based technique (`osm`, `dom`): how
/// the lookup interpolates the optical depth between boundaries; `default` is a choice's index.
pub const fn interp_param(key: &'static str, default: usize) -> ParamSpec {
    ParamSpec {
        key,
        unit: "-",
        doc: "how optical depth is interpolated between boundaries: linear (the thesis), or \
              cubic: the monotone cubic through the boundaries' optical depths (Fritsch-Butland \
              tangents, so T still never rises with depth), the thesis' future work against \
              slice artefacts; against exact it about halves the error with segment splats at \
              16-24 channels and adds 18-35% with point splats",
        min: 0.0,
        max: (INTERP_CHOICES.len() - 1) as f32,
        default: Some(default as f32),
        choices: INTERP_CHOICES,
        integer: false,
        tuned: true,
    }
}

/// Keep in sync with `LayeredParams` in shaders/shadow/layered.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct LayeredParams {
    count: u32,
    packed: u32,
    splat: u32,
    sigma: u32,
    dom_thickness_m: f32,
    dom_ratio: f32,
    full_targets: u32,
    _pad0: u32,
    cubic: u32,
    dom_start_dilation: f32,
    moment_bias: f32,
    moment_overestimation: f32,
    wrapping_zone_rad: f32,
    _pad1: [u32; 3],
    /// What power moments 2, 4, 6 and 8 are pulled towards (the odd ones towards 0).
    moment_bias_target: [f32; 4],
}

/// Bytes of a layered technique's uniform parameters (its memory formula counts them).
pub const PARAMS_BYTES: u64 = std::mem::size_of::<LayeredParams>() as u64;

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![crate::mirror_layout!(
        LayeredParams,
        "shadow/layered.wgsl",
        "LayeredParams",
        [
            count,
            packed,
            splat,
            sigma,
            dom_thickness_m,
            dom_ratio,
            full_targets,
            cubic,
            dom_start_dilation,
            moment_bias,
            moment_overestimation,
            wrapping_zone_rad,
            moment_bias_target
        ]
    )]
}

/// β and the target of power moments 2, 4, 6, 8 for `spec` with `params` at `count` moments:
/// its bias parameter towards the uniform distribution's moments (1/(k + 1)), or with its bias
/// table at `paper` the authors' row for this count ([`super::moment_math::PAPER_BIAS`]).
pub fn moment_bias(spec: &LayeredSpec, params: &TechniqueParams, count: u32) -> (f32, [f32; 4]) {
    let uniform = [1.0 / 3.0, 1.0 / 5.0, 1.0 / 7.0, 1.0 / 9.0];
    let Some(m) = spec.moments.as_ref() else {
        return (0.0, uniform);
    };
    let one = (params.get(m.bias).unwrap_or(0.0), uniform);
    if params.choice_index(m.bias_table) != 1 {
        return one;
    }
    match super::moment_math::paper_bias(m.trigonometric(), count) {
        Some(row) => {
            let mut target = [0.0; 4];
            for (t, v) in target.iter_mut().zip(row.vector.iter().skip(1).step_by(2)) {
                *t = *v as f32;
            }
            (row.bias, target)
        }
        None => one,
    }
}

/// The ratio between successive layers' thicknesses when the last of `layers` is `growth` times
/// as thick as the first: growth^(1/(layers - 1)), which falls towards 1 as layers are added.
pub fn layer_ratio(growth: f32, layers: u32) -> f32 {
    match layers {
        0 | 1 => 1.0,
        n => growth.powf(1.0 / (n - 1) as f32),
    }
}

/// Format of packed target `index` for `packed` channels of `precision`.
pub fn target_format(packed: u32, index: u32, precision: Precision) -> wgpu::TextureFormat {
    use wgpu::TextureFormat as F;
    match ((packed - index * 4).min(4), precision) {
        (1, Precision::Half) => F::R16Float,
        (2, Precision::Half) => F::Rg16Float,
        (_, Precision::Half) => F::Rgba16Float,
        (1, Precision::Single) => F::R32Float,
        (2, Precision::Single) => F::Rg32Float,
        (_, Precision::Single) => F::Rgba32Float,
    }
}

/// Storage precision of the packed channels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Precision {
    /// 16-bit floats: enough for sums of positive optical depths (`osm`, `dom`).
    Half,
    /// 32-bit floats (needs `FLOAT32_BLENDABLE` and `FLOAT32_FILTERABLE`): Fourier coefficients
    /// are sums of terms of both signs that largely cancel, and half floats round the partial
    /// sums so coarsely that the result depends on the order the particles are drawn in.
    Single,
}

impl Precision {
    /// Bytes of one channel.
    pub const fn bytes(self) -> u64 {
        match self {
            Self::Half => 2,
            Self::Single => 4,
        }
    }
}

/// The choices of a `<technique>_precision` parameter, by index ([`Precision`] in order).
pub const PRECISION_CHOICES: &[&str] = &["half", "single"];

/// How a layered technique's channel precision is set.
#[derive(Clone, Copy, Debug)]
pub enum PrecisionSpec {
    /// Always this (the moment maps: 32-bit, as the moment-based papers store 6 and 8 moments).
    Fixed(Precision),
    /// A `<technique>_precision` parameter ([`precision_param`]): its paper allows either.
    Param(&'static ParamSpec),
}

impl LayeredSpec {
    /// The precision of the packed channels under `params`.
    pub fn precision(&self, params: &TechniqueParams) -> Precision {
        match self.precision {
            PrecisionSpec::Fixed(p) => p,
            PrecisionSpec::Param(spec) => match params.choice_index(spec) {
                0 => Precision::Half,
                _ => Precision::Single,
            },
        }
    }

    /// Bytes of one packed channel under `params` (the memory formulas use it).
    pub fn channel_bytes(&self, params: &TechniqueParams) -> u64 {
        self.precision(params).bytes()
    }
}

/// A `<technique>_precision` parameter: half or single floats for the packed channels, `default`
/// unless set; `doc` says what each costs the technique. A channel budget then buys the same
/// channels at twice or half the bytes; `--bytes-per-texel` compares at equal bytes.
pub const fn precision_param(
    key: &'static str,
    default: Precision,
    doc: &'static str,
) -> ParamSpec {
    ParamSpec {
        key,
        unit: "-",
        doc,
        min: 0.0,
        max: (PRECISION_CHOICES.len() - 1) as f32,
        default: Some(match default {
            Precision::Half => 0.0,
            Precision::Single => 1.0,
        }),
        choices: PRECISION_CHOICES,
        integer: false,
        // What is stored, not a knob of the algorithm: it sets the bytes a texel costs.
        tuned: false,
    }
}

/// The generated fragment entry points: for pass `g` of `passes`, `fs_build_{g}` and
/// `fs_build_volume_{g}` writing one vec4 per target of its range (target `i` of the pass is
/// packed target `range.start + i`).
fn build_outputs_wgsl(passes: &[Range<u32>]) -> String {
    passes
        .iter()
        .enumerate()
        .map(|(g, range)| pass_outputs_wgsl(g, range))
        .collect()
}

fn pass_outputs_wgsl(g: usize, range: &Range<u32>) -> String {
    let fields: String = range
        .clone()
        .map(|t| format!("    @location({}) t{t}: vec4<f32>,\n", t - range.start))
        .collect();
    let writes: String = range
        .clone()
        .map(|t| format!("    out.t{t} = target_values(prepared, {t}u);\n"))
        .collect();
    let sums: String = range
        .clone()
        .map(|t| format!("        out.t{t} += target_values(prepared, {t}u);\n"))
        .collect();
    format!(
        "struct BuildOut{g} {{\n{fields}}};\n\n@fragment\nfn fs_build_{g}(in: BuildVertexOut) -> BuildOut{g} {{\n    \
         let splat = splat_fragment(in, layered.splat == 1u);\n    \
         let prepared = prepare_values(splat, in.clip.xy);\n    var out: BuildOut{g};\n{writes}    return out;\n}}\n\n\
         // The volume's steps along the texel's light ray (shaders/shadow/volume_splat.wgsl),\n\
         // summed as their fragments would be (every target blends additively).\n\
         @fragment\nfn fs_build_volume_{g}(in: VolumeVertexOut) -> BuildOut{g} {{\n    \
         let ray = volume_light_ray(in.ndc);\n    if ray.steps == 0u {{\n        discard;\n    }}\n    \
         var out: BuildOut{g};\n    for (var i = 0u; i < ray.steps; i++) {{\n        \
         let splat = volume_splat(ray, i, layered.splat == 1u);\n        \
         if splat.optical_depth <= 0.0 {{\n            continue;\n        }}\n        \
         let prepared = prepare_values(splat, in.clip.xy);\n{sums}    }}\n    return out;\n}}\n\n"
    )
}

/// The build's passes: the packed targets in order, grouped so that each pass writes at most
/// [`MAX_TARGETS`] of them, within the adapter's colour attachments and bytes per sample (each
/// target aligned to its component size, as wgpu counts them). One pass when a budget's targets
/// fit the adapter; above 32 channels, or on an adapter with fewer bytes per sample (WebGPU's
/// default is 32), the particles are drawn once per group: the thesis' multi-pass opacity maps.
/// None when one target alone does not fit.
pub fn target_passes(
    formats: &[wgpu::TextureFormat],
    limits: &wgpu::Limits,
) -> Option<Vec<Range<u32>>> {
    let per_pass = MAX_TARGETS.min(limits.max_color_attachments) as usize;
    let most_bytes = limits.max_color_attachment_bytes_per_sample;
    let mut passes: Vec<Range<u32>> = Vec::new();
    // Bytes a sample of the last pass so far.
    let mut bytes = 0u32;
    for (t, format) in (0u32..).zip(formats) {
        let cost = format.target_pixel_byte_cost()?;
        if cost > most_bytes || per_pass == 0 {
            return None;
        }
        let joined = bytes.next_multiple_of(format.target_component_alignment()?) + cost;
        match passes.last_mut() {
            Some(last) if last.len() < per_pass && joined <= most_bytes => {
                last.end = t + 1;
                bytes = joined;
            }
            _ => {
                passes.push(t..t + 1);
                bytes = cost;
            }
        }
    }
    Some(passes)
}

/// The lookup's compile-time constants ([`super::TechniqueEntry::lookup_constants`]): the
/// count (slices, layers, harmonics, moments) and the packed targets `layered_channels` reads;
/// for moment maps also the roots n their reconstruction finds (shaders/shadow/moments.wgsl).
pub fn lookup_constants(
    spec: &LayeredSpec,
    params: &super::TechniqueParams,
) -> Vec<(&'static str, u32)> {
    let plan = (spec.plan)(params.channels);
    let mut constants = vec![
        ("LAYERED_COUNT", plan.count),
        ("LAYERED_TARGETS", plan.packed.div_ceil(4)),
    ];
    if let Some(moments) = &spec.moments {
        let roots = match moments.trigonometric() {
            true => plan.count,
            false => plan.count / 2,
        };
        constants.push(("MOMENT_ROOTS", roots));
    }
    constants
}

/// The full build shader of `spec` for render targets written in `passes`, after the lookup's
/// constants for `params` (the build shaders import their lookups).
pub fn build_shader_source(
    spec: &LayeredSpec,
    passes: &[Range<u32>],
    params: &super::TechniqueParams,
) -> String {
    let constants = shaders::u32_constants(&lookup_constants(spec, params));
    shaders::compose_after(&constants, spec.build_shader, &[])
        .replace("//{{BUILD_OUTPUTS}}", &build_outputs_wgsl(passes))
}

/// The packed maps: the full 4-channel targets as layers of one array texture, and the 1-, 2- or
/// 3-channel remainder (stored in R, RG or RGBA) as a texture of its own.
struct Maps {
    full_layers: u32,
    full: Option<wgpu::Texture>,
    rest: Option<wgpu::Texture>,
    /// The array as the lookup binds it (the remainder viewed as a 1-layer array when there
    /// are no full layers: the lookup never reads it then).
    full_view: wgpu::TextureView,
    /// The remainder as the lookup binds it (layer 0 of the array when there is none).
    rest_view: wgpu::TextureView,
}

impl Maps {
    /// Maps for `packed` channels of `precision` at `res`², recorded in `memory`.
    fn new(
        memory: &mut MemoryLedger,
        device: &wgpu::Device,
        name: &str,
        packed: u32,
        precision: Precision,
        res: u32,
    ) -> Result<Self, AllocationError> {
        let full_layers = packed / 4;
        let mut texture = |label: String, format, layers| {
            map_texture_layers(memory, device, &label, format, res, layers)
        };
        let full = (full_layers > 0)
            .then(|| {
                let format = target_format(packed, 0, precision);
                texture(format!("{name}.maps"), format, full_layers)
            })
            .transpose()?;
        let rest = (!packed.is_multiple_of(4))
            .then(|| {
                let format = target_format(packed, full_layers, precision);
                texture(format!("{name}.maps.rest"), format, 1)
            })
            .transpose()?;
        let array_view = |t: &wgpu::Texture| {
            t.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2Array),
                ..Default::default()
            })
        };
        let layer_view = |t: &wgpu::Texture, layer| {
            t.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2),
                base_array_layer: layer,
                array_layer_count: Some(1),
                ..Default::default()
            })
        };
        let any = full
            .as_ref()
            .or(rest.as_ref())
            .expect("at least one target");
        Ok(Self {
            full_layers,
            full_view: array_view(full.as_ref().unwrap_or(any)),
            rest_view: layer_view(rest.as_ref().unwrap_or(any), 0),
            full,
            rest,
        })
    }

    /// One render-target view per packed target, in channel order.
    fn attachments(&self) -> Vec<wgpu::TextureView> {
        let mut out: Vec<_> = (0..self.full_layers)
            .map(|layer| {
                self.full.as_ref().expect("full layers exist").create_view(
                    &wgpu::TextureViewDescriptor {
                        dimension: Some(wgpu::TextureViewDimension::D2),
                        base_array_layer: layer,
                        array_layer_count: Some(1),
                        ..Default::default()
                    },
                )
            })
            .collect();
        if let Some(rest) = &self.rest {
            out.push(rest.create_view(&Default::default()));
        }
        out
    }
}

/// A layered technique: a [`LayeredSpec`] with its maps and pipelines.
pub struct Layered {
    spec: &'static LayeredSpec,
    plan: ChannelPlan,
    /// Full RGBA layers in the array (the rest, if any, is one more texture).
    full_targets: u32,
    params: TechniqueParams,
    params_buffer: wgpu::Buffer,
    /// The render-target views, in channel order: the full RGBA layers, then the remainder.
    targets: Vec<wgpu::TextureView>,
    /// The build's passes, each drawing every particle into its group of targets.
    build: Vec<BuildPass>,
    build_bind_group: wgpu::BindGroup,
    /// The depth channel's pass, for specs that have one.
    depth: Option<DepthPass>,
    lookup_layout: wgpu::BindGroupLayout,
    lookup_bind_group: wgpu::BindGroup,
    memory: MemoryLedger,
}

/// One pass of the build ([`target_passes`]).
struct BuildPass {
    /// The packed targets it writes.
    targets: Range<u32>,
    pipeline: wgpu::RenderPipeline,
    /// The density volume's draw into the same targets.
    volume: VolumeBuild,
    /// What each of its fragments writes (for the bench's fragment counts).
    writes: TargetWrites,
}

struct DepthPass {
    view: wgpu::TextureView,
    pipeline: wgpu::RenderPipeline,
    volume: VolumeBuild,
    bind_group: wgpu::BindGroup,
}

/// A filtering sampler.
pub(crate) fn sampler_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
        count: None,
    }
}

/// A filterable 2D float texture (32-bit float maps need `FLOAT32_FILTERABLE`).
pub(crate) fn texture_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    crate::gpu::texture_entry(
        binding,
        visibility,
        wgpu::TextureSampleType::Float { filterable: true },
    )
}

/// A square shadow-map texture of `layers` layers, recorded in `memory`.
fn map_texture_layers(
    memory: &mut MemoryLedger,
    device: &wgpu::Device,
    label: &str,
    format: wgpu::TextureFormat,
    res: u32,
    layers: u32,
) -> Result<wgpu::Texture, AllocationError> {
    memory.texture(
        device,
        &wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: res,
                height: res,
                depth_or_array_layers: layers,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        },
    )
}

/// A group holding only `buffer` as a uniform at binding 0 (a build pass's parameters): its
/// layout (`<label>_layout`) and bind group (`<label>_bind_group`).
pub(crate) fn uniform_group(
    device: &wgpu::Device,
    label: &str,
    buffer: &wgpu::Buffer,
    stages: wgpu::ShaderStages,
) -> (wgpu::BindGroupLayout, wgpu::BindGroup) {
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(&format!("{label}_layout")),
        entries: &[uniform_entry(0, stages)],
    });
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(&format!("{label}_bind_group")),
        layout: &layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: buffer.as_entire_binding(),
        }],
    });
    (layout, group)
}

/// The first two entries of a lookup layout: the technique's uniform parameters (binding 0) and
/// a bilinear sampler (binding 1); its maps follow from binding 2.
pub(crate) fn lookup_layout_head() -> Vec<wgpu::BindGroupLayoutEntry> {
    vec![
        uniform_entry(0, LOOKUP_STAGES),
        sampler_entry(1, LOOKUP_STAGES),
    ]
}

/// The bind-group entries matching [`lookup_layout_head`].
pub(crate) fn lookup_group_head<'a>(
    params: &'a wgpu::Buffer,
    sampler: &'a wgpu::Sampler,
) -> Vec<wgpu::BindGroupEntry<'a>> {
    vec![
        wgpu::BindGroupEntry {
            binding: 0,
            resource: params.as_entire_binding(),
        },
        wgpu::BindGroupEntry {
            binding: 1,
            resource: wgpu::BindingResource::Sampler(sampler),
        },
    ]
}

/// A square single-layer shadow-map texture, recorded in `memory`, and its view.
pub fn map_texture(
    memory: &mut MemoryLedger,
    device: &wgpu::Device,
    label: &str,
    format: wgpu::TextureFormat,
    res: u32,
) -> Result<wgpu::TextureView, AllocationError> {
    Ok(map_texture_layers(memory, device, label, format, res, 1)?
        .create_view(&wgpu::TextureViewDescriptor::default()))
}

/// Additive blending: every fragment adds to what is there.
pub const ADDITIVE: wgpu::BlendComponent = wgpu::BlendComponent {
    src_factor: wgpu::BlendFactor::One,
    dst_factor: wgpu::BlendFactor::One,
    operation: wgpu::BlendOperation::Add,
};

/// A pipeline drawing light-facing particle billboards (`vs_build`) into `formats` with `blend`.
pub fn billboard_pipeline(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    fragment_entry: &str,
    layouts: &[Option<&wgpu::BindGroupLayout>],
    formats: &[wgpu::TextureFormat],
    blend: wgpu::BlendComponent,
) -> wgpu::RenderPipeline {
    let targets: Vec<_> = formats.iter().map(|&f| (f, blend)).collect();
    billboard_pipeline_blends(device, label, module, fragment_entry, layouts, &targets)
}

/// MIN blending: each texel keeps the smallest value written (a start depth).
pub const MIN_BLEND: wgpu::BlendComponent = wgpu::BlendComponent {
    src_factor: wgpu::BlendFactor::One,
    dst_factor: wgpu::BlendFactor::One,
    operation: wgpu::BlendOperation::Min,
};

/// MAX blending: each texel keeps the largest value written (an end depth).
pub const MAX_BLEND: wgpu::BlendComponent = wgpu::BlendComponent {
    src_factor: wgpu::BlendFactor::One,
    dst_factor: wgpu::BlendFactor::One,
    operation: wgpu::BlendOperation::Max,
};

/// A light-space billboard pipeline whose render targets each get their own format and blend
/// (a start depth MIN-blended beside optical depth added, say).
pub(crate) fn billboard_pipeline_blends(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    fragment_entry: &str,
    layouts: &[Option<&wgpu::BindGroupLayout>],
    targets: &[(wgpu::TextureFormat, wgpu::BlendComponent)],
) -> wgpu::RenderPipeline {
    billboard_pipeline_entries(
        device,
        label,
        module,
        ("vs_build", fragment_entry),
        layouts,
        targets,
    )
}

/// How a technique draws a density volume into its maps (shaders/shadow/volume_splat.wgsl): a
/// full-screen triangle whose fragments march their texel's light ray (`fragment_entry`, into
/// the same targets with the same blends as its particles). Made on the first build with a
/// volume, so that a particle scene never compiles it.
pub(crate) struct VolumeBuild {
    device: wgpu::Device,
    module: wgpu::ShaderModule,
    label: String,
    fragment_entry: String,
    layouts: Vec<wgpu::BindGroupLayout>,
    targets: Vec<(wgpu::TextureFormat, wgpu::BlendComponent)>,
    pipeline: std::sync::OnceLock<wgpu::RenderPipeline>,
}

impl VolumeBuild {
    pub(crate) fn new(
        device: &wgpu::Device,
        module: &wgpu::ShaderModule,
        label: String,
        fragment_entry: impl Into<String>,
        layouts: &[&wgpu::BindGroupLayout],
        targets: &[(wgpu::TextureFormat, wgpu::BlendComponent)],
    ) -> Self {
        Self {
            device: device.clone(),
            module: module.clone(),
            label,
            fragment_entry: fragment_entry.into(),
            layouts: layouts.iter().map(|l| (*l).clone()).collect(),
            targets: targets.to_vec(),
            pipeline: std::sync::OnceLock::new(),
        }
    }

    /// Draws the volume into the pass's targets (the pipeline made on first use).
    pub(crate) fn draw(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        frame_bind_group: &wgpu::BindGroup,
        bind_group: &wgpu::BindGroup,
    ) {
        let pipeline = self.pipeline.get_or_init(|| {
            let layouts: Vec<_> = self.layouts.iter().map(Some).collect();
            build_pipeline_entries(
                &self.device,
                &self.label,
                &self.module,
                ("vs_volume", &self.fragment_entry),
                &layouts,
                &self.targets,
                false,
            )
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, frame_bind_group, &[]);
        pass.set_bind_group(1, bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}

/// [`billboard_pipeline_blends`] with its own vertex entry point (one that draws the billboards
/// of other spheres than the particles', e.g. `dom`'s enlarged ones).
fn billboard_pipeline_entries(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    entries: (&str, &str),
    layouts: &[Option<&wgpu::BindGroupLayout>],
    targets: &[(wgpu::TextureFormat, wgpu::BlendComponent)],
) -> wgpu::RenderPipeline {
    build_pipeline_entries(device, label, module, entries, layouts, targets, true)
}

/// A light-space build pipeline: billboards from the particle instances (`instanced`), or a
/// full-screen triangle without vertex buffers.
fn build_pipeline_entries(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    (vertex_entry, fragment_entry): (&str, &str),
    layouts: &[Option<&wgpu::BindGroupLayout>],
    targets: &[(wgpu::TextureFormat, wgpu::BlendComponent)],
    instanced: bool,
) -> wgpu::RenderPipeline {
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: layouts,
        immediate_size: 0,
    });
    let targets: Vec<_> = targets
        .iter()
        .map(|&(format, blend)| {
            Some(wgpu::ColorTargetState {
                format,
                blend: Some(wgpu::BlendState {
                    color: blend,
                    alpha: blend,
                }),
                write_mask: wgpu::ColorWrites::ALL,
            })
        })
        .collect();
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some(vertex_entry),
            compilation_options: Default::default(),
            buffers: if instanced {
                &[Some(ParticleInstance::LAYOUT)]
            } else {
                &[]
            },
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: None,
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some(fragment_entry),
            compilation_options: Default::default(),
            targets: &targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// A colour attachment cleared to `clear` and stored.
pub fn cleared_attachment(
    view: &wgpu::TextureView,
    clear: wgpu::Color,
) -> Option<wgpu::RenderPassColorAttachment<'_>> {
    Some(wgpu::RenderPassColorAttachment {
        view,
        depth_slice: None,
        resolve_target: None,
        ops: wgpu::Operations {
            load: wgpu::LoadOp::Clear(clear),
            store: wgpu::StoreOp::Store,
        },
    })
}

/// Draws every particle as a light-facing billboard with `pipeline` and group 1 `bind_group`.
pub(crate) fn draw_particles(
    pass: &mut wgpu::RenderPass<'_>,
    pipeline: &wgpu::RenderPipeline,
    frame_bind_group: &wgpu::BindGroup,
    bind_group: &wgpu::BindGroup,
    particles: wgpu::BufferSlice<'_>,
    count: u32,
) {
    if count > 0 {
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, frame_bind_group, &[]);
        pass.set_bind_group(1, bind_group, &[]);
        pass.set_vertex_buffer(0, particles);
        pass.draw(0..BILLBOARD_VERTICES, 0..count);
    }
}

impl Layered {
    pub fn new(
        ctx: &TechniqueContext<'_>,
        spec: &'static LayeredSpec,
        params: &TechniqueParams,
    ) -> Result<Self, ShadowError> {
        let gpu = ctx.gpu;
        let device = &gpu.device;
        let plan = (spec.plan)(params.channels);
        let target_count = plan.packed.div_ceil(4);
        let precision = spec.precision(params);
        let formats: Vec<_> = (0..target_count)
            .map(|i| target_format(plan.packed, i, precision))
            .collect();
        let float_features = wgpu::Features::FLOAT32_BLENDABLE | wgpu::Features::FLOAT32_FILTERABLE;
        if precision == Precision::Single && !gpu.features.contains(float_features) {
            return Err(ShadowError::MissingFeature {
                technique: spec.name,
                feature: "FLOAT32_BLENDABLE and FLOAT32_FILTERABLE (32-bit float maps)",
            });
        }
        let Some(passes) = target_passes(&formats, &gpu.limits) else {
            return Err(ShadowError::AdapterLimit {
                technique: spec.name,
                channels: params.channels,
                needed: 1,
                // The target that fits no pass: the largest.
                bytes_per_sample: formats
                    .iter()
                    .filter_map(|f| f.target_pixel_byte_cost())
                    .max()
                    .unwrap_or(0),
                allowed_attachments: gpu.limits.max_color_attachments,
                allowed_bytes: gpu.limits.max_color_attachment_bytes_per_sample,
            });
        };

        let name = spec.name;
        let res = params.resolution_px;
        let mut memory = MemoryLedger::for_technique(&gpu.limits, params.memory_limit_bytes);
        let maps = Maps::new(&mut memory, device, name, plan.packed, precision, res)?;
        let targets = maps.attachments();
        let depth_view = spec
            .depth_channel
            .then(|| {
                map_texture(
                    &mut memory,
                    device,
                    &format!("{name}.depth"),
                    DEPTH_FORMAT,
                    res,
                )
            })
            .transpose()?;
        let params_buffer = memory.buffer(
            device,
            &wgpu::BufferDescriptor {
                label: Some(&format!("{name}.params")),
                size: PARAMS_BYTES,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            },
        )?;

        // Build pass: group 1 holds the parameters and, after a depth pass, the depth channel it
        // reads (the maps themselves are render targets).
        let build_stages = wgpu::ShaderStages::VERTEX_FRAGMENT;
        let (params_layout, params_bind_group) = uniform_group(
            device,
            &format!("{name}.build.params"),
            &params_buffer,
            build_stages,
        );
        let module = shaders::module(
            device,
            &format!("{name}.build"),
            &build_shader_source(spec, &passes, params),
        );
        // One pipeline per pass, for its particles and for the volume, into its targets.
        let build_passes = |label: &str, layout: &wgpu::BindGroupLayout| -> Vec<BuildPass> {
            (0..)
                .zip(&passes)
                .map(|(g, range)| {
                    let formats = &formats[range.start as usize..range.end as usize];
                    let additive: Vec<_> = formats.iter().map(|&f| (f, ADDITIVE)).collect();
                    BuildPass {
                        targets: range.clone(),
                        pipeline: billboard_pipeline(
                            device,
                            &format!("{label}[{g}]"),
                            &module,
                            &format!("fs_build_{g}"),
                            &[Some(ctx.frame_layout), Some(layout)],
                            formats,
                            ADDITIVE,
                        ),
                        volume: VolumeBuild::new(
                            device,
                            &module,
                            format!("{label}.volume[{g}]"),
                            format!("fs_build_volume_{g}"),
                            &[ctx.frame_layout, layout],
                            &additive,
                        ),
                        writes: TargetWrites::of(formats),
                    }
                })
                .collect()
        };
        let (build, build_bind_group, depth) = match &depth_view {
            None => (
                build_passes(&format!("{name}.build"), &params_layout),
                params_bind_group,
                None,
            ),
            Some(depth_view) => {
                let layer_layout =
                    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                        label: Some(&format!("{name}.build.layer_layout")),
                        entries: &[
                            uniform_entry(0, build_stages),
                            texture_entry(DEPTH_BINDING, wgpu::ShaderStages::FRAGMENT),
                        ],
                    });
                let layer_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some(&format!("{name}.build.layer_bind_group")),
                    layout: &layer_layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: params_buffer.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: DEPTH_BINDING,
                            resource: wgpu::BindingResource::TextureView(depth_view),
                        },
                    ],
                });
                let depth_pipeline = billboard_pipeline_entries(
                    device,
                    &format!("{name}.build.depth"),
                    &module,
                    ("vs_depth", "fs_depth"),
                    &[Some(ctx.frame_layout), Some(&params_layout)],
                    &[(DEPTH_FORMAT, MIN_BLEND)],
                );
                (
                    build_passes(&format!("{name}.build.layers"), &layer_layout),
                    layer_bind_group,
                    Some(DepthPass {
                        view: depth_view.clone(),
                        pipeline: depth_pipeline,
                        volume: VolumeBuild::new(
                            device,
                            &module,
                            format!("{name}.build.depth.volume"),
                            "fs_depth_volume",
                            &[ctx.frame_layout, &params_layout],
                            &[(DEPTH_FORMAT, MIN_BLEND)],
                        ),
                        bind_group: params_bind_group,
                    }),
                )
            }
        };

        // Lookup: parameters, a bilinear sampler, the full layers as one array and the remainder
        // (one texture each, so a lookup picks a layer by index instead of switching between
        // textures), and the depth channel if there is one.
        let mut lookup_entries = lookup_layout_head();
        lookup_entries.push(wgpu::BindGroupLayoutEntry {
            binding: 2,
            visibility: LOOKUP_STAGES,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: true },
                view_dimension: wgpu::TextureViewDimension::D2Array,
                multisampled: false,
            },
            count: None,
        });
        lookup_entries.push(texture_entry(3, LOOKUP_STAGES));
        if depth_view.is_some() {
            lookup_entries.push(texture_entry(DEPTH_BINDING, LOOKUP_STAGES));
        }
        let lookup_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(&format!("{name}.lookup.layout")),
            entries: &lookup_entries,
        });
        let sampler = super::map_sampler(device, &format!("{name}.sampler"));
        let mut entries = lookup_group_head(&params_buffer, &sampler);
        entries.push(wgpu::BindGroupEntry {
            binding: 2,
            resource: wgpu::BindingResource::TextureView(&maps.full_view),
        });
        entries.push(wgpu::BindGroupEntry {
            binding: 3,
            resource: wgpu::BindingResource::TextureView(&maps.rest_view),
        });
        if let Some(view) = &depth_view {
            entries.push(wgpu::BindGroupEntry {
                binding: DEPTH_BINDING,
                resource: wgpu::BindingResource::TextureView(view),
            });
        }
        let lookup_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&format!("{name}.lookup.bind_group")),
            layout: &lookup_layout,
            entries: &entries,
        });

        Ok(Self {
            spec,
            plan,
            full_targets: maps.full_layers,
            params: params.clone(),
            params_buffer,
            targets,
            build,
            build_bind_group,
            depth,
            lookup_layout,
            lookup_bind_group,
            memory,
        })
    }

    /// The parameters for the shaders.
    fn shader_params(&self) -> LayeredParams {
        let (moment_bias, moment_bias_target) =
            moment_bias(self.spec, &self.params, self.plan.count);
        LayeredParams {
            count: self.plan.count,
            packed: self.plan.packed,
            splat: match self.params.splat {
                SplatMode::Point => 0,
                SplatMode::Segment => 1,
            },
            sigma: u32::from(self.spec.sigma),
            // 0 tells the shader: from each texel's start to the far bound.
            dom_thickness_m: self
                .spec
                .layer_thickness
                .and_then(|p| self.params.get(p))
                .unwrap_or(0.0),
            dom_ratio: layer_ratio(
                self.spec
                    .layer_growth
                    .and_then(|p| self.params.get(p))
                    .unwrap_or(1.0),
                self.plan.count,
            ),
            full_targets: self.full_targets,
            _pad0: 0,
            cubic: u32::from(
                self.spec
                    .interp
                    .is_some_and(|p| self.params.choice_index(p) == INTERP_CUBIC),
            ),
            dom_start_dilation: self
                .spec
                .start_dilation
                .and_then(|p| self.params.get(p))
                .unwrap_or(1.0),
            moment_bias,
            moment_overestimation: self.moment_param(|m| Some(m.overestimation)),
            wrapping_zone_rad: self.moment_param(|m| m.wrapping_zone),
            _pad1: [0; 3],
            moment_bias_target,
        }
    }

    /// The value of one of the spec's moment parameters (0 where it has none).
    fn moment_param(&self, which: impl Fn(&MomentParams) -> Option<&'static ParamSpec>) -> f32 {
        self.spec
            .moments
            .as_ref()
            .and_then(which)
            .and_then(|p| self.params.get(p))
            .unwrap_or(0.0)
    }
}

impl ShadowTechnique for Layered {
    fn name(&self) -> &'static str {
        self.spec.name
    }
    fn channels_used(&self) -> u32 {
        self.plan.used
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

    fn debug_maps(&self) -> Vec<DebugMap<'_>> {
        let mut out: Vec<DebugMap<'_>> = self
            .targets
            .iter()
            .enumerate()
            .map(|(t, view)| DebugMap {
                view,
                channels: (4 * t as u32..(4 * t as u32 + 4).min(self.plan.packed))
                    .map(|c| (self.spec.channel_name)(c, &self.plan))
                    .collect(),
                kind: self.spec.map_kind,
            })
            .collect();
        if let Some(depth) = &self.depth {
            out.insert(
                0,
                DebugMap {
                    view: &depth.view,
                    channels: vec!["depth where the smoke starts".to_owned()],
                    kind: MapKind::Depth01,
                },
            );
        }
        out
    }

    fn build<'a>(
        &'a mut self,
        gpu: &'a Gpu,
        inputs: BuildInputs<'a>,
    ) -> GpuFuture<'a, Result<(), ShadowError>> {
        Box::pin(async move {
            gpu.queue.write_buffer(
                &self.params_buffer,
                0,
                bytemuck::bytes_of(&self.shader_params()),
            );
            let particles = inputs.particles.slice(..);
            if let Some(depth) = &mut self.depth {
                // The depth where the smoke starts: MIN blending, cleared beyond the far bound.
                let mut pass = inputs
                    .encoder
                    .begin_render_pass(&wgpu::RenderPassDescriptor {
                        label: Some("dom.build.depth"),
                        color_attachments: &[cleared_attachment(&depth.view, wgpu::Color::WHITE)],
                        depth_stencil_attachment: None,
                        timestamp_writes: inputs.timer.pass("shadow"),
                        occlusion_query_set: None,
                        multiview_mask: None,
                    });
                let writes = TargetWrites::of(&[DEPTH_FORMAT]);
                inputs
                    .timer
                    .count_fragments(&mut pass, "shadow", writes, |pass| {
                        draw_particles(
                            pass,
                            &depth.pipeline,
                            inputs.frame_bind_group,
                            &depth.bind_group,
                            particles,
                            inputs.particle_count,
                        );
                        if inputs.volume.is_some() {
                            depth
                                .volume
                                .draw(pass, inputs.frame_bind_group, &depth.bind_group);
                        }
                    });
            }
            for build in &self.build {
                let attachments: Vec<_> = self.targets
                    [build.targets.start as usize..build.targets.end as usize]
                    .iter()
                    .map(|view| cleared_attachment(view, wgpu::Color::TRANSPARENT))
                    .collect();
                let mut pass = inputs
                    .encoder
                    .begin_render_pass(&wgpu::RenderPassDescriptor {
                        label: Some("layered.build"),
                        color_attachments: &attachments,
                        depth_stencil_attachment: None,
                        timestamp_writes: inputs.timer.pass("shadow"),
                        occlusion_query_set: None,
                        multiview_mask: None,
                    });
                inputs
                    .timer
                    .count_fragments(&mut pass, "shadow", build.writes, |pass| {
                        draw_particles(
                            pass,
                            &build.pipeline,
                            inputs.frame_bind_group,
                            &self.build_bind_group,
                            particles,
                            inputs.particle_count,
                        );
                        if inputs.volume.is_some() {
                            build.volume.draw(
                                pass,
                                inputs.frame_bind_group,
                                &self.build_bind_group,
                            );
                        }
                    });
            }
            Ok(())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn target_formats_fit_the_packed_channels() {
        use wgpu::TextureFormat as F;
        let half = |packed, index| target_format(packed, index, Precision::Half);
        assert_eq!(half(6, 0), F::Rgba16Float);
        assert_eq!(half(6, 1), F::Rg16Float);
        assert_eq!(half(5, 1), F::R16Float);
        assert_eq!(half(7, 1), F::Rgba16Float);
        assert_eq!(half(24, 5), F::Rgba16Float);
        assert_eq!(target_format(23, 5, Precision::Single), F::Rgba32Float);
        assert_eq!(target_format(5, 1, Precision::Single), F::R32Float);
    }

    #[test]
    fn passes_hold_the_adapters_attachments_and_bytes_per_sample() {
        let formats = |packed: u32, precision| -> Vec<_> {
            (0..packed.div_ceil(4))
                .map(|i| target_format(packed, i, precision))
                .collect()
        };
        let half = |packed| formats(packed, Precision::Half);
        // WebGPU's default limits: 8 attachments, 32 bytes a sample, so 4 RGBA16F (8 bytes)
        // targets a pass, or 2 RGBA32F; a 2-byte R16F remainder still fits beside 3 RGBA16F.
        let mut limits = wgpu::Limits::default();
        assert_eq!(limits.max_color_attachment_bytes_per_sample, 32);
        assert_eq!(target_passes(&half(24), &limits), Some(vec![0..4, 4..6]));
        assert_eq!(
            target_passes(&half(13), &limits),
            Some(std::iter::once(0..4).collect())
        );
        assert_eq!(
            target_passes(&formats(12, Precision::Single), &limits),
            Some(vec![0..2, 2..3])
        );
        // lavapipe's 128 bytes: 32 channels in one pass, 128 in four of 8.
        limits.max_color_attachment_bytes_per_sample = 128;
        assert_eq!(
            target_passes(&half(32), &limits),
            Some(std::iter::once(0..8).collect())
        );
        assert_eq!(
            target_passes(&half(MAX_MULTI_PASS_CHANNELS), &limits),
            Some(vec![0..8, 8..16, 16..24, 24..32])
        );
        assert_eq!(target_passes(&half(37), &limits), Some(vec![0..8, 8..10]));
        // Fewer attachments: fewer a pass.
        limits.max_color_attachments = 3;
        assert_eq!(target_passes(&half(24), &limits), Some(vec![0..3, 3..6]));
        // A target that fits no pass.
        limits.max_color_attachment_bytes_per_sample = 4;
        assert_eq!(target_passes(&half(4), &limits), None);
    }

    #[test]
    fn layers_thin_as_they_are_added_at_a_fixed_growth() {
        // The last layer over the first is the growth at every count, so the ratio between
        // successive layers falls towards 1 (and the thickest layer's share with it).
        for layers in [5, 11, 23, 47, 127] {
            let r = layer_ratio(3.27, layers);
            assert!(
                (r.powi(layers as i32 - 1) - 3.27).abs() < 1e-3,
                "{layers}: {r}"
            );
        }
        assert!(layer_ratio(3.27, 127) < layer_ratio(3.27, 23));
        let last_share = |layers: u32| {
            let r = f64::from(layer_ratio(3.27, layers));
            r.powi(layers as i32 - 1) * (r - 1.0) / (r.powi(layers as i32) - 1.0)
        };
        assert!(last_share(127) < 0.5 * last_share(23) && last_share(23) < 0.3 * last_share(5));
        assert_eq!(layer_ratio(1.0, 23), 1.0);
        assert_eq!(layer_ratio(8.0, 1), 1.0);
    }

    #[test]
    fn budgets_map_to_the_thesis_channel_plans() {
        // Thesis chapter 4: DOM spends one channel on depth (24 -> 23 layers); FOM 24 channels
        // hold 11 harmonics, 8 hold 3, 6 hold 2.
        let plan = |spec: &LayeredSpec, b| (spec.plan)(b);
        assert_eq!(plan(&super::super::dom::SPEC, 24).count, 23);
        assert_eq!(plan(&super::super::dom::SPEC, 24).used, 24);
        let fom = &super::super::fom::FOM;
        assert_eq!(plan(fom, 24).count, 11);
        assert_eq!(plan(fom, 24).used, 23);
        assert_eq!(plan(fom, 8).count, 3);
        assert_eq!(plan(fom, 6).count, 2);
        assert_eq!(plan(fom, 3).packed, 3);
        assert_eq!(plan(&super::super::osm::SPEC, 6).packed, 6);
    }
}
