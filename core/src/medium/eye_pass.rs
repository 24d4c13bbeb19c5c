//! The eye's pass over the density volume in the frame (`shaders/render/volume_eye.wgsl`):
//! after the opaque pass, each pixel's ray is marched front to back over the part of it the
//! grid covers, up to the opaque surface, with the light's transmittance from the active
//! technique's `shadow_transmittance`, exactly as the particles are lit; the result is laid
//! "over" the frame, and the particles are drawn over it after (the docs' "Compositing").
//!
//! The march runs in rounds of `stride` eye steps. In each, `eye_light` makes one lookup per
//! invocation (a sample with density: V·T into the round's light buffer), so that no lookup's
//! loops share an invocation with another's (llvmpipe's loop budget), and `eye_accumulate`
//! folds the round's samples into each pixel's running radiance and transmittance.

use bytemuck::{Pod, Zeroable};

use crate::frame::{HDR_FORMAT, OVER};
use crate::gpu::{AllocationError, Gpu, GpuTimer, MemoryLedger, storage_descriptor, storage_entry};
use crate::shaders;

/// Light-buffer slots (f32) the rounds may take at most: 32 MiB.
const LIGHT_SLOTS: u64 = 8 << 20;
/// Invocations per workgroup of both kernels.
const WORKGROUP: u64 = 64;
/// Most workgroups along one dispatch dimension.
const MAX_GROUPS_X: u64 = 65_535;
/// Bytes between rounds' uniforms (the dynamic offset alignment every adapter accepts).
const ROUND_STRIDE: u64 = 256;

/// Keep in sync with `EyeRound` in shaders/render/volume_eye.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct EyeRound {
    first: u32,
    steps: u32,
    stride: u32,
    _pad: u32,
}

/// The WGSL structs mirrored here.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![crate::mirror_layout!(
        EyeRound,
        "render/volume_eye.wgsl",
        "EyeRound",
        [first, steps, stride]
    )]
}

/// The pass's own bind group layouts (group 2): the march's and the composite's.
pub struct EyeLayouts {
    march: wgpu::BindGroupLayout,
    composite: wgpu::BindGroupLayout,
}

impl EyeLayouts {
    pub fn new(device: &wgpu::Device) -> Self {
        let compute = wgpu::ShaderStages::COMPUTE;
        let march = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("volume_eye.march_layout"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: compute,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: true,
                        min_binding_size: wgpu::BufferSize::new(
                            std::mem::size_of::<EyeRound>() as u64
                        ),
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: compute,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                storage_entry(2, compute, false),
                storage_entry(3, compute, false),
            ],
        });
        let composite = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("volume_eye.composite_layout"),
            entries: &[storage_entry(4, wgpu::ShaderStages::FRAGMENT, true)],
        });
        Self { march, composite }
    }
}

/// The pass's pipelines for one technique (they call its lookup).
pub struct EyePipelines {
    light: wgpu::ComputePipeline,
    accumulate: wgpu::ComputePipeline,
    composite: wgpu::RenderPipeline,
}

/// The eye pass' module composed with a technique's frame imports (its lookup, the occluders).
pub fn source(imports: &[(&str, &str)]) -> String {
    shaders::compose("render/volume_eye.wgsl", imports)
}

impl EyePipelines {
    pub fn new(
        device: &wgpu::Device,
        name: &str,
        frame_layout: &wgpu::BindGroupLayout,
        technique_layout: &wgpu::BindGroupLayout,
        imports: &[(&str, &str)],
        layouts: &EyeLayouts,
    ) -> Self {
        let module = shaders::module(device, &format!("volume_eye[{name}]"), &source(imports));
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("volume_eye.pipeline_layout"),
            bind_group_layouts: &[
                Some(frame_layout),
                Some(technique_layout),
                Some(&layouts.march),
            ],
            immediate_size: 0,
        });
        let compute = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let composite = crate::frame::fullscreen::pipeline(
            device,
            "volume_eye.composite",
            &module,
            ("vs_composite", "fs_composite"),
            &[Some(frame_layout), None, Some(&layouts.composite)],
            wgpu::ColorTargetState {
                format: HDR_FORMAT,
                blend: Some(wgpu::BlendState {
                    color: OVER,
                    alpha: OVER,
                }),
                write_mask: wgpu::ColorWrites::ALL,
            },
        );
        Self {
            light: compute("eye_light"),
            accumulate: compute("eye_accumulate"),
            composite,
        }
    }
}

/// The pass's buffers for one frame size and step count.
pub struct EyeTargets {
    key: (u32, u32, u32),
    rounds: u32,
    stride: u32,
    pixels: u64,
    march: wgpu::BindGroup,
    composite: wgpu::BindGroup,
    ledger: MemoryLedger,
}

impl EyeTargets {
    /// Buffers for `width` x `height` pixels and `eye_steps` steps, reading `depth_view`.
    pub fn new(
        gpu: &Gpu,
        layouts: &EyeLayouts,
        depth_view: &wgpu::TextureView,
        (width, height): (u32, u32),
        eye_steps: u32,
    ) -> Result<Self, AllocationError> {
        let device = &gpu.device;
        let pixels = u64::from(width) * u64::from(height);
        let stride = (LIGHT_SLOTS / pixels.max(1)).clamp(1, u64::from(eye_steps)) as u32;
        let rounds = eye_steps.div_ceil(stride);
        let mut ledger = MemoryLedger::for_device(&gpu.limits);
        let light = ledger.buffer(
            device,
            &storage_descriptor("volume_eye.light", 4 * pixels * u64::from(stride)),
        )?;
        let state = ledger.buffer(device, &storage_descriptor("volume_eye.state", 16 * pixels))?;
        let mut uniforms = vec![0u8; (ROUND_STRIDE * u64::from(rounds)) as usize];
        for r in 0..rounds {
            let first = r * stride;
            let round = EyeRound {
                first,
                steps: stride.min(eye_steps - first),
                stride,
                _pad: 0,
            };
            let at = (ROUND_STRIDE * u64::from(r)) as usize;
            uniforms[at..at + std::mem::size_of::<EyeRound>()]
                .copy_from_slice(bytemuck::bytes_of(&round));
        }
        let round_buffer = ledger.buffer(
            device,
            &wgpu::BufferDescriptor {
                label: Some("volume_eye.rounds"),
                size: uniforms.len() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            },
        )?;
        gpu.queue.write_buffer(&round_buffer, 0, &uniforms);
        let march = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("volume_eye.march"),
            layout: &layouts.march,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &round_buffer,
                        offset: 0,
                        size: wgpu::BufferSize::new(std::mem::size_of::<EyeRound>() as u64),
                    }),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(depth_view),
                },
                crate::gpu::bind_entry(2, &light),
                crate::gpu::bind_entry(3, &state),
            ],
        });
        let composite = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("volume_eye.composite"),
            layout: &layouts.composite,
            entries: &[crate::gpu::bind_entry(4, &state)],
        });
        Ok(Self {
            key: (width, height, eye_steps),
            rounds,
            stride,
            pixels,
            march,
            composite,
            ledger,
        })
    }

    /// Whether these buffers serve `size` and `eye_steps`.
    pub fn fits(&self, (width, height): (u32, u32), eye_steps: u32) -> bool {
        self.key == (width, height, eye_steps)
    }

    /// Bytes the pass's buffers take.
    pub fn bytes(&self) -> u64 {
        self.ledger.total_bytes()
    }

    /// Rounds of the march, and eye steps per round.
    pub fn rounds(&self) -> (u32, u32) {
        (self.rounds, self.stride)
    }
}

/// A dispatch of `invocations` laid out over x and y (`linear_id` in the shader).
fn dispatch(pass: &mut wgpu::ComputePass<'_>, invocations: u64) {
    let groups = invocations.div_ceil(WORKGROUP).max(1);
    let x = groups.min(MAX_GROUPS_X);
    pass.dispatch_workgroups(x as u32, groups.div_ceil(x) as u32, 1);
}

/// One light space's bindings: its group 0 and the technique's lookup group.
pub struct EyeFace<'a> {
    pub frame: &'a wgpu::BindGroup,
    pub technique: &'a wgpu::BindGroup,
}

/// Records the march's rounds (timed as "volume") and the composite over `hdr_view`. The
/// first face's group 0 serves the passes that light nothing.
pub fn record(
    encoder: &mut wgpu::CommandEncoder,
    timer: &mut GpuTimer,
    pipelines: &EyePipelines,
    targets: &EyeTargets,
    faces: &[EyeFace<'_>],
    hdr_view: &wgpu::TextureView,
) {
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("volume_eye.march"),
            timestamp_writes: timer.compute_pass(PASS_NAME),
        });
        for r in 0..targets.rounds {
            let offset = (ROUND_STRIDE * u64::from(r)) as u32;
            let steps = u64::from(targets.stride.min(targets.key.2 - r * targets.stride));
            pass.set_pipeline(&pipelines.light);
            pass.set_bind_group(2, &targets.march, &[offset]);
            for face in faces {
                pass.set_bind_group(0, face.frame, &[]);
                pass.set_bind_group(1, face.technique, &[]);
                dispatch(&mut pass, targets.pixels * steps);
            }
            pass.set_pipeline(&pipelines.accumulate);
            pass.set_bind_group(0, faces[0].frame, &[]);
            pass.set_bind_group(1, faces[0].technique, &[]);
            dispatch(&mut pass, targets.pixels);
        }
    }
    let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("volume_eye.composite"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: hdr_view,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Load,
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: None,
        timestamp_writes: timer.pass(PASS_NAME),
        occlusion_query_set: None,
        multiview_mask: None,
    });
    pass.set_pipeline(&pipelines.composite);
    pass.set_bind_group(0, faces[0].frame, &[]);
    pass.set_bind_group(2, &targets.composite, &[]);
    pass.draw(0..3, 0..1);
}

/// The pass's name in the frame's pass times.
pub const PASS_NAME: &str = "volume";
