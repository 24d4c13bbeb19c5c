//! Shared machinery of the techniques that keep a few single-value maps per light texel, each
//! with its own blend: a start depth (MIN), an end depth (MAX), the optical depth (ADD). The
//! exponential shadow map and the Beer shadow map of the 2022 dissertation (chapters 3.2.4 and
//! 3.2.5) are such techniques.
//!
//! A technique of this kind is a [`LightMapsSpec`] and a registry entry: its build shader
//! (`shaders/shadow/<name>_build.wgsl`) imports `shadow/layered_build.wgsl` for the light-facing
//! billboards and defines `fs_build`, writing one `@location` per map; its lookup shader imports
//! `shadow/light_maps.wgsl` (the group-1 bindings: parameters, a bilinear sampler, the maps)
//! and defines `shadow_transmittance`. The spec names each map's format, blend and clear value
//! and the technique parameters the lookup reads (`light_maps.values`).

use super::GpuFuture;
use bytemuck::{Pod, Zeroable};

use super::layered::{
    VolumeBuild, billboard_pipeline_blends, cleared_attachment, draw_particles, lookup_group_head,
    lookup_layout_head, map_texture, texture_entry, uniform_group,
};
use super::{
    BuildInputs, DebugMap, LOOKUP_STAGES, MapKind, ParamSpec, ShadowError, ShadowTechnique,
    TechniqueContext, TechniqueParams,
};
use crate::gpu::{Gpu, MemoryLedger, TargetWrites};
use crate::shaders;

/// The most maps one technique of this kind keeps (bindings 2..2 + MAX_MAPS).
pub const MAX_MAPS: usize = 4;

/// One map: what it holds, how fragments combine into it, and what it starts as.
pub struct MapSpec {
    /// Label suffix and inspector caption ("start depth").
    pub name: &'static str,
    pub format: wgpu::TextureFormat,
    pub blend: wgpu::BlendComponent,
    /// The value before any fragment (1.0 beyond the far bound for a MIN-blended depth).
    pub clear: f64,
    pub kind: MapKind,
}

/// Everything that distinguishes one light-maps technique from another.
pub struct LightMapsSpec {
    pub name: &'static str,
    /// Build shader (under `shaders/`) defining `fs_build`.
    pub build_shader: &'static str,
    /// The maps, in `@location` and binding order.
    pub maps: &'static [MapSpec],
    /// Parameters the lookup reads, in the order of `light_maps.values` (at most 4); unset ones
    /// take their default.
    pub lookup_params: &'static [&'static ParamSpec],
}

impl LightMapsSpec {
    /// The build module, for the naga test.
    pub fn build_shaders(&self) -> Vec<(String, String)> {
        vec![(
            format!("{}.build", self.name),
            shaders::compose(self.build_shader, &[]),
        )]
    }

    /// Bytes of the maps at `resolution_px`, plus the 16-byte uniform.
    pub fn bytes(&self, resolution_px: u32) -> u64 {
        let texels = u64::from(resolution_px) * u64::from(resolution_px);
        16 + self
            .maps
            .iter()
            .map(|m| texels * u64::from(m.format.block_copy_size(None).unwrap_or(4)))
            .sum::<u64>()
    }
}

/// Keep in sync with `LightMapsParams` in shaders/shadow/light_maps.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct LightMapsParams {
    values: [f32; 4],
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![crate::mirror_layout!(
        LightMapsParams,
        "shadow/light_maps.wgsl",
        "LightMapsParams",
        [values]
    )]
}

struct Map {
    view: wgpu::TextureView,
    clear: wgpu::Color,
}

/// A light-maps technique at one configuration.
pub struct LightMaps {
    spec: &'static LightMapsSpec,
    maps: Vec<Map>,
    build_pipeline: wgpu::RenderPipeline,
    build_bind_group: wgpu::BindGroup,
    /// The density volume's draw into the same maps.
    volume: VolumeBuild,
    lookup_layout: wgpu::BindGroupLayout,
    lookup_bind_group: wgpu::BindGroup,
    memory: MemoryLedger,
}

impl LightMaps {
    pub fn new(
        ctx: &TechniqueContext<'_>,
        spec: &'static LightMapsSpec,
        params: &TechniqueParams,
    ) -> Result<Self, ShadowError> {
        assert!(spec.maps.len() <= MAX_MAPS && spec.lookup_params.len() <= 4);
        let gpu = ctx.gpu;
        let device = &gpu.device;
        let name = spec.name;
        let res = params.resolution_px;
        let mut memory = MemoryLedger::for_technique(&gpu.limits, params.memory_limit_bytes);
        let maps = spec
            .maps
            .iter()
            .map(|m| {
                Ok(Map {
                    view: map_texture(
                        &mut memory,
                        device,
                        &format!("{name}.{}", m.name.replace(' ', "_")),
                        m.format,
                        res,
                    )?,
                    clear: wgpu::Color {
                        r: m.clear,
                        g: m.clear,
                        b: m.clear,
                        a: m.clear,
                    },
                })
            })
            .collect::<Result<Vec<_>, ShadowError>>()?;
        let params_buffer = memory.buffer(
            device,
            &wgpu::BufferDescriptor {
                label: Some(&format!("{name}.params")),
                size: std::mem::size_of::<LightMapsParams>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            },
        )?;
        let mut values = [0.0f32; 4];
        for (v, p) in values.iter_mut().zip(spec.lookup_params) {
            *v = params.get(p).unwrap_or(0.0);
        }
        gpu.queue.write_buffer(
            &params_buffer,
            0,
            bytemuck::bytes_of(&LightMapsParams { values }),
        );

        let (build_layout, build_bind_group) = uniform_group(
            device,
            &format!("{name}.build.params"),
            &params_buffer,
            wgpu::ShaderStages::VERTEX_FRAGMENT,
        );
        let module = shaders::module(
            device,
            &format!("{name}.build"),
            &shaders::compose(spec.build_shader, &[]),
        );
        let targets: Vec<_> = spec.maps.iter().map(|m| (m.format, m.blend)).collect();
        let build_pipeline = billboard_pipeline_blends(
            device,
            &format!("{name}.build"),
            &module,
            "fs_build",
            &[Some(ctx.frame_layout), Some(&build_layout)],
            &targets,
        );
        let volume = VolumeBuild::new(
            device,
            &module,
            format!("{name}.build.volume"),
            "fs_build_volume",
            &[ctx.frame_layout, &build_layout],
            &targets,
        );

        let mut lookup_entries = lookup_layout_head();
        for i in 0..spec.maps.len() {
            lookup_entries.push(texture_entry(2 + i as u32, LOOKUP_STAGES));
        }
        let lookup_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(&format!("{name}.lookup.layout")),
            entries: &lookup_entries,
        });
        let sampler = super::map_sampler(device, &format!("{name}.sampler"));
        let mut entries = lookup_group_head(&params_buffer, &sampler);
        for (i, map) in maps.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry {
                binding: 2 + i as u32,
                resource: wgpu::BindingResource::TextureView(&map.view),
            });
        }
        let lookup_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&format!("{name}.lookup.bind_group")),
            layout: &lookup_layout,
            entries: &entries,
        });
        Ok(Self {
            spec,
            maps,
            build_pipeline,
            build_bind_group,
            volume,
            lookup_layout,
            lookup_bind_group,
            memory,
        })
    }
}

impl ShadowTechnique for LightMaps {
    fn name(&self) -> &'static str {
        self.spec.name
    }
    fn channels_used(&self) -> u32 {
        self.maps.len() as u32
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
    fn build<'a>(
        &'a mut self,
        _gpu: &'a Gpu,
        inputs: BuildInputs<'a>,
    ) -> GpuFuture<'a, Result<(), ShadowError>> {
        Box::pin(async move {
            let attachments: Vec<_> = self
                .maps
                .iter()
                .map(|m| cleared_attachment(&m.view, m.clear))
                .collect();
            let label = format!("{}.build", self.spec.name);
            let mut pass = inputs
                .encoder
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some(&label),
                    color_attachments: &attachments,
                    depth_stencil_attachment: None,
                    timestamp_writes: inputs.timer.pass("shadow"),
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
            let formats: Vec<_> = self.spec.maps.iter().map(|m| m.format).collect();
            inputs
                .timer
                .count_fragments(&mut pass, "shadow", TargetWrites::of(&formats), |pass| {
                    draw_particles(
                        pass,
                        &self.build_pipeline,
                        inputs.frame_bind_group,
                        &self.build_bind_group,
                        inputs.particles.slice(..),
                        inputs.particle_count,
                    );
                    if inputs.volume.is_some() {
                        self.volume
                            .draw(pass, inputs.frame_bind_group, &self.build_bind_group);
                    }
                });
            Ok(())
        })
    }
    fn debug_maps(&self) -> Vec<DebugMap<'_>> {
        self.maps
            .iter()
            .zip(self.spec.maps)
            .map(|(m, spec)| DebugMap {
                view: &m.view,
                channels: vec![spec.name.to_owned()],
                kind: spec.kind,
            })
            .collect()
    }
}
