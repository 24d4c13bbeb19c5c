//! The procedural cloud's noise textures on the GPU: `shape_main` and `detail_main`
//! (shaders/medium/cloud_noise_gen.wgsl) write the shape (128³, RGBA: Perlin–Worley and three
//! Worley FBMs) and detail (32³, RGB: Worley FBMs) texels from a seed into storage buffers,
//! copied into `Rgba32Float` 3D textures that a march samples with repeat addressing. The CPU
//! mirror of every texel is [`super::cloud_noise`]; `tests/medium.rs` holds the two together.

use bytemuck::{Pod, Zeroable};
use glam::{DAffine3, DVec3, UVec3, Vec3};
use wgpu::util::DeviceExt;

use super::cloud_noise::{
    CloudNoiseParams, CloudParams, DETAIL_SIZE, FLOATS_PER_TEXEL, SHAPE_SIZE,
};
use super::grid::{DensityGrid, box_cells};
use crate::gpu::{
    AllocationError, Gpu, GpuError, MemoryLedger, read_buffer, storage_descriptor, storage_entry,
    texture_3d_entry, uniform_entry,
};
use crate::shaders;

/// Keep in sync with `BakeParams` in shaders/medium/cloud_bake.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct BakeParams {
    first_voxel_m: [f32; 4],
    voxel_m: [f32; 4],
    dims: [u32; 4],
    drift_m: [f32; 4],
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![crate::mirror_layout!(
        BakeParams,
        "medium/cloud_bake.wgsl",
        "BakeParams",
        [first_voxel_m, voxel_m, dims, drift_m]
    )]
}

/// Where a bake puts its voxels: `dims` voxels filling the cloud layer's box, each voxel's
/// density sampled at its centre ([`box_cells`]).
pub fn bake_placement(params: &CloudParams, dims: UVec3) -> DAffine3 {
    let min = DVec3::new(
        f64::from(params.origin_xz_m[0]),
        f64::from(params.altitude_m),
        f64::from(params.origin_xz_m[1]),
    );
    let size = DVec3::new(
        f64::from(params.size_xz_m[0]),
        f64::from(params.thickness_m),
        f64::from(params.size_xz_m[1]),
    );
    box_cells(min, min + size, dims)
}

/// The first voxel's centre and a voxel's size, world metres, of a placement by [`box_cells`]
/// (what `bake_main` steps by).
fn first_voxel_and_size(placement: &DAffine3) -> (DVec3, DVec3) {
    let m = placement.matrix3;
    (
        placement.translation,
        DVec3::new(m.x_axis.x, m.y_axis.y, m.z_axis.z),
    )
}

/// Why the noise could not be made or read.
#[derive(Debug, thiserror::Error)]
pub enum CloudNoiseError {
    #[error(transparent)]
    Allocation(#[from] AllocationError),
    #[error(transparent)]
    Gpu(#[from] GpuError),
}

/// Texels per workgroup edge of the generators (`@workgroup_size(4, 4, 4)`).
const WORKGROUP_EDGE: u32 = 4;
const TEXEL_BYTES: u64 = FLOATS_PER_TEXEL as u64 * 4;

/// The cloud's two noise textures, generated on the device.
pub struct CloudNoiseTextures {
    pub shape: wgpu::Texture,
    pub detail: wgpu::Texture,
    /// The seed they were generated from (the bake's coverage map uses it too).
    pub seed: u32,
}

/// The generators' pipelines.
pub struct CloudNoiseGenerator {
    layout: wgpu::BindGroupLayout,
    shape: wgpu::ComputePipeline,
    detail: wgpu::ComputePipeline,
}

/// The storage buffers one generation writes (scratch: copied into the textures).
struct TexelBuffers {
    shape: wgpu::Buffer,
    detail: wgpu::Buffer,
}

fn texels_bytes(size: u32) -> u64 {
    u64::from(size).pow(3) * TEXEL_BYTES
}

impl CloudNoiseGenerator {
    pub fn new(gpu: &Gpu) -> Self {
        let device = &gpu.device;
        let module = shaders::module(
            device,
            "medium.cloud_noise_gen",
            &shaders::compose("medium/cloud_noise_gen.wgsl", &[]),
        );
        let compute = wgpu::ShaderStages::COMPUTE;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("medium.cloud_noise.layout"),
            entries: &[
                uniform_entry(0, compute),
                storage_entry(1, compute, false),
                storage_entry(2, compute, false),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("medium.cloud_noise.pipeline_layout"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = |label, entry_point| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(label),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(entry_point),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        Self {
            shape: pipeline("medium.cloud_noise.shape", "shape_main"),
            detail: pipeline("medium.cloud_noise.detail", "detail_main"),
            layout,
        }
    }

    /// Records both generators for `seed` into new storage buffers (recorded in `ledger` as
    /// transient: scratch the textures are copied from).
    fn record(
        &self,
        gpu: &Gpu,
        ledger: &mut MemoryLedger,
        encoder: &mut wgpu::CommandEncoder,
        seed: u32,
    ) -> Result<TexelBuffers, AllocationError> {
        let device = &gpu.device;
        let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
        let buffer = |ledger: &mut MemoryLedger, label, size| {
            let mut desc = storage_descriptor(label, size);
            desc.usage = usage;
            ledger.buffer_transient(device, &desc)
        };
        let buffers = TexelBuffers {
            shape: buffer(
                ledger,
                "medium.cloud_noise.shape_texels",
                texels_bytes(SHAPE_SIZE),
            )?,
            detail: buffer(
                ledger,
                "medium.cloud_noise.detail_texels",
                texels_bytes(DETAIL_SIZE),
            )?,
        };
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("medium.cloud_noise.params"),
            contents: bytemuck::bytes_of(&CloudNoiseParams::new(seed)),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("medium.cloud_noise.bind_group"),
            layout: &self.layout,
            entries: &[
                crate::gpu::bind_entry(0, &params),
                crate::gpu::bind_entry(1, &buffers.shape),
                crate::gpu::bind_entry(2, &buffers.detail),
            ],
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("medium.cloud_noise"),
            timestamp_writes: None,
        });
        pass.set_bind_group(0, &bind_group, &[]);
        for (pipeline, size) in [(&self.shape, SHAPE_SIZE), (&self.detail, DETAIL_SIZE)] {
            let groups = size / WORKGROUP_EDGE;
            pass.set_pipeline(pipeline);
            pass.dispatch_workgroups(groups, groups, groups);
        }
        Ok(buffers)
    }

    /// The shape and detail textures for `seed`, recorded in `ledger`.
    pub fn generate(
        &self,
        gpu: &Gpu,
        ledger: &mut MemoryLedger,
        seed: u32,
    ) -> Result<CloudNoiseTextures, CloudNoiseError> {
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("medium.cloud_noise.encoder"),
            });
        let buffers = self.record(gpu, ledger, &mut encoder, seed)?;
        let texture = |ledger: &mut MemoryLedger, label, size: u32| {
            ledger.texture(
                &gpu.device,
                &wgpu::TextureDescriptor {
                    label: Some(label),
                    size: wgpu::Extent3d {
                        width: size,
                        height: size,
                        depth_or_array_layers: size,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D3,
                    format: wgpu::TextureFormat::Rgba32Float,
                    usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                    view_formats: &[],
                },
            )
        };
        let textures = CloudNoiseTextures {
            shape: texture(ledger, "medium.cloud_noise.shape", SHAPE_SIZE)?,
            detail: texture(ledger, "medium.cloud_noise.detail", DETAIL_SIZE)?,
            seed,
        };
        for (buffer, texture, size) in [
            (&buffers.shape, &textures.shape, SHAPE_SIZE),
            (&buffers.detail, &textures.detail, DETAIL_SIZE),
        ] {
            // A row is size x 16 bytes (2048 and 512): multiples of the 256 a copy needs.
            encoder.copy_buffer_to_texture(
                wgpu::TexelCopyBufferInfo {
                    buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(size * TEXEL_BYTES as u32),
                        rows_per_image: Some(size),
                    },
                },
                texture.as_image_copy(),
                texture.size(),
            );
        }
        gpu.queue.submit([encoder.finish()]);
        Ok(textures)
    }

    /// The generators' texels for `seed` read back: (shape, detail), 4 floats a texel, x
    /// fastest, as `cloud_noise::shape_texels` and `detail_texels` lay them out.
    pub async fn read_texels(
        &self,
        gpu: &Gpu,
        seed: u32,
    ) -> Result<(Vec<f32>, Vec<f32>), CloudNoiseError> {
        let mut ledger = MemoryLedger::for_device(&gpu.limits);
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("medium.cloud_noise.read_encoder"),
            });
        let buffers = self.record(gpu, &mut ledger, &mut encoder, seed)?;
        gpu.queue.submit([encoder.finish()]);
        let read = async |buffer: &wgpu::Buffer, size| -> Result<Vec<f32>, GpuError> {
            let bytes = read_buffer(gpu, buffer, 0, texels_bytes(size)).await?;
            Ok(bytemuck::cast_slice(&bytes).to_vec())
        };
        Ok((
            read(&buffers.shape, SHAPE_SIZE).await?,
            read(&buffers.detail, DETAIL_SIZE).await?,
        ))
    }
}

/// The bake's pipeline: the cloud layer's density at voxel centres, from the noise textures.
pub struct CloudBaker {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl CloudBaker {
    pub fn new(gpu: &Gpu) -> Self {
        let device = &gpu.device;
        let module = shaders::module(
            device,
            "medium.cloud_bake",
            &shaders::compose("medium/cloud_bake.wgsl", &[]),
        );
        let compute = wgpu::ShaderStages::COMPUTE;
        let noise = wgpu::TextureSampleType::Float { filterable: false };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("medium.cloud_bake.layout"),
            entries: &[
                uniform_entry(0, compute),
                uniform_entry(1, compute),
                texture_3d_entry(2, compute, noise),
                texture_3d_entry(3, compute, noise),
                storage_entry(4, compute, false),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("medium.cloud_bake.pipeline_layout"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("medium.cloud_bake.pipeline"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("bake_main"),
            compilation_options: Default::default(),
            cache: None,
        });
        Self { layout, pipeline }
    }

    /// The cloud layer of `params`, its noise and coverage map carried by `drift` (world
    /// metres, [`crate::medium::cloud_noise::baked_density_drifted`]), baked from `noise` into a grid of `dims` voxels (extinction
    /// in 1/m: the grid's density scale is 1), read back so that the reference's f64 mirror
    /// and the file-backed media share one type. The voxels' buffer is recorded in `ledger`
    /// as transient; the grid, once uploaded, is counted where it is uploaded.
    pub async fn bake(
        &self,
        gpu: &Gpu,
        ledger: &mut MemoryLedger,
        noise: &CloudNoiseTextures,
        params: &CloudParams,
        dims: UVec3,
        drift: Vec3,
    ) -> Result<DensityGrid, CloudNoiseError> {
        let device = &gpu.device;
        let placement = bake_placement(params, dims);
        let (first_voxel, voxel) = first_voxel_and_size(&placement);
        let count = u64::from(dims.x) * u64::from(dims.y) * u64::from(dims.z);
        let size = 4 * count.max(1);
        let mut desc = storage_descriptor("medium.cloud_bake.voxels", size);
        desc.usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
        let voxels = ledger.buffer_transient(device, &desc)?;
        let bake = BakeParams {
            first_voxel_m: first_voxel.as_vec3().extend(0.0).to_array(),
            voxel_m: voxel.as_vec3().extend(0.0).to_array(),
            dims: [dims.x, dims.y, dims.z, noise.seed],
            drift_m: drift.extend(0.0).to_array(),
        };
        let uniform = |label, contents: &[u8]| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::UNIFORM,
            })
        };
        let cloud = uniform("medium.cloud_bake.cloud", bytemuck::bytes_of(params));
        let bake = uniform("medium.cloud_bake.params", bytemuck::bytes_of(&bake));
        let shape = noise
            .shape
            .create_view(&wgpu::TextureViewDescriptor::default());
        let detail = noise
            .detail
            .create_view(&wgpu::TextureViewDescriptor::default());
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("medium.cloud_bake.bind_group"),
            layout: &self.layout,
            entries: &[
                crate::gpu::bind_entry(0, &cloud),
                crate::gpu::bind_entry(1, &bake),
                crate::gpu::texture_binding(2, &shape),
                crate::gpu::texture_binding(3, &detail),
                crate::gpu::bind_entry(4, &voxels),
            ],
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("medium.cloud_bake.encoder"),
        });
        if count > 0 {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("medium.cloud_bake"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            let groups = dims.map(|d| d.div_ceil(WORKGROUP_EDGE));
            pass.dispatch_workgroups(groups.x, groups.y, groups.z);
        }
        gpu.queue.submit([encoder.finish()]);
        let bytes = read_buffer(gpu, &voxels, 0, size).await?;
        let mut values: Vec<f32> = bytemuck::cast_slice(&bytes).to_vec();
        values.truncate(count as usize);
        Ok(DensityGrid {
            dims,
            values,
            world_from_index: placement,
            density_scale_per_m: 1.0,
            analytic: None,
        })
    }
}

/// The voxel centre (world metres) of voxel `index` of a bake of `dims` voxels, in f32 as
/// `bake_main` computes it.
pub fn bake_voxel_centre(params: &CloudParams, dims: UVec3, index: UVec3) -> Vec3 {
    let (first, voxel) = first_voxel_and_size(&bake_placement(params, dims));
    first.as_vec3() + index.as_vec3() * voxel.as_vec3()
}

/// The generators' and the bake's composed shader modules, for the naga validation test.
pub fn shader_modules() -> Vec<(String, String)> {
    ["medium/cloud_noise_gen.wgsl", "medium/cloud_bake.wgsl"]
        .iter()
        .map(|f| ((*f).to_owned(), shaders::compose(f, &[])))
        .collect()
}
