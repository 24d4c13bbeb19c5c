//! The deep capture: every light-space particle fragment's chord segment stored per texel and
//! merged into the texel's sorted nodes (z, Ω(z)) of the piecewise-linear optical depth, the
//! uncompressed deep shadow map (Lokovic & Veach 2000; thesis 3.3.3.1) that `dsm` and `avsm`
//! compress (see `deep_nodes.rs`).
//!
//! Four passes, all in shaders/shadow/deep_capture.wgsl: a count raster pass over the
//! light-space billboards (atomic count per texel), a prefix scan into list offsets, a fill pass
//! writing each fragment's segment (z0, z1, optical depth) into its texel's list, and a resolve
//! compute pass sorting each list by (z0, z1, optical depth) — a total key, so the lists do not
//! depend on the order the fragments arrived in — and merging it into nodes. The count is read
//! back before the fill so the lists can grow to hold the frame (a CPU–GPU sync per build).
//! A compression pass then binds [`DeepCapture::layout`] as its group 1
//! (shaders/shadow/deep_capture_lists.wgsl declares it) and reads the sorted segments or nodes.
//!
//! (It was `exact`'s build until `exact` became the closed form per point.)
//! Every buffer here is **transient** for the technique that owns the capture: its lookup reads
//! only the compressed nodes. They are allocated and counted all the same, in the technique's
//! ledger, through [`MemoryLedger::buffer_transient`].

use bytemuck::{Pod, Zeroable};

use super::ShadowError;
use super::layered::{billboard_pipeline, cleared_attachment, draw_particles, uniform_entry};
use crate::gpu::{
    AllocationError, Gpu, GpuTimer, MemoryLedger, bind_entry, read_buffer, storage_descriptor,
    storage_entry,
};
use crate::shaders;

/// Keep in sync with `CaptureParams` in shaders/shadow/deep_capture_lists.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct CaptureParams {
    resolution: u32,
    capacity: u32,
    _pad: [u32; 2],
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![crate::mirror_layout!(
        CaptureParams,
        "shadow/deep_capture_lists.wgsl",
        "CaptureParams",
        [resolution, capacity]
    )]
}

/// Bytes per stored segment (z0, z1, optical depth) and per segment's share of the resolved
/// nodes (2 per segment, (z, Ω) each).
pub const SEGMENT_BYTES: u64 = 12;
pub const NODE_BYTES_PER_SEGMENT: u64 = 16;
/// Segments the lists hold before the first frame asks for more.
const INITIAL_CAPACITY: u32 = 1 << 16;
/// Format of the dummy colour target the list passes rasterise into (nothing is written).
const DUMMY_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R8Unorm;

/// The bytes a capture at `resolution_px` with lists for `segment_capacity` segments allocates:
/// a 16-byte uniform, counts, offsets (+1 for the total), row sums (+1), an R8 raster target,
/// and 12 + 16 bytes of segment and node storage per segment.
pub fn bytes(resolution_px: u32, segment_capacity: u64) -> u64 {
    let texels = u64::from(resolution_px) * u64::from(resolution_px);
    16 + texels * 4
        + (texels + 1) * 4
        + (u64::from(resolution_px) + 1) * 4
        + texels
        + segment_capacity * (SEGMENT_BYTES + NODE_BYTES_PER_SEGMENT)
}

/// Buffers sized by the segment capacity, and the bind group over all the capture's buffers.
struct Lists {
    capacity: u32,
    /// Held with the bind group that uses them (the ledger records their sizes).
    _segments: wgpu::Buffer,
    _nodes: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

/// The capture's pipelines and buffers (see the module doc).
pub struct DeepCapture {
    /// The owning technique's name, the prefix of every label.
    name: &'static str,
    resolution: u32,
    params_buffer: wgpu::Buffer,
    counts: wgpu::Buffer,
    offsets: wgpu::Buffer,
    row_sums: wgpu::Buffer,
    dummy_target: wgpu::TextureView,
    layout: wgpu::BindGroupLayout,
    count_pipeline: wgpu::RenderPipeline,
    fill_pipeline: wgpu::RenderPipeline,
    scan_rows: wgpu::ComputePipeline,
    scan_total: wgpu::ComputePipeline,
    scan_write: wgpu::ComputePipeline,
    resolve: wgpu::ComputePipeline,
    lists: Lists,
    /// Segments stored last frame.
    last_segment_count: u32,
}

impl DeepCapture {
    /// Builds the capture for technique `name` at `resolution_px`, recording its buffers in
    /// `memory` as transient. `frame_layout` is group 0 of every pass.
    pub fn new(
        gpu: &Gpu,
        frame_layout: &wgpu::BindGroupLayout,
        name: &'static str,
        resolution_px: u32,
        memory: &mut MemoryLedger,
    ) -> Result<Self, ShadowError> {
        let device = &gpu.device;
        let res = resolution_px;
        let texels = u64::from(res) * u64::from(res);
        let label = |what: &str| format!("{name}.capture.{what}");
        let params_buffer = memory.buffer_transient(
            device,
            &wgpu::BufferDescriptor {
                label: Some(&label("params")),
                size: std::mem::size_of::<CaptureParams>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            },
        )?;
        let mut storage = |what: &str, size: u64| {
            memory.buffer_transient(device, &storage_descriptor(&label(what), size))
        };
        let counts = storage("counts", texels * 4)?;
        let offsets = storage("offsets", (texels + 1) * 4)?;
        let row_sums = storage("row_sums", (u64::from(res) + 1) * 4)?;
        let dummy_target = memory
            .texture_transient(
                device,
                &wgpu::TextureDescriptor {
                    label: Some(&label("raster_target")),
                    size: wgpu::Extent3d {
                        width: res,
                        height: res,
                        depth_or_array_layers: 1,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format: DUMMY_FORMAT,
                    usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                    view_formats: &[],
                },
            )?
            .create_view(&wgpu::TextureViewDescriptor::default());

        let raster_and_compute = wgpu::ShaderStages::FRAGMENT | wgpu::ShaderStages::COMPUTE;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(&label("layout")),
            entries: &[
                uniform_entry(0, wgpu::ShaderStages::VERTEX | raster_and_compute),
                storage_entry(1, raster_and_compute, false),
                storage_entry(2, raster_and_compute, false),
                storage_entry(3, raster_and_compute, false),
                storage_entry(4, wgpu::ShaderStages::COMPUTE, false),
                storage_entry(5, wgpu::ShaderStages::COMPUTE, false),
            ],
        });
        let module = shaders::module(
            device,
            &label("build"),
            &shaders::compose("shadow/deep_capture.wgsl", &[]),
        );
        let groups = [Some(frame_layout), Some(&layout)];
        let raster = |what: &str, entry: &str| {
            billboard_pipeline(
                device,
                &label(what),
                &module,
                entry,
                &groups,
                &[DUMMY_FORMAT],
                super::layered::ADDITIVE,
            )
        };
        let count_pipeline = raster("count", "fs_count");
        let fill_pipeline = raster("fill", "fs_fill");
        let compute_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(&label("compute.pipeline_layout")),
            bind_group_layouts: &groups,
            immediate_size: 0,
        });
        let compute = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(&label(entry)),
                layout: Some(&compute_layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let lists = Lists::new(
            device,
            memory,
            name,
            &layout,
            [&params_buffer, &counts, &offsets, &row_sums],
            INITIAL_CAPACITY,
        )?;
        let capture = Self {
            name,
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
            layout,
            count_pipeline,
            fill_pipeline,
            lists,
            last_segment_count: 0,
        };
        capture.write_params(&gpu.queue);
        Ok(capture)
    }

    /// Layout of the capture's group (group 1 of its passes and of a compression pass).
    pub fn layout(&self) -> &wgpu::BindGroupLayout {
        &self.layout
    }

    /// This frame's group over the lists (replaced when they grow: take it after
    /// [`DeepCapture::record`]).
    pub fn bind_group(&self) -> &wgpu::BindGroup {
        &self.lists.bind_group
    }

    /// Segments stored last frame.
    pub fn segments(&self) -> u32 {
        self.last_segment_count
    }

    /// Segments the lists hold.
    pub fn capacity(&self) -> u32 {
        self.lists.capacity
    }

    fn write_params(&self, queue: &wgpu::Queue) {
        queue.write_buffer(
            &self.params_buffer,
            0,
            bytemuck::bytes_of(&CaptureParams {
                resolution: self.resolution,
                capacity: self.lists.capacity,
                _pad: [0; 2],
            }),
        );
    }

    /// Captures this frame: counts and scans in a submission of its own, reads the total back
    /// and grows the lists (recorded in `memory`) when they cannot hold it, then records the
    /// fill and the resolve into `encoder`. Afterwards [`DeepCapture::bind_group`] holds sorted
    /// segments and their nodes for every texel.
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &mut self,
        gpu: &Gpu,
        memory: &mut MemoryLedger,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut GpuTimer,
        frame_bind_group: &wgpu::BindGroup,
        particles: &wgpu::Buffer,
        particle_count: u32,
    ) -> Result<(), ShadowError> {
        let device = &gpu.device;
        let mut count_encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some(&format!("{}.capture.count.encoder", self.name)),
        });
        count_encoder.clear_buffer(&self.counts, 0, None);
        self.raster(
            &mut count_encoder,
            timer,
            false,
            frame_bind_group,
            particles,
            particle_count,
        );
        // Each scan step in a pass of its own, so that each sees the previous one's writes
        // whatever the backend's barriers between dispatches of one pass.
        let row_groups = self.resolution.div_ceil(64);
        for (pipeline, groups) in [
            (&self.scan_rows, row_groups),
            (&self.scan_total, 1),
            (&self.scan_write, row_groups),
        ] {
            let mut pass = count_encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(&format!("{}.capture.scan", self.name)),
                timestamp_writes: timer.compute_pass("shadow"),
            });
            pass.set_bind_group(0, frame_bind_group, &[]);
            pass.set_bind_group(1, &self.lists.bind_group, &[]);
            pass.set_pipeline(pipeline);
            pass.dispatch_workgroups(groups, 1, 1);
        }
        gpu.queue.submit([count_encoder.finish()]);
        let texels = u64::from(self.resolution) * u64::from(self.resolution);
        let total = read_buffer(gpu, &self.offsets, texels * 4, 4)
            .map(|bytes| u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]))
            .map_err(|err| ShadowError::Gpu(err.to_string()))?;
        if total > self.lists.capacity {
            self.grow(gpu, memory, total)?;
        }
        self.last_segment_count = total;

        // Fill (counts, cleared, become the cursors), then sort and resolve.
        encoder.clear_buffer(&self.counts, 0, None);
        self.raster(
            encoder,
            timer,
            true,
            frame_bind_group,
            particles,
            particle_count,
        );
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(&format!("{}.capture.resolve", self.name)),
            timestamp_writes: timer.compute_pass("shadow"),
        });
        pass.set_pipeline(&self.resolve);
        pass.set_bind_group(0, frame_bind_group, &[]);
        pass.set_bind_group(1, &self.lists.bind_group, &[]);
        let groups = self.resolution.div_ceil(8);
        pass.dispatch_workgroups(groups, groups, 1);
        Ok(())
    }

    /// Reallocates the lists for at least `total` segments, with headroom so that a slowly
    /// changing scene does not reallocate every frame.
    fn grow(
        &mut self,
        gpu: &Gpu,
        memory: &mut MemoryLedger,
        total: u32,
    ) -> Result<(), ShadowError> {
        let limit = gpu.limits.max_storage_buffer_binding_size;
        let fits = |segments: u64| segments * NODE_BYTES_PER_SEGMENT <= limit;
        if !fits(u64::from(total)) {
            return Err(ShadowError::CaptureTooLarge {
                technique: self.name,
                resolution_px: self.resolution,
                segments: u64::from(total),
                bytes: u64::from(total) * (SEGMENT_BYTES + NODE_BYTES_PER_SEGMENT),
                limit,
            });
        }
        let mut capacity = total.saturating_add(total / 4).max(INITIAL_CAPACITY);
        if !fits(u64::from(capacity)) {
            capacity = total;
        }
        // The ledger forgets the old lists before the new ones are checked against the budget.
        let fixed = [
            &self.params_buffer,
            &self.counts,
            &self.offsets,
            &self.row_sums,
        ];
        self.lists = Lists::new(
            &gpu.device,
            memory,
            self.name,
            &self.layout,
            fixed,
            capacity,
        )?;
        self.write_params(&gpu.queue);
        Ok(())
    }

    /// Records one raster pass of the light-space particles: the count pass, or with `fill` the
    /// fill pass.
    fn raster(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut GpuTimer,
        fill: bool,
        frame_bind_group: &wgpu::BindGroup,
        particles: &wgpu::Buffer,
        particle_count: u32,
    ) {
        let (what, pipeline) = if fill {
            ("fill", &self.fill_pipeline)
        } else {
            ("count", &self.count_pipeline)
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(&format!("{}.capture.{what}", self.name)),
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
            &self.lists.bind_group,
            particles.slice(..),
            particle_count,
        );
    }
}

impl Lists {
    /// Allocates (transient) list buffers for `capacity` segments and the bind group over them
    /// and the fixed buffers `[params, counts, offsets, row_sums]`.
    fn new(
        device: &wgpu::Device,
        memory: &mut MemoryLedger,
        name: &str,
        layout: &wgpu::BindGroupLayout,
        fixed: [&wgpu::Buffer; 4],
        capacity: u32,
    ) -> Result<Self, AllocationError> {
        let [params, counts, offsets, row_sums] = fixed;
        let (segments_label, nodes_label) = (
            format!("{name}.capture.segments"),
            format!("{name}.capture.nodes"),
        );
        memory.forget(&segments_label);
        memory.forget(&nodes_label);
        let segments = memory.buffer_transient(
            device,
            &storage_descriptor(&segments_label, u64::from(capacity) * SEGMENT_BYTES),
        )?;
        let nodes = memory.buffer_transient(
            device,
            &storage_descriptor(&nodes_label, u64::from(capacity) * NODE_BYTES_PER_SEGMENT),
        )?;
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&format!("{name}.capture.bind_group")),
            layout,
            entries: &[
                bind_entry(0, params),
                bind_entry(1, counts),
                bind_entry(2, offsets),
                bind_entry(3, &segments),
                bind_entry(4, &nodes),
                bind_entry(5, row_sums),
            ],
        });
        Ok(Self {
            capacity,
            _segments: segments,
            _nodes: nodes,
            bind_group,
        })
    }
}
