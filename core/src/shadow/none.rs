//! `none`: no self-shadowing (T = 1). It allocates nothing and records no pass; frame times with
//! `none` are the baseline for a technique's overhead ratio.

use super::GpuFuture;
use super::{
    BuildInputs, MemoryUse, Role, ShadowError, ShadowTechnique, TechniqueContext, TechniqueEntry,
    TechniqueParams,
};
use crate::gpu::{Gpu, MemoryLedger};

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: "none",
    description: "no self-shadowing (T = 1); the frame-time baseline",
    role: Role::FrameBaseline,
    budget_caption: |_| "no maps".to_owned(),
    min_channels: 1,
    max_channels: super::MAX_CHANNELS,
    in_default_sweep: false,
    in_default_compare: false,
    build_reads_back: false,
    params: &[],
    order_independent: true,
    converges_with_budget: false,
    converges_from: 1,
    compresses_captured_lists: false,
    memory: |_| MemoryUse {
        channels: 0,
        bytes: 0,
        transient_bytes: 0,
    },
    lookup_shader: "shadow/none.wgsl",
    lookup_constants: super::no_lookup_constants,
    extra_shaders: Vec::new,
    create: |ctx, params| Ok(Box::new(NoShadow::new(ctx, params)?)),
    uses_splat: false,
    uses_budget: false,
    owns_particle_pass: false,
    volume: super::VolumeSupport::Shadows,
    shadows_particles: true,
};

pub struct NoShadow {
    layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    memory: MemoryLedger,
}

impl NoShadow {
    pub fn new(ctx: &TechniqueContext<'_>, _params: &TechniqueParams) -> Result<Self, ShadowError> {
        let device = &ctx.gpu.device;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("none.layout"),
            entries: &[],
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("none.bind_group"),
            layout: &layout,
            entries: &[],
        });
        Ok(Self {
            layout,
            bind_group,
            memory: MemoryLedger::for_device(&ctx.gpu.limits),
        })
    }
}

impl ShadowTechnique for NoShadow {
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
    fn build<'a>(
        &'a mut self,
        _gpu: &'a Gpu,
        _inputs: BuildInputs<'a>,
    ) -> GpuFuture<'a, Result<(), ShadowError>> {
        Box::pin(async move { Ok(()) })
    }
}
