//! `exact`: the reference every technique is measured against, a deep shadow map with unbounded
//! memory (Lokovic & Veach 2000; thesis 3.3.3.1).
//!
//! In light space every particle fragment (one light ray through one particle sphere) becomes a
//! segment along its ray: the chord [z_c − w, z_c + w], w = sqrt(r² − d²), carrying optical depth
//! τ(1 − d/r)·2w spread uniformly along it — the density model the spherical billboards use. All
//! segments of a texel are stored (count, prefix sum, fill into storage buffers), sorted in a
//! compute pass and turned into the texel's piecewise-linear optical depth Ω(z), so the lookup
//! evaluates T(z) = exp(−Ω(z)) exactly, partial overlap with a segment included.
//!
//! Memory grows with the number of fragments: the list buffers are sized each frame from a count
//! pass that is submitted and read back first (a CPU–GPU sync: this is the reference, not a
//! contender), and the ledger reports what is allocated.
//!
//! What it still approximates: the light's spatial sampling (one ray per texel, the four rays
//! around a point blended bilinearly, as every technique here does), float32 depths, and, like
//! the renderer, the particle density model itself (constant extinction along each chord).
//! At a high shadow resolution it is the ground truth for that model.
//!
//! The budget does not apply: `channels_used` reports 0 and any budget is accepted.

use bytemuck::{Pod, Zeroable};

use super::layered::{billboard_pipeline, cleared_attachment, draw_particles, uniform_entry};
use super::{
    BuildInputs, LOOKUP_STAGES, MemoryUse, Role, ShadowError, ShadowTechnique, TechniqueContext,
    TechniqueEntry, TechniqueParams,
};
use crate::gpu::{AllocationError, Gpu, MemoryLedger, read_buffer};
use crate::shaders;

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: "exact",
    description: "reference: per-texel sorted segment lists (deep shadow map), exact T(z)",
    role: Role::Reference,
    budget_caption: |_| "no budget (exact lists)".to_owned(),
    min_channels: 1,
    in_default_sweep: false,
    in_default_compare: false,
    build_reads_back: true,
    params: &[],
    order_independent: true,
    converges_with_budget: false,
    compresses_captured_lists: false,
    // Counts, offsets (+1 for the total), row sums (+1), an R8 raster target, a 16-byte uniform
    // and 12 + 16 bytes of segment and node storage per segment of capacity.
    memory: |c| {
        let texels = c.texels();
        MemoryUse {
            channels: 0,
            bytes: 16
                + texels * 4
                + (texels + 1) * 4
                + (u64::from(c.resolution_px) + 1) * 4
                + texels
                + c.counter("segment_capacity") * (SEGMENT_BYTES + NODE_BYTES_PER_SEGMENT),
            transient_bytes: 0,
        }
    },
    lookup_shader: "shadow/exact.wgsl",
    extra_shaders: || {
        vec![(
            "exact.build".to_owned(),
            shaders::compose("shadow/exact_build.wgsl", &[]),
        )]
    },
    create: |ctx, params| Ok(Box::new(Exact::new(ctx, params)?)),
    uses_splat: false,
    uses_budget: false,
};

/// Keep in sync with `ExactParams` in shaders/shadow/exact.wgsl and exact_build.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct ExactParams {
    resolution: u32,
    capacity: u32,
    _pad: [u32; 2],
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![crate::mirror_layout!(
        ExactParams,
        "shadow/exact.wgsl",
        "ExactParams",
        [resolution, capacity]
    )]
}

/// Bytes per stored segment (z0, z1, optical depth) and per texel's share of nodes (2 per
/// segment, (z, Ω) each).
const SEGMENT_BYTES: u64 = 12;
const NODE_BYTES_PER_SEGMENT: u64 = 16;
/// Format of the dummy colour target the list passes rasterise into (nothing is written).
const DUMMY_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R8Unorm;

/// Buffers sized by the segment capacity, and the bind groups that reference them.
struct Lists {
    capacity: u32,
    /// Held with the bind groups that use them (the ledger records their sizes).
    _segments: wgpu::Buffer,
    _nodes: wgpu::Buffer,
    build_bind_group: wgpu::BindGroup,
    lookup_bind_group: wgpu::BindGroup,
}

pub struct Exact {
    resolution: u32,
    params_buffer: wgpu::Buffer,
    counts: wgpu::Buffer,
    offsets: wgpu::Buffer,
    row_sums: wgpu::Buffer,
    dummy_target: wgpu::TextureView,
    build_layout: wgpu::BindGroupLayout,
    count_pipeline: wgpu::RenderPipeline,
    fill_pipeline: wgpu::RenderPipeline,
    scan_rows: wgpu::ComputePipeline,
    scan_total: wgpu::ComputePipeline,
    scan_write: wgpu::ComputePipeline,
    resolve: wgpu::ComputePipeline,
    lookup_layout: wgpu::BindGroupLayout,
    lists: Lists,
    memory: MemoryLedger,
    /// Segments stored last frame.
    last_segment_count: u32,
}

fn storage_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    read_only: bool,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

fn storage_buffer(
    memory: &mut MemoryLedger,
    device: &wgpu::Device,
    label: &str,
    size: u64,
) -> Result<wgpu::Buffer, AllocationError> {
    memory.buffer(
        device,
        &wgpu::BufferDescriptor {
            label: Some(label),
            size: size.max(16),
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        },
    )
}

impl Exact {
    pub fn new(ctx: &TechniqueContext<'_>, params: &TechniqueParams) -> Result<Self, ShadowError> {
        let device = &ctx.gpu.device;
        let res = params.resolution_px;
        let texels = u64::from(res) * u64::from(res);
        let mut memory = MemoryLedger::for_device(&ctx.gpu.limits);
        let params_buffer = memory.buffer(
            device,
            &wgpu::BufferDescriptor {
                label: Some("exact.params"),
                size: std::mem::size_of::<ExactParams>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            },
        )?;
        let counts = storage_buffer(&mut memory, device, "exact.counts", texels * 4)?;
        let offsets = storage_buffer(&mut memory, device, "exact.offsets", (texels + 1) * 4)?;
        let row_sums = storage_buffer(
            &mut memory,
            device,
            "exact.row_sums",
            (u64::from(res) + 1) * 4,
        )?;
        let dummy_target = super::layered::map_texture(
            &mut memory,
            device,
            "exact.raster_target",
            DUMMY_FORMAT,
            res,
        )?;

        let build_stages = wgpu::ShaderStages::VERTEX_FRAGMENT | wgpu::ShaderStages::COMPUTE;
        let build_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("exact.build.layout"),
            entries: &[
                uniform_entry(0, build_stages),
                storage_entry(
                    1,
                    wgpu::ShaderStages::FRAGMENT | wgpu::ShaderStages::COMPUTE,
                    false,
                ),
                storage_entry(
                    2,
                    wgpu::ShaderStages::FRAGMENT | wgpu::ShaderStages::COMPUTE,
                    false,
                ),
                storage_entry(
                    3,
                    wgpu::ShaderStages::FRAGMENT | wgpu::ShaderStages::COMPUTE,
                    false,
                ),
                storage_entry(4, wgpu::ShaderStages::COMPUTE, false),
                storage_entry(5, wgpu::ShaderStages::COMPUTE, false),
            ],
        });
        let lookup_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("exact.lookup.layout"),
            entries: &[
                uniform_entry(0, LOOKUP_STAGES),
                storage_entry(1, LOOKUP_STAGES, true),
                storage_entry(2, LOOKUP_STAGES, true),
            ],
        });
        let module = shaders::module(
            device,
            "exact.build",
            &shaders::compose("shadow/exact_build.wgsl", &[]),
        );
        let groups = [Some(ctx.frame_layout), Some(&build_layout)];
        let raster = |label: &str, entry: &str| {
            billboard_pipeline(
                device,
                label,
                &module,
                entry,
                &groups,
                &[DUMMY_FORMAT],
                super::layered::ADDITIVE,
            )
        };
        let count_pipeline = raster("exact.build.count", "fs_count");
        let fill_pipeline = raster("exact.build.fill", "fs_fill");
        let compute_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("exact.compute.pipeline_layout"),
            bind_group_layouts: &groups,
            immediate_size: 0,
        });
        let compute = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(&format!("exact.{entry}")),
                layout: Some(&compute_layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let lists = Lists::new(
            device,
            &mut memory,
            &build_layout,
            &lookup_layout,
            [&params_buffer, &counts, &offsets, &row_sums],
            1 << 16,
        )?;
        let exact = Self {
            resolution: res,
            scan_rows: compute("scan_rows"),
            scan_total: compute("scan_total"),
            scan_write: compute("scan_write"),
            resolve: compute("resolve"),
            params_buffer,
            counts,
            offsets,
            row_sums,
            dummy_target,
            build_layout,
            count_pipeline,
            fill_pipeline,
            lookup_layout,
            lists,
            memory,
            last_segment_count: 0,
        };
        exact.write_params(&ctx.gpu.queue);
        Ok(exact)
    }

    fn write_params(&self, queue: &wgpu::Queue) {
        queue.write_buffer(
            &self.params_buffer,
            0,
            bytemuck::bytes_of(&ExactParams {
                resolution: self.resolution,
                capacity: self.lists.capacity,
                _pad: [0; 2],
            }),
        );
    }

    /// Records the count raster pass and the prefix sum.
    fn record_count_and_scan(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut crate::gpu::GpuTimer,
        frame_bind_group: &wgpu::BindGroup,
        particles: &wgpu::Buffer,
        particle_count: u32,
    ) {
        encoder.clear_buffer(&self.counts, 0, None);
        self.raster(
            encoder,
            timer,
            false,
            frame_bind_group,
            particles,
            particle_count,
        );
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("exact.scan"),
            timestamp_writes: timer.compute_pass("shadow"),
        });
        pass.set_bind_group(0, frame_bind_group, &[]);
        pass.set_bind_group(1, &self.lists.build_bind_group, &[]);
        let row_groups = self.resolution.div_ceil(64);
        pass.set_pipeline(&self.scan_rows);
        pass.dispatch_workgroups(row_groups, 1, 1);
        pass.set_pipeline(&self.scan_total);
        pass.dispatch_workgroups(1, 1, 1);
        pass.set_pipeline(&self.scan_write);
        pass.dispatch_workgroups(row_groups, 1, 1);
    }

    /// Records one raster pass of the light-space particles: the count pass, or with `fill` the
    /// fill pass.
    fn raster(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut crate::gpu::GpuTimer,
        fill: bool,
        frame_bind_group: &wgpu::BindGroup,
        particles: &wgpu::Buffer,
        particle_count: u32,
    ) {
        let (label, pipeline) = if fill {
            ("exact.fill", &self.fill_pipeline)
        } else {
            ("exact.count", &self.count_pipeline)
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(label),
            color_attachments: &[cleared_attachment(
                &self.dummy_target,
                wgpu::Color::TRANSPARENT,
            )],
            depth_stencil_attachment: None,
            timestamp_writes: timer.pass("shadow"),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        draw_particles(
            &mut pass,
            pipeline,
            frame_bind_group,
            &self.lists.build_bind_group,
            particles.slice(..),
            particle_count,
        );
    }
}

impl Lists {
    /// Allocates list buffers for `capacity` segments and the bind groups over them and the
    /// fixed buffers `[params, counts, offsets, row_sums]`.
    fn new(
        device: &wgpu::Device,
        memory: &mut MemoryLedger,
        build_layout: &wgpu::BindGroupLayout,
        lookup_layout: &wgpu::BindGroupLayout,
        fixed: [&wgpu::Buffer; 4],
        capacity: u32,
    ) -> Result<Self, AllocationError> {
        let [params, counts, offsets, row_sums] = fixed;
        memory.forget("exact.segments");
        memory.forget("exact.nodes");
        let segments = storage_buffer(
            memory,
            device,
            "exact.segments",
            u64::from(capacity) * SEGMENT_BYTES,
        )?;
        let nodes = storage_buffer(
            memory,
            device,
            "exact.nodes",
            u64::from(capacity) * NODE_BYTES_PER_SEGMENT,
        )?;
        fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry {
                binding,
                resource: buffer.as_entire_binding(),
            }
        }
        let build_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("exact.build.bind_group"),
            layout: build_layout,
            entries: &[
                entry(0, params),
                entry(1, counts),
                entry(2, offsets),
                entry(3, &segments),
                entry(4, &nodes),
                entry(5, row_sums),
            ],
        });
        let lookup_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("exact.lookup.bind_group"),
            layout: lookup_layout,
            entries: &[entry(0, params), entry(1, offsets), entry(2, &nodes)],
        });
        Ok(Self {
            capacity,
            _segments: segments,
            _nodes: nodes,
            build_bind_group,
            lookup_bind_group,
        })
    }
}

impl ShadowTechnique for Exact {
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
        &self.lookup_layout
    }
    fn bind_group(&self) -> &wgpu::BindGroup {
        &self.lists.lookup_bind_group
    }

    /// `segments`: stored last frame (light-space particle fragments); `segment_capacity`: what
    /// the list buffers hold.
    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![
            ("segments", u64::from(self.last_segment_count)),
            ("segment_capacity", u64::from(self.lists.capacity)),
        ]
    }

    fn build(&mut self, gpu: &Gpu, inputs: BuildInputs<'_>) -> Result<(), ShadowError> {
        let device = &gpu.device;
        let particle_count = inputs.particle_count;
        let particles = inputs.particles;

        // How many segments this frame has: count and scan in a submission of their own, read
        // the total back, and grow the lists before filling them.
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("exact.count.encoder"),
        });
        self.record_count_and_scan(
            &mut encoder,
            inputs.timer,
            inputs.frame_bind_group,
            particles,
            particle_count,
        );
        gpu.queue.submit([encoder.finish()]);
        let texels = u64::from(self.resolution) * u64::from(self.resolution);
        let total = read_buffer(gpu, &self.offsets, texels * 4, 4)
            .map(|bytes| u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]))
            .map_err(|err| ShadowError::Gpu(err.to_string()))?;
        if total > self.lists.capacity {
            let limit = gpu.limits.max_storage_buffer_binding_size;
            let fits = |segments: u64| segments * NODE_BYTES_PER_SEGMENT <= limit;
            if !fits(u64::from(total)) {
                return Err(ShadowError::ListsTooLarge {
                    resolution_px: self.resolution,
                    segments: u64::from(total),
                    bytes: u64::from(total) * (SEGMENT_BYTES + NODE_BYTES_PER_SEGMENT),
                    limit,
                });
            }
            // Headroom so that a slowly changing scene does not reallocate every frame.
            let mut capacity = total.saturating_add(total / 4).max(1 << 16);
            if !fits(u64::from(capacity)) {
                capacity = total;
            }
            self.lists = Lists::new(
                device,
                &mut self.memory,
                &self.build_layout,
                &self.lookup_layout,
                [
                    &self.params_buffer,
                    &self.counts,
                    &self.offsets,
                    &self.row_sums,
                ],
                capacity,
            )?;
            self.write_params(&gpu.queue);
        }
        self.last_segment_count = total;

        // Fill (counts, cleared, become the cursors), then sort and resolve.
        let encoder = &mut *inputs.encoder;
        encoder.clear_buffer(&self.counts, 0, None);
        self.raster(
            encoder,
            inputs.timer,
            true,
            inputs.frame_bind_group,
            particles,
            particle_count,
        );
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("exact.resolve"),
            timestamp_writes: inputs.timer.compute_pass("shadow"),
        });
        pass.set_pipeline(&self.resolve);
        pass.set_bind_group(0, inputs.frame_bind_group, &[]);
        pass.set_bind_group(1, &self.lists.build_bind_group, &[]);
        let groups = self.resolution.div_ceil(8);
        pass.dispatch_workgroups(groups, groups, 1);
        Ok(())
    }
}
