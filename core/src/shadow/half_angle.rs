//! `has`: half-angle slicing for particles (Kniss et al. 2003; Green 2008, "Volumetric Particle
//! Shadows"; thesis 3.3.3.3).
//!
//! The particles are sorted along the vector halfway between the view and the light directions
//! and split into S batches (S = the channel budget, so its curves line up with the layered
//! techniques in a sweep). For each batch in turn: draw it to the eye, lit through the light
//! buffer (the optical depth of the batches before it), then draw it into the light buffer. When
//! the camera faces the light, the half-angle uses the inverted view vector and the eye
//! composites back to front ("over", thesis Eq. 1.5); otherwise front to back ("under",
//! Eq. 1.4) into an eye buffer of its own that is then composited over the frame. Either way
//! the light buffer is always filled front to back from the light.
//!
//! So this technique owns the particle pass ([`ShadowTechnique::particle_pass`]). Its build pass
//! fills the light buffer with every batch, which is what the opaque pass (the ground and the
//! boxes receiving the smoke's shadow) reads. The light direction used for the half-angle is the
//! spotlight's axis; the light buffer itself is the spotlight's perspective map.
//!
//! Under a point light the direction runs from the light to the smoke's centroid, and the first
//! cube face's instance draws the batches and fills every face's light buffer
//! ([`ParticlePass::light_batch`]), each batch lit from the face its points fall in. Smoke
//! behind the light along that direction has no front-to-back order from it and is refused
//! ([`ShadowError::PointLightBehind`]). With the frame sorted along the half-angle
//! ([`crate::render::SortOrder::HalfAngle`]) it draws in the frame's order and sorts nothing.
//!
//! Memory: the light buffer (one R16F channel at the shadow resolution), the eye buffer (RGBA16F
//! at the frame size) and the particles re-sorted along the half-angle, all in the ledger.

use super::GpuFuture;
use std::ops::Range;
use web_time::Instant;

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use super::layered::{
    ADDITIVE, billboard_pipeline, cleared_attachment, map_texture, sampler_entry, texture_entry,
};
use super::probe::PendingProbe;
use super::{
    BuildInputs, DebugMap, LOOKUP_STAGES, MapKind, MemoryUse, NO_OWNER, OtherFace, ParticlePass,
    ParticlePassInputs, ProbeInputs, ProbePass, Role, ShadowError, ShadowTechnique,
    TechniqueContext, TechniqueEntry, TechniqueParams,
};
use crate::frame::gpu_data::{BILLBOARD_VERTICES, ParticleInstance};
use crate::frame::particles::{LightBuffers, LitParticle, ParticleLighting};
use crate::frame::{HDR_FORMAT, OVER, ParticleLayouts, ParticlePipelines, UNDER, fullscreen};
use crate::gpu::uniform_entry;
use crate::gpu::{AllocationError, Gpu, MemoryLedger, TargetWrites};
use crate::shaders;
use crate::sim::Particle;

/// The most batches `has` draws in: each is a lighting, an eye and a light pass (under a point
/// light, one light pass per cube face: eight), and the frame's timer holds
/// [`crate::gpu::MAX_TIMED_PASSES`], so that every pass of the largest budget is timed with 128
/// to spare. Above the 32 channels of the map techniques: a slice costs 256 bytes (its lighting
/// range), not a map channel, so a byte budget buys many.
pub const MAX_HAS_SLICES: u32 = (crate::gpu::MAX_TIMED_PASSES - 128) / 8;

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: "has",
    description: "half-angle slicing: S batches along the half-angle, eye and light interleaved",
    role: Role::Contender,
    budget_caption: |channels| format!("{channels} slices (batches)"),
    min_channels: 1,
    max_channels: MAX_HAS_SLICES,
    in_default_sweep: true,
    in_default_compare: true,
    build_reads_back: false,
    params: &[],
    order_independent: false,
    converges_with_budget: true,
    converges_from: 1,
    compresses_captured_lists: false,
    // R16F light buffer, RGBA16F eye buffer, the re-sorted instances (32 bytes each, capacity a
    // power of two from 1024), their lighting (64 bytes each), one 256-byte lighting range per
    // slice, a 16-byte uniform and the lighting order's 16-byte placeholder (has lights its
    // batches in their own order).
    memory: |c| {
        let capacity = c.particles.next_power_of_two().max(1024);
        MemoryUse {
            channels: c.channels().into(),
            bytes: 16
                + 16
                + c.texels() * 2
                + c.frame_pixels * 8
                + 96 * capacity
                + 256 * u64::from(c.channels()),
            transient_bytes: 0,
        }
    },
    lookup_shader: "shadow/has.wgsl",
    lookup_constants: super::no_lookup_constants,
    extra_shaders: || {
        vec![(
            "has.build".to_owned(),
            shaders::compose("shadow/has_build.wgsl", &[]),
        )]
    },
    create: |ctx, params| Ok(Box::new(HalfAngle::new(ctx, params)?)),
    uses_splat: false,
    uses_budget: true,
    owns_particle_pass: true,
    volume: super::VolumeSupport::Refuses(
        "it draws the particles in half-angle slices; a volume would need its slices of the grid (Kniss 2003), not written",
    ),
    shadows_particles: true,
};

/// Format of the light buffer (accumulated optical depth).
const LIGHT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R16Float;

/// Keep in sync with `HasParams` in shaders/shadow/has.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct HasParams {
    slices: u32,
    _pad: [u32; 3],
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![crate::mirror_layout!(
        HasParams,
        "shadow/has.wgsl",
        "HasParams",
        [slices]
    )]
}

pub use crate::render::sort::Slicing;

/// `count` sorted particles split into `slices` batches of (nearly) equal size; empty batches
/// are dropped when there are fewer particles than slices.
pub fn batches(count: u32, slices: u32) -> Vec<Range<u32>> {
    let (n, s) = (u64::from(count), u64::from(slices.max(1)));
    (0..s)
        .map(|k| (k * n / s) as u32..((k + 1) * n / s) as u32)
        .filter(|r| !r.is_empty())
        .collect()
}

/// The eye buffer at the frame's size.
struct EyeBuffer {
    size: (u32, u32),
    view: wgpu::TextureView,
    bind_group: wgpu::BindGroup,
}

pub struct HalfAngle {
    slices: u32,
    device: wgpu::Device,
    light_view: wgpu::TextureView,
    lookup_layout: wgpu::BindGroupLayout,
    lookup_bind_group: wgpu::BindGroup,
    light_pipeline: wgpu::RenderPipeline,
    eye_over: ParticlePipelines,
    eye_under: ParticlePipelines,
    composite_layout: wgpu::BindGroupLayout,
    composite_pipeline: wgpu::RenderPipeline,
    eye: Option<EyeBuffer>,
    instances: wgpu::Buffer,
    instance_capacity: u64,
    /// Lighting of each batch, computed just before the batch's eye pass.
    lighting: ParticleLighting,
    lights: LightBuffers,
    /// The lighting's group 3, a shadow history never prepared (so off: `has` lights its
    /// particles unfiltered, `crate::render::history`).
    history: crate::render::history::ShadowHistory,
    /// The instances the last frame lit, in its lighting buffer's order.
    lit_instances: Vec<ParticleInstance>,
    particle_layouts: ParticleLayouts,
    memory: MemoryLedger,
}

fn instance_buffer(
    memory: &mut MemoryLedger,
    device: &wgpu::Device,
    capacity: u64,
) -> Result<wgpu::Buffer, AllocationError> {
    memory.forget("has.instances");
    memory.buffer(
        device,
        &wgpu::BufferDescriptor {
            label: Some("has.instances"),
            size: capacity * std::mem::size_of::<ParticleInstance>() as u64,
            usage: wgpu::BufferUsages::VERTEX
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        },
    )
}

/// Lighting buffers for `capacity` particles in `slices` batches, created through `memory`.
fn light_buffers(
    memory: &mut MemoryLedger,
    device: &wgpu::Device,
    layouts: &ParticleLayouts,
    instances: &wgpu::Buffer,
    capacity: u64,
    slices: u32,
) -> Result<LightBuffers, AllocationError> {
    LightBuffers::new(
        device, memory, layouts, instances, capacity, slices, false, "has",
    )
}

impl HalfAngle {
    pub fn new(ctx: &TechniqueContext<'_>, params: &TechniqueParams) -> Result<Self, ShadowError> {
        let gpu = ctx.gpu;
        let device = &gpu.device;
        let mut memory = MemoryLedger::for_technique(&gpu.limits, params.memory_limit_bytes);
        let params_buffer = memory.buffer(
            device,
            &wgpu::BufferDescriptor {
                label: Some("has.params"),
                size: std::mem::size_of::<HasParams>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            },
        )?;
        gpu.queue.write_buffer(
            &params_buffer,
            0,
            bytemuck::bytes_of(&HasParams {
                slices: params.channels,
                _pad: [0; 3],
            }),
        );
        let light_view = map_texture(
            &mut memory,
            device,
            "has.light",
            LIGHT_FORMAT,
            params.resolution_px,
        )?;
        let lookup_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("has.lookup.layout"),
            entries: &[
                uniform_entry(0, LOOKUP_STAGES),
                sampler_entry(1, LOOKUP_STAGES),
                texture_entry(2, LOOKUP_STAGES),
            ],
        });
        let sampler = super::map_sampler(device, "has.sampler");
        let lookup_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("has.lookup.bind_group"),
            layout: &lookup_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: params_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(&sampler),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(&light_view),
                },
            ],
        });

        let module = shaders::module(
            device,
            "has.build",
            &shaders::compose("shadow/has_build.wgsl", &[]),
        );
        let light_pipeline = billboard_pipeline(
            device,
            "has.light",
            &module,
            "fs_light",
            &[Some(ctx.frame_layout)],
            &[LIGHT_FORMAT],
            ADDITIVE,
        );
        let eye = |label, blend| {
            ParticlePipelines::new(
                device,
                label,
                ctx.frame_layout,
                ctx.particle_layouts,
                ctx.depth_layout,
                blend,
            )
        };
        let (eye_over, eye_under) = (eye("has.eye.over", OVER), eye("has.eye.under", UNDER));
        let lighting = ParticleLighting::new(
            device,
            "has",
            ctx.frame_layout,
            &lookup_layout,
            &ENTRY.frame_imports(params).pairs(),
            ctx.particle_layouts,
        );

        let composite_layout = fullscreen::texture_layout(device, "has.composite.layout");
        let composite_pipeline = fullscreen::pipeline(
            device,
            "has.composite.pipeline",
            &module,
            ("vs_composite", "fs_composite"),
            &[Some(ctx.frame_layout), Some(&composite_layout)],
            wgpu::ColorTargetState {
                format: HDR_FORMAT,
                blend: Some(wgpu::BlendState {
                    color: OVER,
                    alpha: OVER,
                }),
                write_mask: wgpu::ColorWrites::ALL,
            },
        );
        let instance_capacity = 1024;
        let instances = instance_buffer(&mut memory, device, instance_capacity)?;
        let lights = light_buffers(
            &mut memory,
            device,
            ctx.particle_layouts,
            &instances,
            instance_capacity,
            params.channels,
        )?;
        Ok(Self {
            slices: params.channels,
            device: device.clone(),
            light_view,
            lookup_layout,
            lookup_bind_group,
            light_pipeline,
            eye_over,
            eye_under,
            composite_layout,
            composite_pipeline,
            eye: None,
            instances,
            instance_capacity,
            lighting,
            lights,
            // Its placeholder buffers (a few bytes, all zero: off) are no state of the
            // technique's, so not on its ledger.
            history: crate::render::history::ShadowHistory::new(
                device,
                &mut MemoryLedger::for_device(&gpu.limits),
                &ctx.particle_layouts.history,
            )?,
            lit_instances: Vec::new(),
            particle_layouts: ctx.particle_layouts.clone(),
            memory,
        })
    }

    /// Uploads the particles in the light's order along the half-angle (front to back from the
    /// light); returns the batches.
    fn upload_sorted(
        &mut self,
        gpu: &Gpu,
        instances: &[ParticleInstance],
    ) -> Result<Vec<Range<u32>>, AllocationError> {
        let needed = instances.len() as u64;
        if needed > self.instance_capacity {
            self.instance_capacity = needed.next_power_of_two();
            self.instances =
                instance_buffer(&mut self.memory, &self.device, self.instance_capacity)?;
            self.lights = light_buffers(
                &mut self.memory,
                &self.device,
                &self.particle_layouts,
                &self.instances,
                self.instance_capacity,
                self.slices,
            )?;
        }
        if needed > 0 {
            gpu.queue
                .write_buffer(&self.instances, 0, bytemuck::cast_slice(instances));
        }
        Ok(batches(instances.len() as u32, self.slices))
    }

    /// [`ParticlePass::light_batch`] into this face's light buffer and every other face's of a
    /// point light, each through its own light space.
    fn light_pass_all(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut crate::gpu::GpuTimer,
        frame_bind_group: &wgpu::BindGroup,
        others: &mut [OtherFace<'_>],
        batch: Option<Range<u32>>,
        clear: bool,
    ) {
        self.light_batch(
            encoder,
            timer,
            frame_bind_group,
            &self.instances,
            batch.clone(),
            clear,
        );
        for other in others {
            other
                .technique
                .particle_pass()
                .expect("every face holds the same technique")
                .light_batch(
                    encoder,
                    timer,
                    other.frame_bind_group,
                    &self.instances,
                    batch.clone(),
                    clear,
                );
        }
    }

    fn ensure_eye_buffer(&mut self, size: (u32, u32)) -> Result<(), AllocationError> {
        if self.eye.as_ref().is_some_and(|e| e.size == size) {
            return Ok(());
        }
        self.memory.forget("has.eye");
        let texture = self.memory.texture(
            &self.device,
            &crate::gpu::texture_2d_descriptor(
                "has.eye",
                size,
                HDR_FORMAT,
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            ),
        )?;
        let view = texture.create_view(&Default::default());
        let bind_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("has.composite.bind_group"),
            layout: &self.composite_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&view),
            }],
        });
        self.eye = Some(EyeBuffer {
            size,
            view,
            bind_group,
        });
        Ok(())
    }
}

impl ShadowTechnique for HalfAngle {
    fn name(&self) -> &'static str {
        ENTRY.name
    }
    fn channels_used(&self) -> u32 {
        self.slices
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

    /// Every particle into the light buffer, for the opaque pass.
    fn build<'a>(
        &'a mut self,
        _gpu: &'a Gpu,
        inputs: BuildInputs<'a>,
    ) -> GpuFuture<'a, Result<(), ShadowError>> {
        Box::pin(async move {
            let mut pass = inputs
                .encoder
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("has.light.all"),
                    color_attachments: &[cleared_attachment(
                        &self.light_view,
                        wgpu::Color::TRANSPARENT,
                    )],
                    depth_stencil_attachment: None,
                    timestamp_writes: inputs.timer.pass("shadow"),
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
            if inputs.particle_count > 0 {
                inputs.timer.count_fragments(
                    &mut pass,
                    "shadow",
                    TargetWrites::of(&[LIGHT_FORMAT]),
                    |pass| {
                        pass.set_pipeline(&self.light_pipeline);
                        pass.set_bind_group(0, inputs.frame_bind_group, &[]);
                        pass.set_vertex_buffer(0, inputs.particles.slice(..));
                        pass.draw(0..BILLBOARD_VERTICES, 0..inputs.particle_count);
                    },
                );
            }
            Ok(())
        })
    }

    fn particle_pass(&mut self) -> Option<&mut dyn ParticlePass> {
        Some(self)
    }

    fn probe_pass(&mut self) -> Option<&mut dyn ProbePass> {
        Some(self)
    }

    fn debug_maps(&self) -> Vec<DebugMap<'_>> {
        vec![DebugMap {
            view: &self.light_view,
            channels: vec!["light buffer (optical depth of every batch)".to_owned()],
            kind: MapKind::OpticalDepth,
        }]
    }
}

impl ParticlePass for HalfAngle {
    fn light_batch(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut crate::gpu::GpuTimer,
        frame_bind_group: &wgpu::BindGroup,
        instances: &wgpu::Buffer,
        batch: Option<Range<u32>>,
        clear: bool,
    ) {
        let load = if clear {
            wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT)
        } else {
            wgpu::LoadOp::Load
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("has.light"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &self.light_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load,
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: timer.pass("shadow"),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        if let Some(batch) = batch.filter(|b| !b.is_empty()) {
            timer.count_fragments(
                &mut pass,
                "shadow",
                TargetWrites::of(&[LIGHT_FORMAT]),
                |pass| {
                    pass.set_pipeline(&self.light_pipeline);
                    pass.set_bind_group(0, frame_bind_group, &[]);
                    pass.set_vertex_buffer(0, instances.slice(..));
                    pass.draw(0..BILLBOARD_VERTICES, batch);
                },
            );
        }
    }

    fn lit_particles<'a>(
        &'a self,
        gpu: &'a Gpu,
    ) -> GpuFuture<'a, Result<Vec<LitParticle>, crate::gpu::GpuError>> {
        Box::pin(async move {
            let lights = self.lights.read(gpu, self.lit_instances.len()).await?;
            Ok(LitParticle::of(&self.lit_instances, &lights))
        })
    }

    fn record(
        &mut self,
        gpu: &Gpu,
        inputs: ParticlePassInputs<'_>,
    ) -> Result<Option<f64>, ShadowError> {
        Self::check_point_light(
            inputs.particles,
            inputs.light,
            inputs.light_axis,
            inputs.other_faces.len(),
        )?;
        // The light's order: the frame's own when it sorted along this half-angle (reversed
        // when that is front to back for the eye), else a sort of its own (timed).
        let (slicing, instances, sort_ms) = match inputs.shared_order {
            Some(shared) => {
                let instances: Vec<ParticleInstance> = if shared.slicing.eye_front_to_back {
                    shared.eye_back_to_front.iter().rev().copied().collect()
                } else {
                    shared.eye_back_to_front.to_vec()
                };
                (shared.slicing, instances, None)
            }
            None => {
                let slicing = Slicing::new(inputs.camera.forward, inputs.light_axis);
                let sort_start = Instant::now();
                let order = slicing.order(inputs.particles);
                let sort_ms = sort_start.elapsed().as_secs_f64() * 1e3;
                let instances = order
                    .iter()
                    .map(|&i| ParticleInstance::from_particle(&inputs.particles[i as usize]))
                    .collect();
                (slicing, instances, Some(sort_ms))
            }
        };
        let batches = self.upload_sorted(gpu, &instances)?;
        self.lit_instances = instances;
        self.ensure_eye_buffer(inputs.hdr_size)?;
        let eye = self.eye.as_ref().expect("eye buffer was just made");
        let pipelines = if slicing.eye_front_to_back {
            &self.eye_under
        } else {
            &self.eye_over
        };
        let encoder = inputs.encoder;
        self.lighting
            .set_ranges(&gpu.queue, &self.lights, &batches, false);
        // The light buffers start empty; the eye buffer is cleared by the first eye pass.
        let mut others = inputs.other_faces;
        self.light_pass_all(
            encoder,
            inputs.timer,
            inputs.frame_bind_group,
            &mut others,
            None,
            true,
        );
        for (k, batch) in batches.iter().enumerate() {
            {
                // This batch's lighting, through the light buffer as the batches before left it.
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("has.lighting"),
                    timestamp_writes: inputs.timer.compute_pass("particles"),
                });
                let count = batch.end - batch.start;
                self.lighting.dispatch(
                    &mut pass,
                    inputs.frame_bind_group,
                    &self.lookup_bind_group,
                    &self.lights,
                    self.history.bind_group(),
                    k as u32,
                    count,
                );
                // A point light's other faces light the points in their faces.
                for other in &others {
                    self.lighting.dispatch(
                        &mut pass,
                        other.frame_bind_group,
                        other.technique.bind_group(),
                        &self.lights,
                        self.history.bind_group(),
                        k as u32,
                        count,
                    );
                }
            }
            {
                let load = if k == 0 {
                    wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT)
                } else {
                    wgpu::LoadOp::Load
                };
                let depth = (!inputs.spherical).then_some(wgpu::RenderPassDepthStencilAttachment {
                    view: inputs.depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Load,
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                });
                let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("has.eye"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &eye.view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load,
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    depth_stencil_attachment: depth,
                    timestamp_writes: inputs.timer.pass("particles"),
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
                if inputs.spherical {
                    pass.set_pipeline(&pipelines.spherical);
                    pass.set_bind_group(2, inputs.depth_bind_group, &[]);
                } else {
                    pass.set_pipeline(&pipelines.flat);
                }
                pass.set_bind_group(0, inputs.frame_bind_group, &[]);
                pass.set_bind_group(1, &self.lights.read_bind_group, &[]);
                pass.set_vertex_buffer(0, self.instances.slice(..));
                pass.draw(0..BILLBOARD_VERTICES, batch.clone());
            }
            self.light_pass_all(
                encoder,
                inputs.timer,
                inputs.frame_bind_group,
                &mut others,
                Some(batch.clone()),
                false,
            );
        }
        if batches.is_empty() {
            return Ok(sort_ms);
        }
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("has.composite"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: inputs.hdr_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Load,
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: inputs.timer.pass("particles"),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.composite_pipeline);
        pass.set_bind_group(0, inputs.frame_bind_group, &[]);
        pass.set_bind_group(1, &eye.bind_group, &[]);
        pass.draw(0..3, 0..1);
        Ok(sort_ms)
    }
}

impl HalfAngle {
    /// Under a point light (other faces given), the slicing's one light direction must have
    /// every particle in front of the light.
    fn check_point_light(
        particles: &[Particle],
        light: &super::LightSpace,
        light_axis: Vec3,
        faces: usize,
    ) -> Result<(), ShadowError> {
        if faces == 0 {
            return Ok(());
        }
        let behind = particles
            .iter()
            .filter(|p| (p.position - light.position).dot(light_axis) <= 0.0)
            .count();
        if behind > 0 {
            return Err(ShadowError::PointLightBehind {
                technique: ENTRY.name,
                behind: behind as u32,
                particles: particles.len() as u32,
            });
        }
        Ok(())
    }
}

impl ProbePass for HalfAngle {
    /// T at a point as the frame reads it. With owners (a frame's shaded points): a particle's
    /// lighting point through the light buffer as the batches before its particle's left it
    /// (the frame lights a batch's particles, all four points of each, before drawing the batch
    /// into the light buffer); an opaque point (the ground, the boxes: no owner) through the
    /// light buffer after every batch, which is what the frame's opaque pass reads (the build
    /// fills it with every particle), so that a box in front of smoke along the light is
    /// shadowed by the smoke behind it, as it is in the frame: the light buffer holds optical
    /// depth, not where along the ray it lies. Without owners, a point in the smoke as a
    /// particle there would be lit: through the batches wholly before it along the half-angle.
    fn probe<'a>(
        &'a mut self,
        gpu: &'a Gpu,
        inputs: ProbeInputs<'a>,
    ) -> GpuFuture<'a, anyhow::Result<Vec<f32>>> {
        Box::pin(async move {
            Self::check_point_light(
                inputs.particles,
                inputs.light,
                inputs.light_axis,
                inputs.other_faces.len(),
            )?;
            let mut encoder = inputs.encoder;
            let slicing = Slicing::new(inputs.camera_forward, inputs.light_axis);
            let order = slicing.order(inputs.particles);
            let instances: Vec<ParticleInstance> = order
                .iter()
                .map(|&i| ParticleInstance::from_particle(&inputs.particles[i as usize]))
                .collect();
            let batches = self.upload_sorted(gpu, &instances)?;
            let last_keys: Vec<f32> = batches
                .iter()
                .map(|b| {
                    inputs.particles[order[b.end as usize - 1] as usize]
                        .position
                        .dot(slicing.axis)
                })
                .collect();
            // Group the points by how many batches lie before them: a lighting point's particle's
            // batch, every batch for an opaque point, those wholly before a free point along the
            // axis. (Only a probe with owners needs each particle's batch.)
            let mut batch_of_particle = vec![0usize; inputs.owners.map_or(0, |_| order.len())];
            if !batch_of_particle.is_empty() {
                for (k, batch) in batches.iter().enumerate() {
                    for &i in &order[batch.start as usize..batch.end as usize] {
                        batch_of_particle[i as usize] = k;
                    }
                }
            }
            let mut groups: Vec<Vec<usize>> = vec![Vec::new(); batches.len() + 1];
            for (i, p) in inputs.points.iter().enumerate() {
                let group = match inputs.owners.map(|o| o[i]) {
                    Some(NO_OWNER) => batches.len(),
                    Some(owner) => batch_of_particle[owner as usize],
                    None => last_keys.partition_point(|&k| k < p.dot(slicing.axis)),
                };
                groups[group].push(i);
            }
            let mut timer = crate::gpu::GpuTimer::disabled();
            let mut others = inputs.other_faces;
            self.light_pass_all(
                &mut encoder,
                &mut timer,
                inputs.frame_bind_group,
                &mut others,
                None,
                true,
            );
            let mut pending: Vec<(usize, PendingProbe)> = Vec::new();
            for (k, group) in groups.iter().enumerate() {
                if !group.is_empty() {
                    let points: Vec<Vec3> = group.iter().map(|&i| inputs.points[i]).collect();
                    let lookups: Vec<(&wgpu::BindGroup, &wgpu::BindGroup)> =
                        std::iter::once((inputs.frame_bind_group, &self.lookup_bind_group))
                            .chain(
                                others
                                    .iter()
                                    .map(|o| (o.frame_bind_group, o.technique.bind_group())),
                            )
                            .collect();
                    pending.push((k, inputs.probe.record(gpu, &mut encoder, &lookups, &points)));
                }
                if let Some(batch) = batches.get(k) {
                    self.light_pass_all(
                        &mut encoder,
                        &mut timer,
                        inputs.frame_bind_group,
                        &mut others,
                        Some(batch.clone()),
                        false,
                    );
                }
            }
            gpu.queue.submit([encoder.finish()]);
            let mut out = vec![1.0; inputs.points.len()];
            for (k, probe) in pending {
                for (&i, t) in groups[k].iter().zip(probe.read(gpu).await?) {
                    out[i] = t;
                }
            }
            Ok(out)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn batches_cover_every_particle_once_in_order() {
        let b = batches(10, 3);
        assert_eq!(b, vec![0..3, 3..6, 6..10]);
        assert_eq!(batches(2, 5), vec![0..1, 1..2]);
        assert!(batches(0, 4).is_empty());
    }

    #[test]
    fn the_half_angle_inverts_the_view_when_the_camera_faces_the_light() {
        let light = Vec3::new(0.0, -1.0, 0.0);
        // Looking the way the light travels: half-angle between them, front to back.
        let s = Slicing::new(Vec3::new(1.0, 0.0, 0.0), light);
        assert!(s.eye_front_to_back);
        assert!((s.axis - Vec3::new(1.0, -1.0, 0.0).normalize()).length() < 1e-6);
        // Looking into the light: the inverted view is used, back to front.
        let s = Slicing::new(Vec3::new(0.6, 0.8, 0.0), light);
        assert!(!s.eye_front_to_back);
        assert!((s.axis - Vec3::new(-0.6, -1.8, 0.0).normalize()).length() < 1e-6);
        // Either way the axis has a positive component along the light: sorting by it is
        // front to back from the light.
        assert!(s.axis.dot(light) > 0.0);
    }
}
