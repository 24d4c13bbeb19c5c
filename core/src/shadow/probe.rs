//! The transmittance probe: T(p) at arbitrary world points, computed on the GPU by the active
//! technique's own `shadow_transmittance` (composed into `shaders/shadow/probe.wgsl`), so the
//! numbers the CLI's `probe`, the error metrics and the tests see are the ones the lighting uses:
//! there is no second implementation to drift.

use glam::Vec3;
use wgpu::util::DeviceExt;

use super::ShadowTechnique;
use crate::gpu::{Gpu, GpuError, read_buffer};
use crate::shaders;

/// A compute pipeline evaluating one technique's lookup at points.
pub struct Probe {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    /// Whether the next probes multiply T by the opaque occluders' visibility, as the lighting
    /// does ([`Probe::set_with_occluders`]).
    with_occluders: bool,
}

/// A recorded probe dispatch whose results can be read once its commands are submitted.
pub struct PendingProbe {
    results: wgpu::Buffer,
    count: usize,
}

impl Probe {
    pub fn new(
        gpu: &Gpu,
        frame_layout: &wgpu::BindGroupLayout,
        technique: &dyn ShadowTechnique,
        params: &super::TechniqueParams,
    ) -> Self {
        let device = &gpu.device;
        let entry = super::find(technique.name()).expect("a live technique is registered");
        let module = shaders::module(
            device,
            &format!("probe[{}]", entry.name),
            &source(entry, params),
        );
        let storage = |binding, read_only| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("probe.layout"),
            entries: &[storage(0, true), storage(1, false)],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("probe.pipeline_layout"),
            bind_group_layouts: &[
                Some(frame_layout),
                Some(technique.bind_group_layout()),
                Some(&layout),
            ],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("probe.pipeline"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("probe_main"),
            compilation_options: Default::default(),
            cache: None,
        });
        Self {
            layout,
            pipeline,
            with_occluders: false,
        }
    }

    /// From now on, evaluate the light's whole visibility at each point (T times the opaque
    /// occluders' visibility, as the lighting shaders do), or the smoke's T alone (the default).
    pub fn set_with_occluders(&mut self, on: bool) {
        self.with_occluders = on;
    }

    /// Records the evaluation of T at `points` with each (frame, lookup) bind group pair of
    /// `lookups` in turn: one for a spotlight; a point light's six faces, each writing the
    /// points in its face.
    pub fn record(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        lookups: &[(&wgpu::BindGroup, &wgpu::BindGroup)],
        points: &[Vec3],
    ) -> PendingProbe {
        let device = &gpu.device;
        let count = points.len();
        let w = if self.with_occluders { 1.0 } else { 0.0 };
        let padded: Vec<[f32; 4]> = points.iter().map(|p| p.extend(w).to_array()).collect();
        let points_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("probe.points"),
            contents: bytemuck::cast_slice(if padded.is_empty() {
                &[[0.0f32; 4]][..]
            } else {
                &padded
            }),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let results = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("probe.results"),
            size: (count.max(1) * 4) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("probe.bind_group"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: points_buffer.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: results.as_entire_binding(),
                },
            ],
        });
        if count > 0 {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("probe"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(2, &bind_group, &[]);
            for (frame_bind_group, technique_bind_group) in lookups {
                pass.set_bind_group(0, *frame_bind_group, &[]);
                pass.set_bind_group(1, *technique_bind_group, &[]);
                pass.dispatch_workgroups((count as u32).div_ceil(64), 1, 1);
            }
        }
        PendingProbe { results, count }
    }
}

impl PendingProbe {
    /// Waits for the submitted dispatch and returns T per point.
    pub async fn read(self, gpu: &Gpu) -> Result<Vec<f32>, GpuError> {
        if self.count == 0 {
            return Ok(Vec::new());
        }
        let bytes = read_buffer(gpu, &self.results, 0, (self.count * 4) as u64).await?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }
}

/// The composed probe shader for a technique: its lookup and its occluders' visibility, as the
/// lighting shaders are composed ([`super::TechniqueEntry::frame_imports`]).
pub fn source(entry: &super::TechniqueEntry, params: &super::TechniqueParams) -> String {
    shaders::compose("shadow/probe.wgsl", &entry.frame_imports(params).pairs())
}
