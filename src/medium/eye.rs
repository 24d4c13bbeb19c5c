//! The eye's ray march through a density grid (`shaders/medium/eye_march.wgsl`), and
//! [`EyeMarchProbe`], which evaluates it at a list of rays with the light's transmittance by
//! secondary ray marching, so that `tests/medium.rs` can hold the shader to its f64 mirror
//! (`DensityGrid::march_eye`) and to the closed forms. The volume's eye pass in the frame will
//! call the same `march_eye` with the active technique's transmittance.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use wgpu::util::DeviceExt;

use super::gpu_grid::{GpuGrid, GridGpuError};
use crate::gpu::{Gpu, read_buffer};
use crate::shaders;

/// Keep in sync with `EyeProbeParams` in shaders/medium/eye_march_probe.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct EyeProbeParams {
    light: [f32; 4],
    albedo: [f32; 4],
    eye_steps: u32,
    light_steps: u32,
    count: u32,
    jitter: f32,
}

/// Keep in sync with `EyeRay` in shaders/medium/eye_march_probe.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct EyeRayData {
    origin: [f32; 4],
    dir: [f32; 4],
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![
        crate::mirror_layout!(
            EyeProbeParams,
            "medium/eye_march_probe.wgsl",
            "EyeProbeParams",
            [light, albedo, eye_steps, light_steps, count, jitter]
        ),
        crate::mirror_layout!(
            EyeRayData,
            "medium/eye_march_probe.wgsl",
            "EyeRay",
            [origin, dir]
        ),
    ]
}

/// A ray of the probe: `origin + t·dir` for t in [`t_near`, `t_far`] (world metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EyeRay {
    pub origin: Vec3,
    /// A unit vector.
    pub dir: Vec3,
    pub t_near: f32,
    pub t_far: f32,
}

/// How the probe marches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EyeMarchSettings {
    pub light: Vec3,
    pub albedo: Vec3,
    pub eye_steps: u32,
    /// Samples towards the light from each eye sample (SRM's N).
    pub light_steps: u32,
    /// Where in its step each eye sample lies, 0..1.
    pub jitter: f32,
}

/// The march's radiance and transmittance along one ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EyeResult {
    pub radiance: Vec3,
    pub transmittance: f32,
}

/// The eye-march probe's pipeline.
pub struct EyeMarchProbe {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl EyeMarchProbe {
    pub fn new(gpu: &Gpu) -> Self {
        let device = &gpu.device;
        let module = shaders::module(
            device,
            "medium.eye_march_probe",
            &shaders::compose("medium/eye_march_probe.wgsl", &[]),
        );
        let compute = wgpu::ShaderStages::COMPUTE;
        let buffer = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: compute,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("medium.eye_probe.layout"),
            entries: &[
                buffer(0, wgpu::BufferBindingType::Uniform),
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: compute,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D3,
                        multisampled: false,
                    },
                    count: None,
                },
                buffer(2, wgpu::BufferBindingType::Uniform),
                buffer(3, wgpu::BufferBindingType::Storage { read_only: true }),
                buffer(4, wgpu::BufferBindingType::Storage { read_only: false }),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("medium.eye_probe.pipeline_layout"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("medium.eye_probe.pipeline"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("eye_probe_main"),
            compilation_options: Default::default(),
            cache: None,
        });
        Self { layout, pipeline }
    }

    /// The march along each of `rays` through `grid`. Refused where one invocation's loops
    /// (eye steps x (light steps + 3), plus the set-up) would pass the adapter's loop budget.
    pub fn march(
        &self,
        gpu: &Gpu,
        grid: &GpuGrid,
        settings: &EyeMarchSettings,
        rays: &[EyeRay],
    ) -> Result<Vec<EyeResult>, GridGpuError> {
        let loops = u64::from(settings.eye_steps) * (u64::from(settings.light_steps) + 4) + 3;
        if let Some(budget) = gpu.loop_budget()
            && loops > u64::from(budget)
        {
            return Err(GridGpuError::TooManySteps {
                steps: loops.min(u64::from(u32::MAX)) as u32,
                budget,
            });
        }
        if rays.is_empty() {
            return Ok(Vec::new());
        }
        let device = &gpu.device;
        let params = EyeProbeParams {
            light: settings.light.extend(1.0).to_array(),
            albedo: settings.albedo.extend(0.0).to_array(),
            eye_steps: settings.eye_steps,
            light_steps: settings.light_steps,
            count: rays.len() as u32,
            jitter: settings.jitter,
        };
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("medium.eye_probe.params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let data: Vec<EyeRayData> = rays
            .iter()
            .map(|r| EyeRayData {
                origin: r.origin.extend(r.t_near).to_array(),
                dir: r.dir.extend(r.t_far).to_array(),
            })
            .collect();
        let rays_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("medium.eye_probe.rays"),
            contents: bytemuck::cast_slice(&data),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let size = 16 * rays.len() as u64;
        let results = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("medium.eye_probe.results"),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("medium.eye_probe.bind_group"),
            layout: &self.layout,
            entries: &[
                crate::gpu::bind_entry(0, grid.params()),
                crate::gpu::texture_binding(1, grid.view()),
                crate::gpu::bind_entry(2, &params),
                crate::gpu::bind_entry(3, &rays_buffer),
                crate::gpu::bind_entry(4, &results),
            ],
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("medium.eye_probe.encoder"),
        });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("medium.eye_probe"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups((rays.len() as u32).div_ceil(64), 1, 1);
        }
        gpu.queue.submit([encoder.finish()]);
        let bytes = read_buffer(gpu, &results, 0, size)?;
        let values: &[[f32; 4]] = bytemuck::cast_slice(&bytes);
        Ok(values
            .iter()
            .map(|v| EyeResult {
                radiance: Vec3::new(v[0], v[1], v[2]),
                transmittance: v[3],
            })
            .collect())
    }
}

/// The probe's composed shader module, for the naga validation test.
pub fn shader_modules() -> Vec<(String, String)> {
    vec![(
        "medium/eye_march_probe.wgsl".to_owned(),
        shaders::compose("medium/eye_march_probe.wgsl", &[]),
    )]
}
