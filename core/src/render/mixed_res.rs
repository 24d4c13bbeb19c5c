//! Mixed-resolution particles (issue 14 §3; the thesis' future work, after Jansen & Bavoil 2011,
//! "Fast rendering of opacity-mapped particles using DirectX 11 tessellation and mixed
//! resolutions", NVIDIA's smokeParticles sample, and the low-resolution rendering with bilateral
//! upsampling in Yusov's slides).
//!
//! The particle pass is fill-bound: at [`ParticleRes::Half`] it draws a quarter of the
//! fragments. With a [`ParticleRes`] below 1 the frame records three passes where the particle
//! pass was:
//! 1. `downsample`: the opaque depth reduced to the low resolution, each texel the nearest depth
//!    of its D x D block (why the nearest: `shaders/render/mixed_res.wgsl`);
//! 2. `particles`: the same billboards and pipelines as at full resolution, into a cleared
//!    premultiplied HDR target 1/D the size, clipped against that depth (spherical billboards)
//!    or depth-tested against it (flat ones); its alpha accumulates the smoke's opacity;
//! 3. `upsample`: a full-screen pass composites it "over" the full-resolution frame, each pixel
//!    taking the low-resolution texels that saw its own surface (bilateral in depth, with a
//!    nearest-depth fallback), so the frame's alpha still ends up holding the smoke's opacity.
//!
//! Full resolution records the particle pass exactly as before (bit-identical frames). `has`
//! draws its own particle pass and refuses other resolutions
//! ([`crate::shadow::ShadowError::ParticleResUnsupported`]).

use std::fmt;
use std::str::FromStr;

use bytemuck::{Pod, Zeroable};

use crate::frame::{DEPTH_FORMAT, HDR_FORMAT, OVER, fullscreen};
use crate::shaders;

/// The resolution of the particle pass relative to the frame, per axis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ParticleRes {
    /// The frame's own resolution (the thesis; the default).
    #[default]
    Full,
    /// Half the width and height: a quarter of the fragments.
    Half,
    /// A quarter of the width and height: a sixteenth of the fragments.
    Quarter,
}

impl ParticleRes {
    /// Every resolution, finest first.
    pub const ALL: [ParticleRes; 3] = [Self::Full, Self::Half, Self::Quarter];

    /// Frame pixels per particle-pass texel along each axis.
    pub fn divisor(self) -> u32 {
        match self {
            Self::Full => 1,
            Self::Half => 2,
            Self::Quarter => 4,
        }
    }

    /// As the CLI spells it: `1`, `1/2`, `1/4`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Full => "1",
            Self::Half => "1/2",
            Self::Quarter => "1/4",
        }
    }

    /// The low-resolution target's size for a `width` x `height` frame (rounded up, so every
    /// frame pixel has a texel).
    pub fn low_size(self, width: u32, height: u32) -> (u32, u32) {
        let d = self.divisor();
        (width.div_ceil(d).max(1), height.div_ceil(d).max(1))
    }
}

impl fmt::Display for ParticleRes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ParticleRes {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|r| r.name() == s.trim())
            .ok_or_else(|| {
                format!("\"{s}\" is not a particle resolution: allowed 1, 1/2, 1/4 (of the frame's, per axis)")
            })
    }
}

/// Parses `--particle-res` (clap's value parser).
pub fn parse_particle_res(s: &str) -> Result<ParticleRes, String> {
    s.parse()
}

impl serde::Serialize for ParticleRes {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for ParticleRes {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let s = String::deserialize(deserializer)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

/// Keep in sync with `MixedRes` in shaders/render/mixed_res.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct MixedResUniforms {
    pub divisor: u32,
    pub depth_tolerance: f32,
    pub pad0: u32,
    pub pad1: u32,
}

/// The layouts of this module's WGSL mirrors, for the naga check.
pub fn layouts() -> Vec<crate::gpu::MirrorLayout> {
    vec![crate::mirror_layout!(
        MixedResUniforms,
        "render/mixed_res.wgsl",
        "MixedRes",
        [divisor, depth_tolerance, pad0, pad1]
    )]
}

/// Relative view-depth difference under which a low-resolution texel counts as seeing a
/// pixel's surface. The thesis scene's silhouettes (the box against the ground 2-6 m behind it,
/// the ground against the background) differ by far more; a block of ground seen at a grazing
/// angle spans a few per cent of its depth at 1/4 resolution, which stays within it.
pub const DEPTH_TOLERANCE: f32 = 0.05;

/// The downsample and upsample pipelines (long-lived; built on the first mixed-resolution frame).
pub(super) struct MixedResPipelines {
    downsample_layout: wgpu::BindGroupLayout,
    upsample_layout: wgpu::BindGroupLayout,
    pub downsample: wgpu::RenderPipeline,
    pub upsample: wgpu::RenderPipeline,
}

/// The frame pixels the smoke can cover, as a scissor rectangle `[x, y, width, height]`: the
/// union of every particle sphere's screen bounds (the eight corners of its view-aligned
/// bounding cube, projected: the sphere's projection lies within theirs), widened by
/// `margin_px`. The whole frame when a sphere reaches the camera's near plane; `None` when no
/// particle is in view. The upsample reads nothing but cleared texels outside it, so
/// scissoring it there leaves the frame unchanged.
pub fn smoke_rect(
    camera: &crate::frame::CameraMatrices,
    near_m: f32,
    particles: &[crate::sim::Particle],
    (width, height): (u32, u32),
    margin_px: u32,
) -> Option<[u32; 4]> {
    use rayon::prelude::*;
    let clip_from_view = camera.clip_from_view;
    let view_from_world = camera.view_from_world;
    let (w, h) = (width as f32, height as f32);
    // (min x, min y, max x, max y) in pixels, or everything when a sphere is at the eye.
    let bounds = particles
        .par_iter()
        .map(|p| {
            let c = view_from_world.transform_point3(p.position);
            let r = p.radius_m;
            if -(c.z + r) <= near_m {
                return [
                    f32::NEG_INFINITY,
                    f32::NEG_INFINITY,
                    f32::INFINITY,
                    f32::INFINITY,
                ];
            }
            let mut b = [
                f32::INFINITY,
                f32::INFINITY,
                f32::NEG_INFINITY,
                f32::NEG_INFINITY,
            ];
            for i in 0..8 {
                let corner = c + glam::Vec3::new(
                    if i & 1 == 0 { -r } else { r },
                    if i & 2 == 0 { -r } else { r },
                    if i & 4 == 0 { -r } else { r },
                );
                let ndc = clip_from_view.project_point3(corner);
                let (x, y) = ((ndc.x * 0.5 + 0.5) * w, (0.5 - ndc.y * 0.5) * h);
                b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
            }
            b
        })
        .reduce(
            || {
                [
                    f32::INFINITY,
                    f32::INFINITY,
                    f32::NEG_INFINITY,
                    f32::NEG_INFINITY,
                ]
            },
            |a, b| {
                [
                    a[0].min(b[0]),
                    a[1].min(b[1]),
                    a[2].max(b[2]),
                    a[3].max(b[3]),
                ]
            },
        );
    let margin = margin_px as f32;
    let x0 = (bounds[0] - margin).floor().clamp(0.0, w) as u32;
    let y0 = (bounds[1] - margin).floor().clamp(0.0, h) as u32;
    let x1 = (bounds[2] + margin).ceil().clamp(0.0, w) as u32;
    let y1 = (bounds[3] + margin).ceil().clamp(0.0, h) as u32;
    (x1 > x0 && y1 > y0).then(|| [x0, y0, x1 - x0, y1 - y0])
}

fn depth_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Depth,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

fn uniform_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

impl MixedResPipelines {
    pub fn new(device: &wgpu::Device, frame_layout: &wgpu::BindGroupLayout) -> Self {
        let module = shaders::module(
            device,
            "mixed_res",
            &shaders::compose("render/mixed_res.wgsl", &[]),
        );
        let downsample_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("mixed_res.downsample.layout"),
            entries: &[depth_entry(0), uniform_entry(3)],
        });
        let upsample_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("mixed_res.upsample.layout"),
            entries: &[
                depth_entry(0),
                depth_entry(1),
                fullscreen::texture_entry(2),
                uniform_entry(3),
            ],
        });
        let pipeline = |label: &str,
                        group: &wgpu::BindGroupLayout,
                        fragment: &str,
                        targets: &[Option<wgpu::ColorTargetState>],
                        depth_stencil: Option<wgpu::DepthStencilState>| {
            fullscreen::pipeline_with(
                device,
                label,
                &module,
                ("vs_main", fragment),
                &[Some(frame_layout), Some(group)],
                targets,
                depth_stencil,
            )
        };
        let downsample = pipeline(
            "mixed_res.downsample.pipeline",
            &downsample_layout,
            "fs_downsample",
            &[],
            Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Always),
                stencil: Default::default(),
                bias: Default::default(),
            }),
        );
        let upsample = pipeline(
            "mixed_res.upsample.pipeline",
            &upsample_layout,
            "fs_upsample",
            &[Some(wgpu::ColorTargetState {
                format: HDR_FORMAT,
                blend: Some(wgpu::BlendState {
                    color: OVER,
                    alpha: OVER,
                }),
                write_mask: wgpu::ColorWrites::ALL,
            })],
            None,
        );
        Self {
            downsample_layout,
            upsample_layout,
            downsample,
            upsample,
        }
    }
}

/// The low-resolution targets of one frame size and [`ParticleRes`].
pub(super) struct LowResTargets {
    pub res: ParticleRes,
    /// The full-resolution frame size they were made for.
    pub frame_size: (u32, u32),
    pub color_view: wgpu::TextureView,
    pub depth_view: wgpu::TextureView,
    /// The low-resolution depth as the particle pass's group 2 (spherical billboards).
    pub depth_bind_group: wgpu::BindGroup,
    pub downsample_bind_group: wgpu::BindGroup,
    pub upsample_bind_group: wgpu::BindGroup,
}

impl LowResTargets {
    pub fn new(
        device: &wgpu::Device,
        pipelines: &MixedResPipelines,
        particle_depth_layout: &wgpu::BindGroupLayout,
        full_depth: &wgpu::TextureView,
        frame_size: (u32, u32),
        res: ParticleRes,
    ) -> Self {
        let (width, height) = res.low_size(frame_size.0, frame_size.1);
        let texture = |label, format| {
            device.create_texture(&crate::gpu::texture_2d_descriptor(
                label,
                (width, height),
                format,
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            ))
        };
        let color_view = texture("mixed_res.hdr", HDR_FORMAT).create_view(&Default::default());
        let depth_view = texture("mixed_res.depth", DEPTH_FORMAT).create_view(&Default::default());
        let uniforms = MixedResUniforms {
            divisor: res.divisor(),
            depth_tolerance: DEPTH_TOLERANCE,
            pad0: 0,
            pad1: 0,
        };
        let params = wgpu::util::DeviceExt::create_buffer_init(
            device,
            &wgpu::util::BufferInitDescriptor {
                label: Some("mixed_res.uniforms"),
                contents: bytemuck::bytes_of(&uniforms),
                usage: wgpu::BufferUsages::UNIFORM,
            },
        );
        let view = |binding, view| wgpu::BindGroupEntry {
            binding,
            resource: wgpu::BindingResource::TextureView(view),
        };
        let depth_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("mixed_res.particles_depth_bind_group"),
            layout: particle_depth_layout,
            entries: &[view(0, &depth_view)],
        });
        let downsample_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("mixed_res.downsample.bind_group"),
            layout: &pipelines.downsample_layout,
            entries: &[
                view(0, full_depth),
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: params.as_entire_binding(),
                },
            ],
        });
        let upsample_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("mixed_res.upsample.bind_group"),
            layout: &pipelines.upsample_layout,
            entries: &[
                view(0, full_depth),
                view(1, &depth_view),
                view(2, &color_view),
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: params.as_entire_binding(),
                },
            ],
        });
        Self {
            res,
            frame_size,
            color_view,
            depth_view,
            depth_bind_group,
            downsample_bind_group,
            upsample_bind_group,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_smoke_rect_holds_every_particles_disc_and_not_the_whole_thesis_frame() {
        let scene = crate::scene::Scene::thesis_plume();
        let particles = crate::sim::simulate(&scene);
        let size = (scene.output.width_px, scene.output.height_px);
        let camera = crate::frame::CameraMatrices::new(&scene, size.0, size.1);
        let [x, y, w, h] =
            smoke_rect(&camera, scene.camera.near_m, &particles, size, 0).expect("smoke in view");
        // Every particle's disc on screen (its centre and the four points a radius away across
        // the view) lies inside, up to rounding to whole pixels.
        let (right, up) = (
            camera
                .view_from_world
                .inverse()
                .transform_vector3(glam::Vec3::X),
            camera
                .view_from_world
                .inverse()
                .transform_vector3(glam::Vec3::Y),
        );
        for p in &particles {
            for d in [glam::Vec3::ZERO, right, -right, up, -up] {
                let q = camera
                    .project_to_pixel(p.position + d * p.radius_m, size.0, size.1)
                    .unwrap();
                assert!(
                    q.x >= x as f32 - 1.0
                        && q.y >= y as f32 - 1.0
                        && q.x <= (x + w) as f32 + 1.0
                        && q.y <= (y + h) as f32 + 1.0,
                    "{q} outside [{x}, {y}, {w}, {h}]"
                );
            }
        }
        // The plume covers under half of the thesis frame's pixels (the scissor's saving).
        assert!(
            u64::from(w) * u64::from(h) < u64::from(size.0) * u64::from(size.1) / 2,
            "[{x}, {y}, {w}, {h}]"
        );
        assert_eq!(smoke_rect(&camera, scene.camera.near_m, &[], size, 4), None);
    }

    #[test]
    fn particle_res_parses_its_three_names_and_refuses_the_rest() {
        for r in ParticleRes::ALL {
            assert_eq!(r.name().parse::<ParticleRes>(), Ok(r));
            let json = serde_json::to_string(&r).unwrap();
            assert_eq!(serde_json::from_str::<ParticleRes>(&json).unwrap(), r);
        }
        for bad in ["1/3", "0", "abc", "", "2", "0.5"] {
            assert!(bad.parse::<ParticleRes>().is_err(), "{bad}");
        }
        assert_eq!(ParticleRes::Half.low_size(1024, 768), (512, 384));
        assert_eq!(ParticleRes::Quarter.low_size(1023, 5), (256, 2));
    }
}
