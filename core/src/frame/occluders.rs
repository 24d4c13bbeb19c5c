//! Opaque occluders in the light: the ground and the boxes cast shadows onto the smoke and onto
//! each other (the thesis' future work, chapter 5: "handle opaque polygons in the volumetric
//! shadow maps").
//!
//! Each frame, before the technique's build, the opaque mesh is rasterised from the spotlight
//! into a depth map (`shaders/render/occluder_map.wgsl`) of the scene's
//! `shadow.occluder_resolution_px`: the radial distance from the light to the nearest *back*
//! face (the faces turned towards the light are culled, so a lit face is never compared with
//! itself). The lighting shaders multiply the technique's T(p) by `occluder_visibility(p)`:
//! every technique reads the map through `shaders/common/occluders_map.wgsl` (3x3 bilinear
//! comparison taps, PCF), while the reference `exact` tests the boxes and the ground analytically
//! (`shaders/common/occluders_exact.wgsl`), an opaque hit being T = 0. Both read group 0: the
//! map (binding 1), its comparison sampler (2) and the boxes (3), which [`Occluders`] owns.
//! Its bytes are its own ledger's, reported apart from the technique's.

use glam::{Mat4, Vec3};

use super::gpu_data::OccluderBox;
use crate::gpu::{AllocationError, Gpu, GpuTimer, MemoryLedger};
use crate::scene::Scene;
use crate::shaders;

pub use crate::scene::MAX_BOXES;

/// Loop iterations the exact occluder test takes at most: one per box and the loop's exit.
pub const OCCLUDER_LOOP_RESERVE: u32 = MAX_BOXES as u32 + 1;

/// Format of the occluders' depth map.
pub const OCCLUDER_MAP_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The occluders' depth map, the boxes for the exact test, and the pass that draws the map.
pub struct Occluders {
    resolution_px: u32,
    /// Whether the lighting reads the map; the reference tests the boxes exactly instead, and
    /// gets a 1x1 placeholder the pass never draws.
    uses_map: bool,
    map_view: wgpu::TextureView,
    sampler: wgpu::Sampler,
    boxes: wgpu::Buffer,
    box_capacity: u64,
    pipeline: wgpu::RenderPipeline,
    /// Group 0 of the map's own pass: the frame uniforms alone (the frame's full group 0 holds
    /// the map itself, which this pass writes).
    uniform_bind_group: wgpu::BindGroup,
    memory: MemoryLedger,
}

impl Occluders {
    /// The map at `resolution_px` and room for one box; `frame_buffer` is the frame's uniforms.
    pub fn new(
        gpu: &Gpu,
        frame_buffer: &wgpu::Buffer,
        resolution_px: u32,
    ) -> Result<Self, AllocationError> {
        let device = &gpu.device;
        let uniform_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("occluders.uniform_layout"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let uniform_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("occluders.uniform_bind_group"),
            layout: &uniform_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: frame_buffer.as_entire_binding(),
            }],
        });
        let module = shaders::module(
            device,
            "occluder_map",
            &shaders::compose("render/occluder_map.wgsl", &[]),
        );
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("occluders.pipeline_layout"),
            bind_group_layouts: &[Some(&uniform_layout)],
            immediate_size: 0,
        });
        // Back faces only: see the module docs.
        let pipeline = super::geometry::mesh_pipeline(
            device,
            "occluders.pipeline",
            &module,
            &layout,
            wgpu::Face::Front,
            OCCLUDER_MAP_FORMAT,
            &[],
        );
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("occluders.sampler"),
            address_mode_u: wgpu::AddressMode::ClampToEdge,
            address_mode_v: wgpu::AddressMode::ClampToEdge,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            compare: Some(wgpu::CompareFunction::LessEqual),
            ..Default::default()
        });
        let mut memory = MemoryLedger::for_device(&device.limits());
        let map_view =
            map_texture(gpu, &mut memory, resolution_px)?.create_view(&Default::default());
        let boxes = box_buffer(gpu, &mut memory, 1)?;
        Ok(Self {
            resolution_px,
            uses_map: true,
            map_view,
            sampler,
            boxes,
            box_capacity: 1,
            pipeline,
            uniform_bind_group,
            memory,
        })
    }

    /// Makes the map `scene`'s resolution (1x1 when the lighting does not read it: `uses_map`
    /// false) and uploads its boxes. True when a resource was replaced, so that the frame's
    /// group 0 must be bound anew.
    pub fn prepare(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        uses_map: bool,
    ) -> Result<bool, AllocationError> {
        let mut replaced = false;
        self.uses_map = uses_map;
        let resolution_px = if uses_map {
            scene.shadow.occluder_resolution_px
        } else {
            1
        };
        if resolution_px != self.resolution_px {
            let mut memory = MemoryLedger::for_device(&gpu.device.limits());
            let map = map_texture(gpu, &mut memory, resolution_px)?;
            let boxes = box_buffer(gpu, &mut memory, self.box_capacity)?;
            (self.map_view, self.boxes, self.memory) =
                (map.create_view(&Default::default()), boxes, memory);
            self.resolution_px = resolution_px;
            replaced = true;
        }
        let boxes = boxes_of(scene);
        if boxes.len() as u64 > self.box_capacity {
            let capacity = (boxes.len() as u64).next_power_of_two();
            self.memory.forget("occluders.boxes");
            self.boxes = box_buffer(gpu, &mut self.memory, capacity)?;
            self.box_capacity = capacity;
            replaced = true;
        }
        if !boxes.is_empty() {
            gpu.queue
                .write_buffer(&self.boxes, 0, bytemuck::cast_slice(&boxes));
        }
        Ok(replaced)
    }

    /// The frame's group-0 entries after the uniforms: the map, its sampler, the boxes.
    pub fn frame_entries(&self) -> [wgpu::BindGroupEntry<'_>; 3] {
        [
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(&self.map_view),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::Sampler(&self.sampler),
            },
            wgpu::BindGroupEntry {
                binding: 3,
                resource: self.boxes.as_entire_binding(),
            },
        ]
    }

    /// Side of the map the lighting reads, `None` when it reads none (the reference).
    pub fn map_px(&self) -> Option<u32> {
        self.uses_map.then_some(self.resolution_px)
    }

    /// Records the map's pass ("occluders") over the opaque mesh's `vertex_count` vertices;
    /// nothing when the lighting does not read the map.
    pub fn record(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut GpuTimer,
        vertices: &wgpu::Buffer,
        vertex_count: u32,
    ) {
        if !self.uses_map {
            return;
        }
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("occluders"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.map_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: timer.pass("occluders"),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        if vertex_count > 0 {
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.uniform_bind_group, &[]);
            pass.set_vertex_buffer(0, vertices.slice(..));
            pass.draw(0..vertex_count, 0..1);
        }
    }

    /// What the map and the boxes occupy.
    pub fn memory(&self) -> &MemoryLedger {
        &self.memory
    }
}

/// The group-0 layout entries [`Occluders::frame_entries`] fill.
pub fn frame_layout_entries() -> [wgpu::BindGroupLayoutEntry; 3] {
    let stages = wgpu::ShaderStages::FRAGMENT.union(wgpu::ShaderStages::COMPUTE);
    [
        wgpu::BindGroupLayoutEntry {
            binding: 1,
            visibility: stages,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Depth,
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        },
        wgpu::BindGroupLayoutEntry {
            binding: 2,
            visibility: stages,
            ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Comparison),
            count: None,
        },
        wgpu::BindGroupLayoutEntry {
            binding: 3,
            visibility: stages,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: true },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        },
    ]
}

/// The light's projection for the map: `view_from_world` and the field of view of the light's
/// own projection (so a point lands at the same map coordinates as in every technique's maps),
/// with the near and far planes around the opaque geometry. Returns it and the far distance the
/// map's depths are divided by (metres).
pub fn clip_from_world(scene: &Scene, view_from_world: Mat4, tan_half_fov: f32) -> (Mat4, f32) {
    let light = scene.light.position;
    let far_m = opaque_corners(scene)
        .map(|c| c.distance(light))
        .fold(1.0f32, f32::max)
        * 1.01;
    let proj = Mat4::perspective_rh(2.0 * tan_half_fov.atan(), 1.0, 1e-3 * far_m, far_m);
    (proj * view_from_world, far_m)
}

/// The length below which the exact occluder test (`shaders/common/occluders_exact.wgsl` and its
/// CPU mirror `shadow::closed_form::occluder_visibility`) takes a point to lie on a surface: a hit
/// closer than this to the point is its own surface, and so is the ground plane for a point this
/// close to it. It follows the scene's scale: 1e-4 of `smoke_far_m` (the farthest smoke's
/// distance from the light), so a 1 cm puff and a 1 km cloud are treated alike; and it is never
/// under 32 float steps (2^-18 relative) of the light's largest coordinate, so smoke far from
/// the origin, where positions round coarsely, is not shadowed by rounding either.
pub fn epsilon_m(light_position: Vec3, smoke_far_m: f32) -> f32 {
    let scale = 1e-4 * smoke_far_m.max(0.0);
    let rounding = light_position.abs().max_element() * (2.0f32).powi(-18);
    scale.max(rounding).max(f32::MIN_POSITIVE)
}

/// Every corner of the ground square and of the boxes.
fn opaque_corners(scene: &Scene) -> impl Iterator<Item = Vec3> + '_ {
    let g = &scene.ground;
    let h = g.size_m * 0.5;
    let ground = [(-h, -h), (-h, h), (h, -h), (h, h)].map(|(x, z)| Vec3::new(x, g.height_m, z));
    let boxes = scene.boxes.iter().flat_map(|b| {
        (0..8).map(move |i| {
            let s = Vec3::new(
                if i & 1 == 0 { -0.5 } else { 0.5 },
                if i & 2 == 0 { -0.5 } else { 0.5 },
                if i & 4 == 0 { -0.5 } else { 0.5 },
            );
            b.center + b.size * s
        })
    });
    ground.into_iter().chain(boxes)
}

fn boxes_of(scene: &Scene) -> Vec<OccluderBox> {
    scene
        .boxes
        .iter()
        .map(|b| OccluderBox {
            min: (b.center - b.size * 0.5).extend(0.0).to_array(),
            max: (b.center + b.size * 0.5).extend(0.0).to_array(),
        })
        .collect()
}

fn map_texture(
    gpu: &Gpu,
    memory: &mut MemoryLedger,
    resolution_px: u32,
) -> Result<wgpu::Texture, AllocationError> {
    memory.texture(
        &gpu.device,
        &crate::gpu::texture_2d_descriptor(
            "occluders.map",
            (resolution_px, resolution_px),
            OCCLUDER_MAP_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        ),
    )
}

fn box_buffer(
    gpu: &Gpu,
    memory: &mut MemoryLedger,
    capacity: u64,
) -> Result<wgpu::Buffer, AllocationError> {
    memory.buffer(
        &gpu.device,
        &wgpu::BufferDescriptor {
            label: Some("occluders.boxes"),
            size: capacity * std::mem::size_of::<OccluderBox>() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        },
    )
}
