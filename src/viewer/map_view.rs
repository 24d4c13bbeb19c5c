//! The inspector's picture of one shadow-map channel (`shaders/render/map_view.wgsl`): a small
//! render pass from the technique's map texture into an sRGB image the UI shows.

use bytemuck::{Pod, Zeroable};

use smokeshadow_core::shaders;
use smokeshadow_core::shadow::MapKind;

/// Keep in sync with `MapViewParams` in shaders/render/map_view.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct MapViewParams {
    component: u32,
    kind: u32,
    scale: f32,
    _pad: u32,
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<smokeshadow_core::gpu::MirrorLayout> {
    vec![smokeshadow_core::mirror_layout!(
        MapViewParams,
        "render/map_view.wgsl",
        "MapViewParams",
        [component, kind, scale]
    )]
}

/// Format of the inspector image.
pub const MAP_VIEW_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

pub struct MapView {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    params: wgpu::Buffer,
}

impl MapView {
    pub fn new(device: &wgpu::Device) -> Self {
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("map_view.layout"),
            entries: &[
                smokeshadow_core::frame::fullscreen::texture_entry(0),
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ],
        });
        let module = shaders::module(
            device,
            "map_view",
            &shaders::compose("render/map_view.wgsl", &[]),
        );
        let pipeline = smokeshadow_core::frame::fullscreen::pipeline(
            device,
            "map_view.pipeline",
            &module,
            ("vs_main", "fs_main"),
            &[Some(&layout)],
            MAP_VIEW_FORMAT.into(),
        );
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("map_view.params"),
            size: std::mem::size_of::<MapViewParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self {
            layout,
            pipeline,
            params,
        }
    }

    /// Draws `component` of `source` (of `kind`, values times `scale`) into `target`.
    #[allow(clippy::too_many_arguments)]
    pub fn draw(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        source: &wgpu::TextureView,
        component: u32,
        kind: MapKind,
        scale: f32,
        target: &wgpu::TextureView,
    ) {
        queue.write_buffer(
            &self.params,
            0,
            bytemuck::bytes_of(&MapViewParams {
                component: component.min(3),
                kind: match kind {
                    MapKind::OpticalDepth => 0,
                    MapKind::Depth01 => 1,
                    MapKind::Signed => 2,
                },
                scale,
                _pad: 0,
            }),
        );
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("map_view.bind_group"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(source),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: self.params.as_entire_binding(),
                },
            ],
        });
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("map_view"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}
