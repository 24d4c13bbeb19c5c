//! `osm`: opacity shadow maps (Kim & Neumann 2001; thesis 3.3.3.2).
//!
//! A budget of B channels is B slices, uniformly spaced over the light-space depth range that is
//! fitted to the particles each frame. Slice k stores the optical depth Ω in front of boundary k;
//! every light-space particle fragment adds its optical depth to each boundary at or beyond its
//! depth (additive blending, no sort). The slices live in ceil(B/4) half-float render targets
//! written together with MRT; the last target has only as many components as it needs (R16F for
//! 1, RG16F for 2, RGBA16F for 3 or 4: there is no 3-component render format, so B ≡ 3 (mod 4)
//! allocates one unused channel, and the memory figure says so). Lookup interpolates linearly
//! between the two boundaries around the point and returns T = exp(-Ω).

use bytemuck::{Pod, Zeroable};

use super::{
    BuildInputs, LOOKUP_STAGES, ShadowError, ShadowTechnique, SplatMode, TechniqueContext,
    TechniqueEntry, TechniqueParams,
};
use crate::gpu::{Gpu, MemoryLedger};
use crate::render::gpu_data::{BILLBOARD_VERTICES, ParticleInstance};
use crate::shaders;

pub const ENTRY: TechniqueEntry = TechniqueEntry {
    name: "osm",
    description: "opacity shadow maps: B uniform depth slices of accumulated optical depth",
    min_channels: 1,
    lookup_shader: "shadow/osm.wgsl",
    extra_shaders: || {
        (1..=super::MAX_CHANNELS.div_ceil(4))
            .map(|targets| {
                (
                    format!("osm.build[{targets} targets]"),
                    build_shader_source(targets),
                )
            })
            .collect()
    },
    create: |ctx, params| Ok(Box::new(Osm::new(ctx, params)?)),
};

/// Lookup bindings for the maps: the shader has 8 texture slots.
const MAP_SLOTS: u32 = 8;

/// Keep in sync with `OsmParams` in shaders/shadow/osm.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct OsmParams {
    slices: u32,
    splat: u32,
    _pad: [u32; 2],
}

pub struct Osm {
    slices: u32,
    targets: Vec<wgpu::TextureView>,
    build_pipeline: wgpu::RenderPipeline,
    build_bind_group: wgpu::BindGroup,
    lookup_layout: wgpu::BindGroupLayout,
    lookup_bind_group: wgpu::BindGroup,
    memory: MemoryLedger,
}

/// Format of render target `index` for `slices` slices.
fn target_format(slices: u32, index: u32) -> wgpu::TextureFormat {
    match (slices - index * 4).min(4) {
        1 => wgpu::TextureFormat::R16Float,
        2 => wgpu::TextureFormat::Rg16Float,
        _ => wgpu::TextureFormat::Rgba16Float,
    }
}

/// The generated fragment entry point writing one vec4 per target.
fn build_outputs_wgsl(targets: u32) -> String {
    let fields: String = (0..targets)
        .map(|i| format!("    @location({i}) t{i}: vec4<f32>,\n"))
        .collect();
    let writes: String = (0..targets)
        .map(|i| format!("    out.t{i} = target_values(splat, {i}u);\n"))
        .collect();
    format!(
        "struct BuildOut {{\n{fields}}};\n\n@fragment\nfn fs_build(in: BuildVertexOut) -> BuildOut {{\n    \
         let splat = splat_fragment(in);\n    var out: BuildOut;\n{writes}    return out;\n}}\n"
    )
}

/// The full build shader for `targets` render targets.
pub fn build_shader_source(targets: u32) -> String {
    shaders::compose("shadow/osm_build.wgsl", &[])
        .replace("//{{BUILD_OUTPUTS}}", &build_outputs_wgsl(targets))
}

impl Osm {
    pub fn new(ctx: &TechniqueContext<'_>, params: &TechniqueParams) -> Result<Self, ShadowError> {
        let gpu = ctx.gpu;
        let device = &gpu.device;
        let slices = params.channels;
        let target_count = slices.div_ceil(4);
        let formats: Vec<_> = (0..target_count)
            .map(|i| target_format(slices, i))
            .collect();
        let bytes_per_sample: u32 = formats
            .iter()
            .map(|f| f.target_pixel_byte_cost().unwrap_or(8))
            .sum();
        if target_count > gpu.limits.max_color_attachments
            || bytes_per_sample > gpu.limits.max_color_attachment_bytes_per_sample
        {
            return Err(ShadowError::AdapterLimit {
                technique: ENTRY.name,
                channels: slices,
                needed: target_count,
                bytes_per_sample,
                allowed_attachments: gpu.limits.max_color_attachments,
                allowed_bytes: gpu.limits.max_color_attachment_bytes_per_sample,
            });
        }

        let mut memory = MemoryLedger::default();
        let res = params.resolution_px;
        let targets: Vec<wgpu::TextureView> = formats
            .iter()
            .enumerate()
            .map(|(i, &format)| {
                memory
                    .texture(
                        device,
                        &wgpu::TextureDescriptor {
                            label: Some(&format!("osm.map{i}")),
                            size: wgpu::Extent3d {
                                width: res,
                                height: res,
                                depth_or_array_layers: 1,
                            },
                            mip_level_count: 1,
                            sample_count: 1,
                            dimension: wgpu::TextureDimension::D2,
                            format,
                            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                                | wgpu::TextureUsages::TEXTURE_BINDING,
                            view_formats: &[],
                        },
                    )
                    .create_view(&wgpu::TextureViewDescriptor::default())
            })
            .collect();

        let params_buffer = memory.buffer(
            device,
            &wgpu::BufferDescriptor {
                label: Some("osm.params"),
                size: std::mem::size_of::<OsmParams>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            },
        );
        let splat = match params.splat {
            SplatMode::Point => 0,
            SplatMode::Segment => 1,
        };
        gpu.queue.write_buffer(
            &params_buffer,
            0,
            bytemuck::bytes_of(&OsmParams {
                slices,
                splat,
                _pad: [0; 2],
            }),
        );

        let uniform_entry = |binding, visibility| wgpu::BindGroupLayoutEntry {
            binding,
            visibility,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };

        // Build pass: group 1 holds only the parameters (the maps are its render targets).
        let build_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("osm.build.layout"),
            entries: &[uniform_entry(0, wgpu::ShaderStages::VERTEX_FRAGMENT)],
        });
        let build_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("osm.build.bind_group"),
            layout: &build_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: params_buffer.as_entire_binding(),
            }],
        });
        let module = shaders::module(device, "osm.build", &build_shader_source(target_count));
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("osm.build.pipeline_layout"),
            bind_group_layouts: &[Some(ctx.frame_layout), Some(&build_layout)],
            immediate_size: 0,
        });
        let additive = wgpu::BlendComponent {
            src_factor: wgpu::BlendFactor::One,
            dst_factor: wgpu::BlendFactor::One,
            operation: wgpu::BlendOperation::Add,
        };
        let color_targets: Vec<_> = formats
            .iter()
            .map(|&format| {
                Some(wgpu::ColorTargetState {
                    format,
                    blend: Some(wgpu::BlendState {
                        color: additive,
                        alpha: additive,
                    }),
                    write_mask: wgpu::ColorWrites::ALL,
                })
            })
            .collect();
        let build_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("osm.build.pipeline"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_build"),
                compilation_options: Default::default(),
                buffers: &[Some(ParticleInstance::LAYOUT)],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_build"),
                compilation_options: Default::default(),
                targets: &color_targets,
            }),
            multiview_mask: None,
            cache: None,
        });

        // Lookup: parameters, a bilinear sampler and 8 map slots (unused slots repeat map 0;
        // the shader never reads a slot beyond ceil(B/4)).
        let mut lookup_entries = vec![
            uniform_entry(0, LOOKUP_STAGES),
            wgpu::BindGroupLayoutEntry {
                binding: 1,
                visibility: LOOKUP_STAGES,
                ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                count: None,
            },
        ];
        lookup_entries.extend((0..MAP_SLOTS).map(|i| wgpu::BindGroupLayoutEntry {
            binding: 2 + i,
            visibility: LOOKUP_STAGES,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: true },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        }));
        let lookup_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("osm.lookup.layout"),
            entries: &lookup_entries,
        });
        let sampler = super::map_sampler(device, "osm.sampler");
        let mut entries = vec![
            wgpu::BindGroupEntry {
                binding: 0,
                resource: params_buffer.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::Sampler(&sampler),
            },
        ];
        entries.extend((0..MAP_SLOTS).map(|i| wgpu::BindGroupEntry {
            binding: 2 + i,
            resource: wgpu::BindingResource::TextureView(
                targets.get(i as usize).unwrap_or(&targets[0]),
            ),
        }));
        let lookup_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("osm.lookup.bind_group"),
            layout: &lookup_layout,
            entries: &entries,
        });

        Ok(Self {
            slices,
            targets,
            build_pipeline,
            build_bind_group,
            lookup_layout,
            lookup_bind_group,
            memory,
        })
    }
}

impl ShadowTechnique for Osm {
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

    fn build(&mut self, _gpu: &Gpu, inputs: BuildInputs<'_>) {
        let attachments: Vec<_> = self
            .targets
            .iter()
            .map(|view| {
                Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })
            })
            .collect();
        let mut pass = inputs
            .encoder
            .begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("osm.build"),
                color_attachments: &attachments,
                depth_stencil_attachment: None,
                timestamp_writes: inputs.timer.pass("shadow"),
                occlusion_query_set: None,
                multiview_mask: None,
            });
        if inputs.particle_count > 0 {
            pass.set_pipeline(&self.build_pipeline);
            pass.set_bind_group(0, inputs.frame_bind_group, &[]);
            pass.set_bind_group(1, &self.build_bind_group, &[]);
            pass.set_vertex_buffer(0, inputs.particles.slice(..));
            pass.draw(0..BILLBOARD_VERTICES, 0..inputs.particle_count);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn target_formats_fit_the_budget() {
        assert_eq!(target_format(6, 0), wgpu::TextureFormat::Rgba16Float);
        assert_eq!(target_format(6, 1), wgpu::TextureFormat::Rg16Float);
        assert_eq!(target_format(5, 1), wgpu::TextureFormat::R16Float);
        assert_eq!(target_format(7, 1), wgpu::TextureFormat::Rgba16Float);
        assert_eq!(target_format(24, 5), wgpu::TextureFormat::Rgba16Float);
    }
}
