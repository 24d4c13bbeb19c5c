//! The particle pass's pieces: lighting each particle once per frame with the active technique
//! ([`ParticleLighting`], `shaders/render/particle_lighting.wgsl`), and drawing the billboards
//! with that lighting ([`ParticlePipelines`], `shaders/render/particles.wgsl`).
//!
//! Lighting is a compute pass over a range of the instance buffer: the renderer lights every
//! particle in one dispatch; half-angle slicing lights one batch at a time, between its light
//! passes. The draw pipelines do not depend on the technique at all.

use std::ops::Range;

use bytemuck::{Pod, Zeroable};

use super::gpu_data::ParticleInstance;
use super::{DEPTH_FORMAT, HDR_FORMAT};
use crate::gpu::{AllocationError, Gpu, GpuError, MemoryLedger};
use crate::shaders;

/// Premultiplied "over" (thesis Eq. 1.5): C = C_src + (1 - α_src) C_dst, the same for alpha.
pub const OVER: wgpu::BlendComponent = wgpu::BlendComponent {
    src_factor: wgpu::BlendFactor::One,
    dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
    operation: wgpu::BlendOperation::Add,
};

/// Premultiplied "under" (thesis Eq. 1.4), for front-to-back compositing:
/// C = C_dst + (1 - α_dst) C_src, the same for alpha.
pub const UNDER: wgpu::BlendComponent = wgpu::BlendComponent {
    src_factor: wgpu::BlendFactor::OneMinusDstAlpha,
    dst_factor: wgpu::BlendFactor::One,
    operation: wgpu::BlendOperation::Add,
};

/// One particle's lighting: radiance at its four lighting points (w unused). Keep in sync with
/// `ParticleLight` in shaders/render/particle_lighting.wgsl and particles.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub struct ParticleLight {
    pub radiance: [[f32; 4]; 4],
}

/// Keep in sync with `LightRange` in shaders/render/particle_lighting.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct LightRange {
    start: u32,
    count: u32,
    /// Not 0: light the range in the order [`LightBuffers::write_order`] wrote.
    ordered: u32,
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![
        crate::mirror_layout!(
            ParticleLight,
            "render/particle_lighting.wgsl",
            "ParticleLight",
            [radiance]
        ),
        crate::mirror_layout!(
            LightRange,
            "render/particle_lighting.wgsl",
            "LightRange",
            [start, count, ordered]
        ),
    ]
}

/// Particles one workgroup of the lighting pass lights (`PARTICLES_PER_WORKGROUP` in
/// shaders/render/particle_lighting.wgsl), with an invocation per lighting point (256), so that
/// each invocation makes one lookup and a looping lookup may take llvmpipe's whole loop budget
/// (`shadow::exact`). 4,000,000 particles need 62,500 workgroups, within the 65,535 of a
/// dispatch.
const PARTICLES_PER_WORKGROUP: u32 = 64;

/// Uniform offsets must be multiples of this (the WebGPU minimum, which every adapter meets).
const RANGE_STRIDE: u64 = 256;

/// The bind group layouts of the lighting buffers, made once and shared by every pipeline that
/// reads or writes them.
#[derive(Clone)]
pub struct ParticleLayouts {
    /// The lighting as the draw pipelines read it (group 1, vertex stage).
    pub read: wgpu::BindGroupLayout,
    /// Instances, lighting, the range uniform and the lighting order as the lighting pass uses
    /// them (group 2).
    pub io: wgpu::BindGroupLayout,
    /// The shadow's temporal history (group 3 of the renderer's lighting pass:
    /// `crate::render::history`).
    pub history: wgpu::BindGroupLayout,
}

impl ParticleLayouts {
    pub fn new(device: &wgpu::Device) -> Self {
        let storage = crate::gpu::storage_entry;
        let read = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("particles.light_layout"),
            entries: &[storage(0, wgpu::ShaderStages::VERTEX, true)],
        });
        let compute = wgpu::ShaderStages::COMPUTE;
        let io = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("particle_lighting.io_layout"),
            entries: &[
                storage(0, compute, true),
                storage(1, compute, false),
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: compute,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: true,
                        min_binding_size: wgpu::BufferSize::new(
                            std::mem::size_of::<LightRange>() as u64
                        ),
                    },
                    count: None,
                },
                storage(3, compute, true),
            ],
        });
        let history = crate::render::history::layout(device);
        Self { read, io, history }
    }
}

/// The lighting compute pipeline for one technique's lookup.
pub struct ParticleLighting {
    pipeline: wgpu::ComputePipeline,
}

impl ParticleLighting {
    /// `imports`: the technique's lookup shader (group 1, `shadow_transmittance`) and the
    /// occluders' visibility, as `TechniqueEntry::frame_imports` gives them. Group 3 is the
    /// shadow's temporal history (`crate::render::history`; off in a history never prepared).
    pub fn new(
        device: &wgpu::Device,
        name: &str,
        frame_layout: &wgpu::BindGroupLayout,
        lookup_layout: &wgpu::BindGroupLayout,
        imports: &[(&str, &str)],
        layouts: &ParticleLayouts,
    ) -> Self {
        let module = shaders::module(
            device,
            &format!("particle_lighting[{name}]"),
            &lighting_source(imports),
        );
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("particle_lighting.pipeline_layout"),
            bind_group_layouts: &[
                Some(frame_layout),
                Some(lookup_layout),
                Some(&layouts.io),
                Some(&layouts.history),
            ],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(&format!("particle_lighting[{name}]")),
            layout: Some(&layout),
            module: &module,
            entry_point: Some("light_particles"),
            compilation_options: Default::default(),
            cache: None,
        });
        Self { pipeline }
    }

    /// Writes `ranges` (at most the buffers' batch capacity) for the next submission, to be lit
    /// in the order [`LightBuffers::write_order`] wrote when `ordered`.
    pub fn set_ranges(
        &self,
        queue: &wgpu::Queue,
        buffers: &LightBuffers,
        ranges: &[Range<u32>],
        ordered: bool,
    ) {
        assert!(
            ranges.len() <= buffers.max_batches as usize,
            "more batches than allocated"
        );
        let mut bytes = vec![0u8; ranges.len() * RANGE_STRIDE as usize];
        for (i, r) in ranges.iter().enumerate() {
            let at = i * RANGE_STRIDE as usize;
            let range = LightRange {
                start: r.start,
                count: r.end - r.start,
                ordered: u32::from(ordered),
            };
            let range = bytemuck::bytes_of(&range);
            bytes[at..at + range.len()].copy_from_slice(range);
        }
        if !bytes.is_empty() {
            queue.write_buffer(&buffers.ranges, 0, &bytes);
        }
    }

    /// Records the lighting of range `batch` (as set by [`Self::set_ranges`], `count` particles)
    /// into `pass`.
    #[allow(clippy::too_many_arguments)]
    pub fn dispatch(
        &self,
        pass: &mut wgpu::ComputePass<'_>,
        frame_bind_group: &wgpu::BindGroup,
        lookup_bind_group: &wgpu::BindGroup,
        buffers: &LightBuffers,
        history: &wgpu::BindGroup,
        batch: u32,
        count: u32,
    ) {
        if count == 0 {
            return;
        }
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, frame_bind_group, &[]);
        pass.set_bind_group(1, lookup_bind_group, &[]);
        pass.set_bind_group(3, history, &[]);
        let offset = (u64::from(batch) * RANGE_STRIDE) as u32;
        pass.set_bind_group(2, &buffers.io_bind_group, &[offset]);
        pass.dispatch_workgroups(count.div_ceil(PARTICLES_PER_WORKGROUP), 1, 1);
    }
}

/// The lighting buffer for one instance buffer, the ranges uniform, and the order to light the
/// particles in.
pub struct LightBuffers {
    capacity: u64,
    max_batches: u32,
    lighting: wgpu::Buffer,
    ranges: wgpu::Buffer,
    /// Instance indices, 4 bytes a particle of capacity.
    order: wgpu::Buffer,
    /// The lighting as the draw pipelines read it (group 1).
    pub read_bind_group: wgpu::BindGroup,
    io_bind_group: wgpu::BindGroup,
}

impl LightBuffers {
    /// Lighting for `capacity` particles of `instances`, in up to `max_batches` ranges; in a
    /// technique's order ([`LightBuffers::write_order`]) when `ordered` (otherwise the order
    /// binding is a 16-byte placeholder). Its buffers are created through `memory` (the
    /// technique's ledger, or the frame's), which forgets those of the same `label` first: the
    /// buffers this replaces.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        device: &wgpu::Device,
        memory: &mut MemoryLedger,
        layouts: &ParticleLayouts,
        instances: &wgpu::Buffer,
        capacity: u64,
        max_batches: u32,
        ordered: bool,
        label: &str,
    ) -> Result<Self, AllocationError> {
        let mut buffer = |what: &str, size: u64, usage: wgpu::BufferUsages| {
            let name = format!("{label}.{what}");
            memory.forget(&name);
            memory.buffer(
                device,
                &wgpu::BufferDescriptor {
                    label: Some(&name),
                    size,
                    usage,
                    mapped_at_creation: false,
                },
            )
        };
        use wgpu::BufferUsages as U;
        let lighting = buffer(
            "lighting",
            capacity.max(1) * std::mem::size_of::<ParticleLight>() as u64,
            // COPY_SRC: read back for `read` (tests and the sweep's error at lighting points).
            U::STORAGE | U::COPY_SRC,
        )?;
        let ranges = buffer(
            "light_ranges",
            u64::from(max_batches.max(1)) * RANGE_STRIDE,
            U::UNIFORM | U::COPY_DST,
        )?;
        let order = buffer(
            "light_order",
            if ordered { capacity.max(4) * 4 } else { 16 },
            U::STORAGE | U::COPY_DST,
        )?;
        let read_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&format!("{label}.light_bind_group")),
            layout: &layouts.read,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: lighting.as_entire_binding(),
            }],
        });
        let io_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&format!("{label}.light_io_bind_group")),
            layout: &layouts.io,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: instances.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: lighting.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &ranges,
                        offset: 0,
                        size: wgpu::BufferSize::new(std::mem::size_of::<LightRange>() as u64),
                    }),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: order.as_entire_binding(),
                },
            ],
        });
        Ok(Self {
            capacity,
            max_batches,
            lighting,
            ranges,
            order,
            read_bind_group,
            io_bind_group,
        })
    }

    /// Writes the order a range set `ordered` lights its particles in: `order[i]` is the
    /// instance the lighting of slot i lights (at most the capacity).
    pub fn write_order(&self, queue: &wgpu::Queue, order: &[u32]) {
        assert!(
            order.len() as u64 * 4 <= self.order.size(),
            "order beyond the order buffer"
        );
        if !order.is_empty() {
            queue.write_buffer(&self.order, 0, bytemuck::cast_slice(order));
        }
    }

    /// Particles this lighting holds.
    pub fn capacity(&self) -> u64 {
        self.capacity
    }

    /// The lighting of the first `count` particles as the last submitted frame left it (waits
    /// for the GPU): per particle, its four points' radiance, with the smoke's T in w.
    pub async fn read(&self, gpu: &Gpu, count: usize) -> Result<Vec<ParticleLight>, GpuError> {
        let count = (count as u64).min(self.capacity);
        if count == 0 {
            return Ok(Vec::new());
        }
        let size = count * std::mem::size_of::<ParticleLight>() as u64;
        let bytes = crate::gpu::read_buffer(gpu, &self.lighting, 0, size).await?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }
}

/// One particle as the last frame lit it: its sphere and the smoke's T its lighting used at
/// each of its four lighting points (`render::shaded::particle_lighting_points`' order).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LitParticle {
    pub center: glam::Vec3,
    pub radius_m: f32,
    pub transmittance: [f32; 4],
}

impl LitParticle {
    /// Pairs `instances` with the lighting `read` returned for them, in the same order.
    pub fn of(instances: &[ParticleInstance], lights: &[ParticleLight]) -> Vec<Self> {
        instances
            .iter()
            .zip(lights)
            .map(|(i, l)| Self {
                center: glam::Vec3::from_slice(&i.center_radius[..3]),
                radius_m: i.center_radius[3],
                transmittance: l.radiance.map(|r| r[3]),
            })
            .collect()
    }
}

/// The composed lighting shader for a technique's `imports` (its lookup and the occluders'
/// visibility: `TechniqueEntry::frame_imports`).
pub fn lighting_source(imports: &[(&str, &str)]) -> String {
    shaders::compose("render/particle_lighting.wgsl", imports)
}

/// The particle pass's two pipelines (`shaders/render/particles.wgsl`): spherical billboards
/// (group 2 = opaque depth) and flat billboards with a hard depth test; group 1 is the lighting.
pub struct ParticlePipelines {
    pub spherical: wgpu::RenderPipeline,
    pub flat: wgpu::RenderPipeline,
}

impl ParticlePipelines {
    /// Pipelines compositing into an HDR-format target with `blend`.
    pub fn new(
        device: &wgpu::Device,
        label: &str,
        frame_layout: &wgpu::BindGroupLayout,
        layouts: &ParticleLayouts,
        depth_layout: &wgpu::BindGroupLayout,
        blend: wgpu::BlendComponent,
    ) -> Self {
        let light_layout = &layouts.read;
        let module = shaders::module(
            device,
            label,
            &shaders::compose("render/particles.wgsl", &[]),
        );
        let layout = |suffix: &str, groups: &[Option<&wgpu::BindGroupLayout>]| {
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(&format!("{label}.{suffix}.pipeline_layout")),
                bind_group_layouts: groups,
                immediate_size: 0,
            })
        };
        let spherical_layout = layout(
            "spherical",
            &[Some(frame_layout), Some(light_layout), Some(depth_layout)],
        );
        let flat_layout = layout("flat", &[Some(frame_layout), Some(light_layout)]);
        let target = [Some(wgpu::ColorTargetState {
            format: HDR_FORMAT,
            blend: Some(wgpu::BlendState {
                color: blend,
                alpha: blend,
            }),
            write_mask: wgpu::ColorWrites::ALL,
        })];
        let pipeline = |suffix: &str,
                        layout: &wgpu::PipelineLayout,
                        fs,
                        depth: Option<wgpu::DepthStencilState>| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(&format!("{label}.{suffix}.pipeline")),
                layout: Some(layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("vs_main"),
                    compilation_options: Default::default(),
                    buffers: &[Some(ParticleInstance::LAYOUT)],
                },
                primitive: wgpu::PrimitiveState::default(),
                depth_stencil: depth,
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(fs),
                    compilation_options: Default::default(),
                    targets: &target,
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        Self {
            spherical: pipeline("spherical", &spherical_layout, "fs_spherical", None),
            flat: pipeline(
                "flat",
                &flat_layout,
                "fs_flat",
                Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(false),
                    depth_compare: Some(wgpu::CompareFunction::Less),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
            ),
        }
    }
}
