//! `srm`: secondary ray marching (the 2022 dissertation's SRM, seeds/000 §3.2.3, Algorithm 2;
//! the 2018 cloud thesis' "steps towards the sun", seeds/004 §4.1): no map at all. Each lookup
//! marches `srm_light_steps` samples of the density volume from the point to the light
//! (trilinear, midpoint rule over the part of the segment the grid covers) and returns
//! exp(-Σ σ Δt). Its cost grows with the cloud the eye crosses, a map's does not: the
//! dissertation's coverage experiment.
//!
//! It marches the density volume only: a particle has no density to sample, so a scene with
//! particles is refused in one line (`shadows_particles`). Shaders: `shaders/shadow/srm.wgsl`.

use super::GpuFuture;
use bytemuck::{Pod, Zeroable};

use super::{
    BuildInputs, LOOKUP_STAGES, MemoryUse, ParamSpec, Role, ShadowError, ShadowTechnique,
    TechniqueContext, TechniqueEntry, TechniqueParams,
};
use crate::gpu::{Gpu, MemoryLedger};

/// `srm_light_steps`: samples of each lookup's march towards the light.
pub const LIGHT_STEPS: ParamSpec = ParamSpec {
    key: "srm_light_steps",
    unit: "-",
    doc: "samples N of the march from the point to the light through the density volume \
          (rounded to an integer; the dissertation varied 1-50): more find thin and distant \
          cloud, at N texture reads per lookup",
    min: 1.0,
    max: 4096.0,
    default: Some(DEFAULT_LIGHT_STEPS as f32),
    choices: &[],
    integer: true,
    tuned: false,
};

/// Where the 2018 thesis' returns stop (docs/volumes.md, "the sun-step experiment": RMSE
/// 0.0037 at 5 steps on the cloud, 0.0012 at 8) with a margin: 16.
pub const DEFAULT_LIGHT_STEPS: u32 = 16;

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: "srm",
    description: "secondary ray marching: N samples of the density volume towards the light per \
                  lookup, no map (the dissertation's SRM); volumes only",
    role: Role::Contender,
    budget_caption: |_| "no map (N light samples)".to_owned(),
    min_channels: 1,
    max_channels: super::MAX_CHANNELS,
    in_default_sweep: false,
    in_default_compare: false,
    build_reads_back: false,
    params: &[LIGHT_STEPS],
    order_independent: true,
    converges_with_budget: false,
    converges_from: 1,
    compresses_captured_lists: false,
    // Its one uniform.
    memory: |_| MemoryUse {
        channels: 0,
        bytes: std::mem::size_of::<SrmParams>() as u64,
        transient_bytes: 0,
    },
    lookup_shader: "shadow/srm.wgsl",
    lookup_constants: super::no_lookup_constants,
    extra_shaders: Vec::new,
    create: |ctx, params| Ok(Box::new(Srm::new(ctx, params)?)),
    uses_splat: false,
    uses_budget: false,
    owns_particle_pass: false,
    volume: super::VolumeSupport::Shadows,
    shadows_particles: false,
};

/// Keep in sync with `SrmParams` in shaders/shadow/srm.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct SrmParams {
    steps: u32,
    _pad: [u32; 3],
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![crate::mirror_layout!(
        SrmParams,
        "shadow/srm.wgsl",
        "SrmParams",
        [steps]
    )]
}

pub struct Srm {
    steps: u32,
    layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    memory: MemoryLedger,
}

impl Srm {
    pub fn new(ctx: &TechniqueContext<'_>, params: &TechniqueParams) -> Result<Self, ShadowError> {
        let gpu = ctx.gpu;
        let steps = params
            .get(&LIGHT_STEPS)
            .map_or(DEFAULT_LIGHT_STEPS, |s| s.round() as u32);
        if let Some(budget) = gpu.loop_budget()
            && steps + 3 > budget
        {
            return Err(ShadowError::Volume(format!(
                "srm: {steps} light steps exceed what one shader invocation may loop on this \
                 adapter ({budget} iterations, 3 of them the march's set-up)"
            )));
        }
        let mut memory = MemoryLedger::for_technique(&gpu.limits, params.memory_limit_bytes);
        let buffer = memory.buffer(
            &gpu.device,
            &wgpu::BufferDescriptor {
                label: Some("srm.params"),
                size: std::mem::size_of::<SrmParams>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            },
        )?;
        gpu.queue.write_buffer(
            &buffer,
            0,
            bytemuck::bytes_of(&SrmParams {
                steps,
                _pad: [0; 3],
            }),
        );
        let (layout, bind_group) =
            super::layered::uniform_group(&gpu.device, "srm.lookup", &buffer, LOOKUP_STAGES);
        Ok(Self {
            steps,
            layout,
            bind_group,
            memory,
        })
    }
}

impl ShadowTechnique for Srm {
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
        &self.layout
    }
    fn bind_group(&self) -> &wgpu::BindGroup {
        &self.bind_group
    }
    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![("srm_light_steps", u64::from(self.steps))]
    }
    /// Nothing to build: every lookup marches the volume itself.
    fn build<'a>(
        &'a mut self,
        _gpu: &'a Gpu,
        _inputs: BuildInputs<'a>,
    ) -> GpuFuture<'a, Result<(), ShadowError>> {
        Box::pin(async move { Ok(()) })
    }
}
