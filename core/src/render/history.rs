//! The shadow's temporal history (`[shadow] history = w`, `sweep --shadow-history W`): each
//! particle's transmittance at its four lighting points blended with its own from the frame
//! before, T' = (1 − w) T + w T'_prev, as engines filter a shadow that flickers (0.9 is the
//! weight they default to). A filtered shadow lags the smoke by about w / (1 − w) frames (9 at
//! 0.9) and costs 20 bytes a particle (the history and the frame's instance-to-particle map)
//! and one read and write a lighting point; `docs/studies.md` measures what it buys.
//!
//! The history is kept per particle, the i-th of the scene's particles (the sort's index), so
//! it survives a moving camera and the back-to-front order changing; it assumes the i-th
//! particle of a frame is the i-th of the last one when their counts agree (the emitter's
//! slots; a particle file sequence that keeps its particles' order). A particle starts afresh
//! when it has no history: the first frame after [`ShadowHistory::reset`] (a technique is
//! set, an animated sweep starts a cell), another particle count, or a particle whose age went
//! down (reborn in its slot). Only the particles' lighting is filtered; the ground's shadow and
//! a technique that lights the particles in its own pass (`has`) are not, and `exact`, the
//! reference, never is.

use bytemuck::{Pod, Zeroable};

use crate::gpu::{AllocationError, Gpu, MemoryLedger};
use crate::sim::Particle;

/// Keep in sync with `HistoryParams` in shaders/render/shadow_history.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct HistoryParams {
    weight: f32,
    _pad: [u32; 3],
}

/// Bit 31 of an instance's id: it has no history (`HISTORY_FRESH` in the shader).
const FRESH: u32 = 1 << 31;

/// The WGSL struct mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![crate::mirror_layout!(
        HistoryParams,
        "render/shadow_history.wgsl",
        "HistoryParams",
        [weight]
    )]
}

/// The bind group layout of the history (group 3 of the renderer's lighting pass).
pub fn layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    let storage = crate::gpu::storage_entry;
    let compute = wgpu::ShaderStages::COMPUTE;
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("shadow_history.layout"),
        entries: &[
            storage(0, compute, false),
            storage(1, compute, true),
            wgpu::BindGroupLayoutEntry {
                binding: 2,
                visibility: compute,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            },
        ],
    })
}

/// The history's buffers and what decides which particles have one.
pub struct ShadowHistory {
    ids: wgpu::Buffer,
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    /// Particles the buffers hold (1 while the history was never on).
    capacity: u64,
    /// Each particle's age in the last frame whose lighting ran filtered; `None` after a
    /// reset. And the ages of the frame prepared since, which become it once its lighting ran
    /// ([`ShadowHistory::lit`]; a probe prepares a frame without lighting it).
    ages: Option<Vec<f32>>,
    prepared: Option<Vec<f32>>,
    weight: f32,
}

impl ShadowHistory {
    /// An empty history (placeholders of one particle: off until a frame asks for it).
    pub fn new(
        device: &wgpu::Device,
        memory: &mut MemoryLedger,
        layout: &wgpu::BindGroupLayout,
    ) -> Result<Self, AllocationError> {
        Self::with_capacity(device, memory, layout, 1)
    }

    fn with_capacity(
        device: &wgpu::Device,
        memory: &mut MemoryLedger,
        layout: &wgpu::BindGroupLayout,
        capacity: u64,
    ) -> Result<Self, AllocationError> {
        use wgpu::BufferUsages as U;
        let mut buffer = |what: &str, size: u64, usage: U| {
            let label = format!("shadow_history.{what}");
            memory.forget(&label);
            memory.buffer(
                device,
                &wgpu::BufferDescriptor {
                    label: Some(&label),
                    size,
                    usage,
                    mapped_at_creation: false,
                },
            )
        };
        let values = buffer("values", capacity * 16, U::STORAGE)?;
        let ids = buffer("ids", capacity.max(4) * 4, U::STORAGE | U::COPY_DST)?;
        let params = buffer(
            "params",
            std::mem::size_of::<HistoryParams>() as u64,
            U::UNIFORM | U::COPY_DST,
        )?;
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shadow_history.bind_group"),
            layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: values.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: ids.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: params.as_entire_binding(),
                },
            ],
        });
        // (The bind group keeps the values' buffer alive; the ledger counts its bytes.)
        Ok(Self {
            ids,
            params,
            bind_group,
            capacity,
            ages: None,
            prepared: None,
            // Unwritten: the first `prepare` writes the weight.
            weight: f32::NAN,
        })
    }

    /// Forgets every particle's history: the next filtered frame starts afresh.
    pub fn reset(&mut self) {
        self.ages = None;
        self.prepared = None;
    }

    /// Sets the frame up: weight `weight` (0: off) for `particles` drawn in `order` (the sort's
    /// particle index of each instance), growing the buffers to hold them (which forgets the
    /// history).
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        memory: &mut MemoryLedger,
        layout: &wgpu::BindGroupLayout,
        weight: f32,
        particles: &[Particle],
        order: &[u32],
    ) -> Result<(), AllocationError> {
        let weight = if particles.is_empty() { 0.0 } else { weight };
        if weight > 0.0 && particles.len() as u64 > self.capacity {
            let capacity = (particles.len() as u64).next_power_of_two();
            *self = Self::with_capacity(&gpu.device, memory, layout, capacity)?;
        }
        if weight.to_bits() != self.weight.to_bits() {
            gpu.queue.write_buffer(
                &self.params,
                0,
                bytemuck::bytes_of(&HistoryParams {
                    weight,
                    _pad: [0; 3],
                }),
            );
            self.weight = weight;
        }
        if weight <= 0.0 {
            self.ages = None;
            self.prepared = None;
            return Ok(());
        }
        let ages: Vec<f32> = particles.iter().map(|p| p.age_s).collect();
        let known = self.ages.as_ref().filter(|a| a.len() == ages.len());
        let ids: Vec<u32> = order
            .iter()
            .map(|&i| match known {
                Some(last) if ages[i as usize] >= last[i as usize] => i,
                _ => i | FRESH,
            })
            .collect();
        gpu.queue
            .write_buffer(&self.ids, 0, bytemuck::cast_slice(&ids));
        self.prepared = Some(ages);
        Ok(())
    }

    /// The prepared frame's lighting was recorded: its particles now have a history.
    pub fn lit(&mut self) {
        if let Some(ages) = self.prepared.take() {
            self.ages = Some(ages);
        }
    }

    /// Whether the last prepared frame is filtered.
    pub fn active(&self) -> bool {
        self.weight > 0.0
    }

    pub fn bind_group(&self) -> &wgpu::BindGroup {
        &self.bind_group
    }
}
