//! Full-screen passes: one triangle over the target that reads one texture, as the tone map,
//! half-angle slicing's composite of its eye buffer and the viewer's map inspector draw.

/// An unfilterable 2D float texture at `binding`, read by the fragment stage (texels are
/// loaded, not sampled).
pub fn texture_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    crate::gpu::texture_entry(
        binding,
        wgpu::ShaderStages::FRAGMENT,
        wgpu::TextureSampleType::Float { filterable: false },
    )
}

/// A layout with one [`texture_entry`] at binding 0.
pub fn texture_layout(device: &wgpu::Device, label: &str) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &[texture_entry(0)],
    })
}

/// A full-screen pipeline: `vertex` draws the triangle (no vertex buffers), `fragment` writes
/// `target`.
pub fn pipeline(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    (vertex, fragment): (&str, &str),
    layouts: &[Option<&wgpu::BindGroupLayout>],
    target: wgpu::ColorTargetState,
) -> wgpu::RenderPipeline {
    pipeline_with(
        device,
        label,
        module,
        (vertex, fragment),
        layouts,
        &[Some(target)],
        None,
    )
}

/// [`pipeline`] writing `targets` (none for a depth-only pass) and `depth_stencil`.
pub fn pipeline_with(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    (vertex, fragment): (&str, &str),
    layouts: &[Option<&wgpu::BindGroupLayout>],
    targets: &[Option<wgpu::ColorTargetState>],
    depth_stencil: Option<wgpu::DepthStencilState>,
) -> wgpu::RenderPipeline {
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: layouts,
        immediate_size: 0,
    });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some(vertex),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil,
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some(fragment),
            compilation_options: Default::default(),
            targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}
