//! Compressed deep shadow maps: the machinery `dsm` and `avsm` share. A [`DeepCapture`] stores
//! every texel's segments and their optical depth nodes (transient), then the technique's
//! compression pass (its `compress` entry point) reduces each texel to N = floor(B / 2) nodes
//! (depth in metres, value) of 32-bit floats in one storage buffer, texel i's at
//! [i·N, (i + 1)·N), a texel with fewer repeating its last. That buffer and a 16-byte uniform
//! are all the lookup reads (shaders/shadow/deep_nodes.wgsl evaluates a texel; each technique's
//! lookup blends four).
//!
//! A technique of this kind is a [`DeepNodesSpec`]: its compression shader, and optionally a
//! few words of statistics the compression accumulates (atomics) and the build reads back for
//! [`ShadowTechnique::counters`] (`dsm`'s error tolerances), and the rounds its compression
//! takes (`deep_capture`'s loop budget). Adding one: a spec and an entry in
//! `src/shadow/<name>.rs`, a lookup shader that imports `shadow/deep_nodes.wgsl`, a build shader
//! that imports `shadow/deep_capture_lists.wgsl` and `shadow/deep_params.wgsl`, declares group 2
//! as [`DeepNodes::new`] lays it out, covers the texels of the band's 8x8 tiles (one workgroup
//! a tile: `band_texel` gives an 8x8 workgroup's invocation its texel, `tile_texel` a tile's
//! texel by place, as `dsm`'s two texels an invocation take them), and does round
//! `pass_round.index`'s share of its work (group 3).

use super::GpuFuture;
use bytemuck::{Pod, Zeroable};

use super::deep_capture::{BandPass, DeepCapture, Resolve};
use super::{
    BuildInputs, LOOKUP_STAGES, MemoryCase, MemoryUse, ShadowError, ShadowTechnique,
    TechniqueContext, TechniqueParams,
};
use crate::gpu::uniform_entry;
use crate::gpu::{Gpu, MemoryLedger, read_buffer};
use crate::gpu::{bind_entry, storage_descriptor, storage_entry};
use crate::shaders;

/// Keep in sync with `DeepParams` in shaders/shadow/deep_params.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct DeepParams {
    resolution: u32,
    nodes_per_texel: u32,
    bisection_steps: u32,
    _pad: u32,
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![crate::mirror_layout!(
        DeepParams,
        "shadow/deep_params.wgsl",
        "DeepParams",
        [resolution, nodes_per_texel, bisection_steps]
    )]
}

/// Bytes of one node: depth and value, two 32-bit floats.
pub const NODE_BYTES: u64 = 8;

/// Nodes per texel under a budget of `channels`: two channels (depth, value) per node.
pub fn nodes_per_texel(channels: u32) -> u32 {
    channels / 2
}

/// What one compressed deep shadow map technique is.
pub struct DeepNodesSpec {
    pub name: &'static str,
    /// Its compression shader (entry point `compress`), under `shaders/`.
    pub build_shader: &'static str,
    /// The grain of a per-texel search the compression runs (`dsm`'s tolerance, searched to
    /// Ω_max / 2^steps: as fine as that many steps of bisection over [0, Ω_max]); 0 when it
    /// runs none.
    pub bisection_steps: u32,
    /// Words of statistics the compression accumulates in group 2, binding 2 (cleared before
    /// each build, read back after it: a second CPU–GPU sync); 0 for none, and no binding.
    pub stats_words: u32,
    /// The counters reported from those words (called with all `stats_words` of them).
    pub stats_counters: fn(&[u32]) -> Vec<(&'static str, u64)>,
    /// Rounds the compression takes over lists of at most `max_list` segments when a dispatch
    /// may loop `loop_budget` times (see `deep_capture`'s module doc; the shader splits its work
    /// by the same arithmetic).
    pub rounds: fn(max_list: u32, loop_budget: u32, params: &TechniqueParams) -> u32,
    /// What the capture's resolve leaves for the compression under these parameters.
    pub resolve: fn(&TechniqueParams) -> Resolve,
    /// The compression's compile-time constants for N nodes per texel under `params`, composed
    /// before its shader (`const NAME: u32 = V;`, which its `#unroll` blocks may be bounded by).
    pub compress_constants:
        fn(nodes_per_texel: u32, params: &TechniqueParams) -> Vec<(&'static str, u32)>,
    /// The parameter sets whose compression shaders differ at a budget (the naga test composes
    /// each).
    pub shader_variants: fn(channels: u32) -> Vec<TechniqueParams>,
}

impl DeepNodesSpec {
    /// The capture's and the compression's shaders, composed, for the naga test: the
    /// compression at the fewest nodes per texel a budget gives (2, at 4 channels) and the most.
    pub fn build_shaders(&self) -> Vec<(String, String)> {
        let mut out = vec![(
            format!("{}.capture", self.name),
            shaders::compose("shadow/deep_capture.wgsl", &[]),
        )];
        for channels in [4, super::MAX_CHANNELS] {
            let n = nodes_per_texel(channels);
            for (v, params) in (self.shader_variants)(channels).iter().enumerate() {
                out.push((
                    format!("{}.compress.{n}_nodes.variant{v}", self.name),
                    self.compress_shader(n, params),
                ));
            }
        }
        out
    }

    /// The compression shader for N nodes per texel under `params`, after its constants.
    fn compress_shader(&self, nodes_per_texel: u32, params: &TechniqueParams) -> String {
        shaders::compose_after(
            &shaders::u32_constants(&(self.compress_constants)(nodes_per_texel, params)),
            self.build_shader,
            &[],
        )
    }

    /// Bytes of the statistics buffer (none without statistics).
    fn stats_bytes(&self) -> u64 {
        match self.stats_words {
            0 => 0,
            words => (u64::from(words) * 4).max(16),
        }
    }

    /// The memory formula: 2N channels; a 16-byte uniform and N nodes of 8 bytes per texel kept
    /// for the lookup, plus the transient capture (`deep_capture::bytes`, its lists as large as
    /// the `segment_capacity` counter says, before a build their first capacity) and the statistics
    /// words.
    pub fn memory(&self, c: &MemoryCase<'_>) -> MemoryUse {
        let nodes = u64::from(nodes_per_texel(c.channels()));
        // Before a build (no counters), the lists' first capacity.
        let capacity = match c.counters.is_empty() {
            true => u64::from(super::deep_capture::INITIAL_CAPACITY),
            false => c.counter("segment_capacity"),
        };
        let transient = super::deep_capture::bytes(
            c.resolution_px(),
            capacity,
            (self.resolve)(c.params).node_texels(),
        ) + self.stats_bytes();
        MemoryUse {
            channels: 2 * nodes,
            bytes: 16 + c.texels() * nodes * NODE_BYTES + transient,
            transient_bytes: transient,
        }
    }
}

/// A compressed deep shadow map: the capture, the compression pass and the nodes it writes.
pub struct DeepNodes {
    spec: &'static DeepNodesSpec,
    resolution: u32,
    nodes_per_texel: u32,
    params: TechniqueParams,
    capture: DeepCapture,
    /// Held with the bind groups that use them (the ledger records their sizes).
    _params_buffer: wgpu::Buffer,
    _nodes: wgpu::Buffer,
    stats: Option<wgpu::Buffer>,
    compress_pipeline: wgpu::ComputePipeline,
    compress_bind_group: wgpu::BindGroup,
    lookup_layout: wgpu::BindGroupLayout,
    lookup_bind_group: wgpu::BindGroup,
    memory: MemoryLedger,
    /// The statistics words after the last build.
    last_stats: Vec<u32>,
}

impl DeepNodes {
    pub fn new(
        ctx: &TechniqueContext<'_>,
        spec: &'static DeepNodesSpec,
        params: &TechniqueParams,
    ) -> Result<Self, ShadowError> {
        let gpu = ctx.gpu;
        let device = &gpu.device;
        let res = params.resolution_px;
        let nodes_per_texel = nodes_per_texel(params.channels);
        let texels = u64::from(res) * u64::from(res);
        let mut memory = MemoryLedger::for_technique(&gpu.limits, params.memory_limit_bytes);
        let label = |what: &str| format!("{}.{what}", spec.name);

        // What the lookup reads: the parameters and the nodes.
        let params_buffer = memory.buffer(
            device,
            &wgpu::BufferDescriptor {
                label: Some(&label("params")),
                size: std::mem::size_of::<DeepParams>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            },
        )?;
        let nodes = memory.buffer(
            device,
            &storage_descriptor(
                &label("nodes"),
                texels * u64::from(nodes_per_texel) * NODE_BYTES,
            ),
        )?;
        // Build scratch: the statistics, and the capture (last: its lists take what a memory
        // limit leaves).
        let stats = match spec.stats_words {
            0 => None,
            _ => Some(memory.buffer_transient(
                device,
                &storage_descriptor(&label("stats"), spec.stats_bytes()),
            )?),
        };
        let capture = DeepCapture::new(
            gpu,
            ctx.frame_layout,
            spec.name,
            res,
            (spec.resolve)(params),
            &mut memory,
        )?;
        gpu.queue.write_buffer(
            &params_buffer,
            0,
            bytemuck::bytes_of(&DeepParams {
                resolution: res,
                nodes_per_texel,
                bisection_steps: spec.bisection_steps,
                _pad: 0,
            }),
        );

        let entry = bind_entry;
        let compute = wgpu::ShaderStages::COMPUTE;
        let mut compress_entries =
            vec![uniform_entry(0, compute), storage_entry(1, compute, false)];
        let mut compress_resources = vec![entry(0, &params_buffer), entry(1, &nodes)];
        if let Some(stats) = &stats {
            compress_entries.push(storage_entry(2, compute, false));
            compress_resources.push(entry(2, stats));
        }
        let compress_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(&label("compress.layout")),
            entries: &compress_entries,
        });
        let compress_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&label("compress.bind_group")),
            layout: &compress_layout,
            entries: &compress_resources,
        });
        let module = shaders::module(
            device,
            &label("compress"),
            &spec.compress_shader(nodes_per_texel, params),
        );
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(&label("compress.pipeline_layout")),
            bind_group_layouts: &[
                Some(ctx.frame_layout),
                Some(capture.layout()),
                Some(&compress_layout),
                Some(capture.rounds_layout()),
            ],
            immediate_size: 0,
        });
        let compress_pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(&label("compress")),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("compress"),
            compilation_options: Default::default(),
            cache: None,
        });

        let lookup_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(&label("lookup.layout")),
            entries: &[
                uniform_entry(0, LOOKUP_STAGES),
                storage_entry(1, LOOKUP_STAGES, true),
            ],
        });
        let lookup_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&label("lookup.bind_group")),
            layout: &lookup_layout,
            entries: &[entry(0, &params_buffer), entry(1, &nodes)],
        });
        Ok(Self {
            spec,
            resolution: res,
            nodes_per_texel,
            params: params.clone(),
            capture,
            _params_buffer: params_buffer,
            _nodes: nodes,
            stats,
            compress_pipeline,
            compress_bind_group,
            lookup_layout,
            lookup_bind_group,
            memory,
            last_stats: vec![0; spec.stats_words as usize],
        })
    }
}

impl ShadowTechnique for DeepNodes {
    fn name(&self) -> &'static str {
        self.spec.name
    }
    fn channels_used(&self) -> u32 {
        2 * self.nodes_per_texel
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

    /// `segments`: captured last frame; `segment_capacity`: what the capture's lists hold (one
    /// band's worth); `capture_bands`: the bands the map was captured in; `max_texel_list`: the
    /// longest texel list; then the technique's own statistics.
    fn counters(&self) -> Vec<(&'static str, u64)> {
        let mut out = vec![
            ("segments", self.capture.segments()),
            ("segment_capacity", u64::from(self.capture.capacity())),
            ("capture_bands", u64::from(self.capture.bands())),
            ("max_texel_list", u64::from(self.capture.max_list())),
            (
                "counts_by_blending",
                u64::from(self.capture.counts_by_blending()),
            ),
        ];
        out.extend((self.spec.stats_counters)(&self.last_stats));
        out
    }

    fn build<'a>(
        &'a mut self,
        gpu: &'a Gpu,
        inputs: BuildInputs<'a>,
    ) -> GpuFuture<'a, Result<(), ShadowError>> {
        Box::pin(async move {
            // With statistics to read back, the capture's fill and the compression go in a
            // submission of their own; otherwise they join the frame.
            let mut own = None;
            let encoder = match &self.stats {
                Some(_) => own.insert(gpu.device.create_command_encoder(
                    &wgpu::CommandEncoderDescriptor {
                        label: Some(&format!("{}.build.encoder", self.spec.name)),
                    },
                )),
                None => &mut *inputs.encoder,
            };
            // Zeroed by a queue write, which lands before the capture's first submission (bands
            // before the last are submitted before `encoder`).
            if let Some(stats) = &self.stats {
                gpu.queue
                    .write_buffer(stats, 0, &vec![0; self.spec.stats_bytes() as usize]);
            }
            let (spec, pipeline, compress_bind_group, resolution, params) = (
                self.spec,
                &self.compress_pipeline,
                &self.compress_bind_group,
                self.resolution,
                &self.params,
            );
            let frame_bind_group = inputs.frame_bind_group;
            // The compression of each band, over the band's rows of the capture, in rounds.
            let compress = |encoder: &mut wgpu::CommandEncoder,
                            timer: &mut crate::gpu::GpuTimer,
                            band: &BandPass<'_>| {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(&format!("{}.compress", spec.name)),
                    timestamp_writes: timer.compute_pass("shadow"),
                });
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, frame_bind_group, &[]);
                pass.set_bind_group(1, band.capture, &[]);
                pass.set_bind_group(2, compress_bind_group, &[]);
                let groups = (resolution.div_ceil(8), band.band.rows().div_ceil(8));
                let rounds = (spec.rounds)(band.max_list, band.loop_budget, params);
                band.rounds.dispatch(&mut pass, rounds, groups);
            };
            self.capture
                .record(
                    gpu,
                    &mut self.memory,
                    encoder,
                    inputs.timer,
                    frame_bind_group,
                    inputs.particles,
                    inputs.particle_count,
                    inputs.volume.is_some(),
                    compress,
                )
                .await?;
            if let (Some(encoder), Some(stats)) = (own, &self.stats) {
                gpu.queue.submit([encoder.finish()]);
                let bytes = read_buffer(gpu, stats, 0, u64::from(self.spec.stats_words) * 4)
                    .await
                    .map_err(|err| ShadowError::Gpu(err.to_string()))?;
                self.last_stats = bytes
                    .chunks_exact(4)
                    .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
                    .collect();
            }
            Ok(())
        })
    }
}
