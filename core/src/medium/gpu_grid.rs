//! A density grid on the GPU: an `R32Float` 3D texture read with `textureLoad` (exact voxel
//! values; the trilinear weights are the shader's, as in the f64 mirror [`super::grid`]), and
//! [`GridMarch`], the light's transmittance through it at world points by a fixed-step march
//! (`shaders/medium/grid_march.wgsl`): what the volumes' reference evaluates at N and 2N steps,
//! held to the CPU mirror by `tests/medium.rs`.

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, UVec3, Vec3};
use thiserror::Error;
use wgpu::util::DeviceExt;

use super::grid::{DensityGrid, IndexShape, IndexShapeKind};
use crate::gpu::{
    AllocationError, Gpu, GpuError, MemoryLedger, bind_entry, read_buffer, storage_entry,
    texture_3d_entry, texture_binding, uniform_entry,
};
use crate::shaders;

/// Keep in sync with `GridParams` in shaders/medium/grid.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct GridParams {
    pub index_from_world: [[f32; 4]; 4],
    /// Voxels along x, y, z (w unused); zero for an empty grid.
    pub dims: [u32; 4],
    pub density_scale_per_m: f32,
    /// The frame's marches ([`super::frame`]); the probes leave them 0.
    pub eye_steps: u32,
    pub jitter: f32,
    pub reference_steps: u32,
    pub albedo_powder: [f32; 4],
    pub build_steps: u32,
    /// 0: the voxels; 1: an ellipsoid (`shape_a` its centre, `shape_b` its radii); 2: a box
    /// (`shape_a` to `shape_b`), in index space, of density `shape_a[3]` ([`IndexShape`]).
    pub shape_kind: u32,
    pub _pad: [u32; 2],
    pub shape_a: [f32; 4],
    pub shape_b: [f32; 4],
}

/// The uniform's fields of a grid's shape: (kind, a, b).
fn shape_fields(shape: Option<&IndexShape>) -> (u32, [f32; 4], [f32; 4]) {
    let Some(shape) = shape else {
        return (0, [0.0; 4], [0.0; 4]);
    };
    let density = shape.density as f32;
    match shape.kind {
        IndexShapeKind::Ellipsoid { center, radii } => (
            1,
            center.as_vec3().extend(density).to_array(),
            radii.as_vec3().extend(0.0).to_array(),
        ),
        IndexShapeKind::Box { min, max } => (
            2,
            min.as_vec3().extend(density).to_array(),
            max.as_vec3().extend(0.0).to_array(),
        ),
    }
}

/// Keep in sync with `MarchParams` in shaders/medium/grid_march.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct MarchParams {
    light: [f32; 4],
    steps: u32,
    count: u32,
    _pad: [u32; 2],
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![
        crate::mirror_layout!(
            GridParams,
            "medium/grid_march.wgsl",
            "GridParams",
            [
                index_from_world,
                dims,
                density_scale_per_m,
                eye_steps,
                jitter,
                reference_steps,
                albedo_powder,
                build_steps,
                shape_kind,
                shape_a,
                shape_b
            ]
        ),
        crate::mirror_layout!(
            MarchParams,
            "medium/grid_march.wgsl",
            "MarchParams",
            [light, steps, count]
        ),
    ]
}

/// Why a grid cannot go to the GPU or be marched there.
#[derive(Debug, Error)]
pub enum GridGpuError {
    #[error("a grid of {x}x{y}x{z} voxels exceeds the device's 3D texture size of {max}")]
    TooLarge { x: u32, y: u32, z: u32, max: u32 },
    #[error(transparent)]
    Allocation(#[from] AllocationError),
    #[error(
        "a march of {steps} steps exceeds what one shader invocation may loop on this adapter \
         ({budget} iterations, 3 of them the march's set-up)"
    )]
    TooManySteps { steps: u32, budget: u32 },
    #[error(
        "an eye march of {eye_steps} steps, each marching {light_steps} steps towards the light, \
         loops {loops} times, more than one shader invocation may loop on this adapter \
         ({budget})"
    )]
    TooManyLoops {
        eye_steps: u32,
        light_steps: u32,
        loops: u64,
        budget: u32,
    },
    #[error(
        "the light march did not converge: T at {steps} and {} steps differ by {difference:.2e} \
         at {point}, more than {tolerance:.0e}, and {} steps would pass {limit} steps",
        2 * steps,
        4 * steps
    )]
    NotConverged {
        steps: u32,
        difference: f32,
        tolerance: f32,
        point: Vec3,
        limit: u32,
    },
    #[error(transparent)]
    Gpu(#[from] GpuError),
}

/// How a converged march searches: from `start_steps`, doubling, until T at N and 2N agree
/// within `tolerance`, with 2N never past `max_steps`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Convergence {
    pub start_steps: u32,
    pub max_steps: u32,
    pub tolerance: f32,
}

/// A march whose step count was shown to have converged at every point.
#[derive(Clone, Debug, PartialEq)]
pub struct ConvergedMarch {
    /// T at each point with `2 * steps` steps.
    pub transmittance: Vec<f32>,
    /// The step count N whose T agreed with 2N's at every point.
    pub steps: u32,
    /// The largest |T(N) - T(2N)| over the points.
    pub worst_difference: f32,
}

/// A [`DensityGrid`] uploaded: its voxels and its placement.
pub struct GpuGrid {
    pub(super) params: wgpu::Buffer,
    /// What `params` holds (the frame's medium writes its march settings into a copy).
    pub(super) uniform: GridParams,
    pub(super) view: wgpu::TextureView,
    /// Bytes the voxels and the parameters take on the device.
    pub bytes: u64,
    /// Voxels along x, y, z (zero for an empty grid).
    pub dims: UVec3,
}

impl GpuGrid {
    /// Uploads `grid`, its texture and uniform recorded in `ledger` (an empty grid takes one
    /// zero voxel, so that the binding exists).
    pub fn upload(
        gpu: &Gpu,
        ledger: &mut MemoryLedger,
        grid: &DensityGrid,
    ) -> Result<Self, GridGpuError> {
        let dims = grid.dims;
        let max = gpu.limits.max_texture_dimension_3d;
        if dims.max_element() > max {
            return Err(GridGpuError::TooLarge {
                x: dims.x,
                y: dims.y,
                z: dims.z,
                max,
            });
        }
        let empty = dims.min_element() == 0;
        // A shape is sampled in closed form ([`IndexShape`]): its voxels are never read, so one
        // placeholder voxel is bound, as for no grid.
        let placeholder = empty || grid.analytic.is_some();
        let size = match placeholder {
            true => wgpu::Extent3d {
                width: 1,
                height: 1,
                depth_or_array_layers: 1,
            },
            false => wgpu::Extent3d {
                width: dims.x,
                height: dims.y,
                depth_or_array_layers: dims.z,
            },
        };
        let before = ledger.total_bytes();
        let texture = ledger.texture(
            &gpu.device,
            &wgpu::TextureDescriptor {
                label: Some("medium.grid.density"),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D3,
                format: wgpu::TextureFormat::R32Float,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            },
        )?;
        let zero = [0.0f32];
        let voxels: &[f32] = if placeholder { &zero } else { &grid.values };
        gpu.queue.write_texture(
            texture.as_image_copy(),
            bytemuck::cast_slice(voxels),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * size.width),
                rows_per_image: Some(size.height),
            },
            size,
        );
        let index_from_world = grid.world_from_index.inverse();
        let (shape_kind, shape_a, shape_b) = shape_fields(grid.analytic.as_ref());
        let params = GridParams {
            index_from_world: Mat4::from(glam::Affine3A::from_mat3_translation(
                index_from_world.matrix3.as_mat3(),
                index_from_world.translation.as_vec3(),
            ))
            .to_cols_array_2d(),
            dims: [dims.x, dims.y, dims.z, 0].map(|d| if empty { 0 } else { d }),
            density_scale_per_m: grid.density_scale_per_m as f32,
            eye_steps: 0,
            jitter: 0.0,
            reference_steps: 0,
            albedo_powder: [0.0; 4],
            build_steps: 0,
            shape_kind,
            _pad: [0; 2],
            shape_a,
            shape_b,
        };
        let params_buffer = ledger.buffer_init(
            &gpu.device,
            "medium.grid.params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        )?;
        Ok(Self {
            params: params_buffer,
            uniform: params,
            view: texture.create_view(&wgpu::TextureViewDescriptor::default()),
            bytes: ledger.total_bytes() - before,
            dims: if empty { UVec3::ZERO } else { dims },
        })
    }
}

/// A compute pipeline that evaluates something of a grid at a list of inputs, one invocation
/// an input (`@workgroup_size(64)`), with the bindings every such shader declares: the grid's
/// uniform (0) and voxels (1), its own uniform (2), its inputs (3, read) and its results (4).
/// [`GridMarch`] and `super::eye::EyeMarchProbe` are two.
pub(super) struct GridProbe {
    label: &'static str,
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl GridProbe {
    /// The pipeline of `entry_point` in the composed `shader`, its objects labelled `label`.
    pub(super) fn new(gpu: &Gpu, label: &'static str, shader: &str, entry_point: &str) -> Self {
        let device = &gpu.device;
        let module = shaders::module(device, label, &shaders::compose(shader, &[]));
        let compute = wgpu::ShaderStages::COMPUTE;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(&format!("{label}.layout")),
            entries: &[
                uniform_entry(0, compute),
                texture_3d_entry(
                    1,
                    compute,
                    wgpu::TextureSampleType::Float { filterable: false },
                ),
                uniform_entry(2, compute),
                storage_entry(3, compute, true),
                storage_entry(4, compute, false),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(&format!("{label}.pipeline_layout")),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(&format!("{label}.pipeline")),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some(entry_point),
            compilation_options: Default::default(),
            cache: None,
        });
        Self {
            label,
            layout,
            pipeline,
        }
    }

    /// Evaluates `count` inputs (`inputs`, laid out as the shader reads them) through `grid`
    /// with the shader's uniform `params`, and reads back `result_bytes` bytes a result.
    pub(super) async fn run(
        &self,
        gpu: &Gpu,
        grid: &GpuGrid,
        params: &[u8],
        inputs: &[u8],
        count: usize,
        result_bytes: u64,
    ) -> Result<Vec<u8>, GpuError> {
        if count == 0 {
            return Ok(Vec::new());
        }
        let device = &gpu.device;
        let label = self.label;
        let buffer = |what: &str, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(&format!("{label}.{what}")),
                contents,
                usage,
            })
        };
        let params = buffer("params", params, wgpu::BufferUsages::UNIFORM);
        let inputs = buffer("inputs", inputs, wgpu::BufferUsages::STORAGE);
        let size = result_bytes * count as u64;
        let results = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(&format!("{label}.results")),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&format!("{label}.bind_group")),
            layout: &self.layout,
            entries: &[
                bind_entry(0, &grid.params),
                texture_binding(1, &grid.view),
                bind_entry(2, &params),
                bind_entry(3, &inputs),
                bind_entry(4, &results),
            ],
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some(&format!("{label}.encoder")),
        });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(label),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups((count as u32).div_ceil(64), 1, 1);
        }
        gpu.queue.submit([encoder.finish()]);
        read_buffer(gpu, &results, 0, size).await
    }
}

/// The transmittance march's pipeline.
pub struct GridMarch {
    probe: GridProbe,
}

impl GridMarch {
    pub fn new(gpu: &Gpu) -> Self {
        Self {
            probe: GridProbe::new(
                gpu,
                "medium.grid_march",
                "medium/grid_march.wgsl",
                "march_main",
            ),
        }
    }

    /// T from `light` to each of `points` (world metres) through `grid`, marched with `steps`
    /// steps, as `DensityGrid::marched_optical_depth` computes it in f64.
    pub async fn transmittance(
        &self,
        gpu: &Gpu,
        grid: &GpuGrid,
        light: Vec3,
        points: &[Vec3],
        steps: u32,
    ) -> Result<Vec<f32>, GridGpuError> {
        if let Some(budget) = gpu.loop_budget()
            && steps.saturating_add(3) > budget
        {
            return Err(GridGpuError::TooManySteps { steps, budget });
        }
        let params = MarchParams {
            light: light.extend(1.0).to_array(),
            steps,
            count: points.len() as u32,
            _pad: [0; 2],
        };
        let padded: Vec<[f32; 4]> = points.iter().map(|p| p.extend(1.0).to_array()).collect();
        let bytes = self
            .probe
            .run(
                gpu,
                grid,
                bytemuck::bytes_of(&params),
                bytemuck::cast_slice(&padded),
                points.len(),
                4,
            )
            .await?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }
}

impl GridMarch {
    /// T from `light` to each of `points` through `grid`, with a step count shown to have
    /// converged: starting at `search.start_steps`, or at two steps a voxel along the longest segment
    /// the grid's support holds if that is more (`DensityGrid::min_steps`: N and 2N can agree
    /// while both step over a thin feature), the steps double until T at N and at 2N agree
    /// within `search.tolerance` at every point (the volumes' reference, issue 26 §4). Refused in
    /// one line when 2N would pass `search.max_steps` or the adapter's loop budget first.
    pub async fn converged_transmittance(
        &self,
        gpu: &Gpu,
        grid: &GpuGrid,
        light: Vec3,
        points: &[Vec3],
        search: Convergence,
    ) -> Result<ConvergedMarch, GridGpuError> {
        let Convergence {
            start_steps,
            max_steps,
            tolerance,
        } = search;
        let limit = match gpu.loop_budget() {
            Some(budget) => max_steps.min(budget.saturating_sub(3)),
            None => max_steps,
        };
        let diagonal = (grid.dims.as_vec3() + Vec3::ONE).length();
        let mut steps = start_steps.max(super::grid::steps_per_voxel_length(f64::from(diagonal)));
        let mut coarse = self.transmittance(gpu, grid, light, points, steps).await?;
        loop {
            let fine = self
                .transmittance(gpu, grid, light, points, 2 * steps)
                .await?;
            let (worst_at, worst_difference) = coarse
                .iter()
                .zip(&fine)
                .map(|(a, b)| (a - b).abs())
                .enumerate()
                .fold((0, 0.0f32), |w, (i, d)| if d > w.1 { (i, d) } else { w });
            if worst_difference <= tolerance {
                return Ok(ConvergedMarch {
                    transmittance: fine,
                    steps,
                    worst_difference,
                });
            }
            if 4 * u64::from(steps) > u64::from(limit) {
                return Err(GridGpuError::NotConverged {
                    steps,
                    difference: worst_difference,
                    tolerance,
                    point: points[worst_at],
                    limit,
                });
            }
            steps *= 2;
            coarse = fine;
        }
    }
}

/// The medium's composed shader modules, for the naga validation test.
pub fn shader_modules() -> Vec<(String, String)> {
    vec![(
        "medium/grid_march.wgsl".to_owned(),
        shaders::compose("medium/grid_march.wgsl", &[]),
    )]
}
