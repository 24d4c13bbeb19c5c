//! The frame's passes after its start, in the order [`Renderer::render`] records them: the
//! particles' lighting, the opaque pass, a volume's eye march, the particle pass (the
//! technique's own, or billboards at full or lower resolution with its downsample and
//! upsample) and the tone map.

use glam::Vec3;

use super::start::other_faces;
use super::{
    CameraMatrices, FrameStats, HDR_FORMAT, ParticleRes, RenderOptions, Renderer, gpu_data,
    mixed_res,
};
use crate::gpu::{FragmentTally, Gpu, GpuError, TargetWrites};
use crate::medium::eye_pass;
use crate::scene::Scene;
use crate::shadow::{self, ShadowError};
use crate::sim::Particle;

impl Renderer {
    /// Each particle's lighting, once, with the technique's T (part of rendering them); a point
    /// light's faces each light the points in their face. In the technique's order when it has
    /// one for these particles (the first face's: the order only speeds the lighting up,
    /// whichever face's it is).
    pub(super) fn record_lighting(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        particle_count: u32,
    ) {
        let lighting = &self.pipelines.lighting;
        let everything = 0..particle_count;
        let order = self.faces[0]
            .technique
            .lighting_order()
            .filter(|order| order.len() == particle_count as usize);
        if let Some(order) = order {
            self.lights.write_order(&gpu.queue, order);
        }
        lighting.set_ranges(
            &gpu.queue,
            &self.lights,
            std::slice::from_ref(&everything),
            order.is_some(),
        );
        self.history.lit();
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("particles.lighting"),
            timestamp_writes: self.timer.compute_pass("particles"),
        });
        for face in &self.faces {
            lighting.dispatch(
                &mut pass,
                &face.frame_bind_group,
                face.technique.bind_group(),
                &self.lights,
                self.history.bind_group(),
                0,
                particle_count,
            );
        }
    }

    /// The opaque pass: ground and boxes over the background, into the HDR target (alpha 0) and
    /// the depth texture. A point light's faces each shade the fragments in their face (the
    /// others are discarded, so each pixel is written by one face's draw).
    pub(super) fn record_opaque(&mut self, encoder: &mut wgpu::CommandEncoder, background: Vec3) {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("opaque"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &self.targets.hdr_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color {
                        r: f64::from(background.x),
                        g: f64::from(background.y),
                        b: f64::from(background.z),
                        a: 0.0,
                    }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.targets.depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: self.timer.pass("opaque"),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipelines.opaque);
        pass.set_vertex_buffer(0, self.opaque_vertices.slice(..));
        for face in &self.faces {
            pass.set_bind_group(0, &face.frame_bind_group, &[]);
            pass.set_bind_group(1, face.technique.bind_group(), &[]);
            pass.draw(0..self.opaque_vertex_count, 0..1);
        }
    }

    /// The eye's march of the density volume over the opaque scene (nothing without one).
    pub(super) fn record_volume(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
    ) -> Result<(), ShadowError> {
        let steps = self.medium.eye_steps();
        if steps == 0 {
            return Ok(());
        }
        let size = self.size();
        if !self
            .eye_targets
            .as_ref()
            .is_some_and(|t| t.fits(size, steps))
        {
            self.eye_targets = Some(
                eye_pass::EyeTargets::new(
                    gpu,
                    &self.eye_layouts,
                    &self.targets.depth_view,
                    size,
                    steps,
                )
                .map_err(|e| ShadowError::Volume(format!("the eye's march of the volume: {e}")))?,
            );
        }
        if self.pipelines.eye.is_none() {
            let technique = self.faces[0].technique.as_ref();
            let entry = shadow::find(technique.name())?;
            self.pipelines.eye = Some(eye_pass::EyePipelines::new(
                &gpu.device,
                technique.name(),
                &self.frame_layout,
                technique.bind_group_layout(),
                &entry.frame_imports(&self.technique_config.params).pairs(),
                &self.eye_layouts,
            ));
        }
        let faces: Vec<_> = self
            .faces
            .iter()
            .map(|f| eye_pass::EyeFace {
                frame: &f.frame_bind_group,
                technique: f.technique.bind_group(),
            })
            .collect();
        eye_pass::record(
            encoder,
            &mut self.timer,
            self.pipelines.eye.as_ref().expect("made above"),
            self.eye_targets.as_ref().expect("made above"),
            &faces,
            &self.targets.hdr_view,
        );
        Ok(())
    }

    /// The particle pass of a technique that draws the particles itself (`has`: slices lit as
    /// they are drawn); its own sort, when it makes one, joins the frame's sort time.
    pub(super) fn record_owned_particle_pass(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        particles: &[Particle],
        camera: &CameraMatrices,
        options: &RenderOptions,
        stats: &mut FrameStats,
    ) -> Result<(), ShadowError> {
        let (first, rest) = self
            .faces
            .split_first_mut()
            .expect("a light has at least one face");
        let owner = first
            .technique
            .particle_pass()
            .expect("called for a technique that draws the particles");
        let shared_order = self.slicing.map(|slicing| shadow::SharedOrder {
            slicing,
            eye_back_to_front: &self.instances,
        });
        let own_sort_ms = owner.record(
            gpu,
            shadow::ParticlePassInputs {
                encoder,
                timer: &mut self.timer,
                frame_bind_group: &first.frame_bind_group,
                particles,
                camera,
                light: &stats.light,
                light_axis: stats.light_direction,
                hdr_view: &self.targets.hdr_view,
                hdr_size: (self.targets.width, self.targets.height),
                depth_bind_group: &self.targets.depth_bind_group,
                depth_view: &self.targets.depth_view,
                spherical: options.spherical,
                shared_order,
                other_faces: other_faces(rest),
            },
        )?;
        if let Some(ms) = own_sort_ms {
            stats.sort_ms += ms;
            stats.sorts += 1;
        }
        Ok(())
    }

    /// The renderer's particle pass: the lit billboards back to front over the opaque scene.
    /// Full resolution draws straight into the frame; a lower one into its own cleared target
    /// against the downsampled depth, composited by a depth-aware upsample ([`mixed_res`]).
    #[allow(clippy::too_many_arguments)] // the frame's inputs, each used by one step
    pub(super) fn record_particle_pass(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        scene: &Scene,
        particles: &[Particle],
        camera: &CameraMatrices,
        options: &RenderOptions,
        particle_count: u32,
    ) {
        let low = match options.particle_res {
            ParticleRes::Full => None,
            res => {
                self.ensure_low_res(gpu, res);
                self.record_downsample(encoder);
                self.low_res.as_ref()
            }
        };
        let (color_view, color_load, depth_view, depth_bind_group) = match low {
            None => (
                &self.targets.hdr_view,
                wgpu::LoadOp::Load,
                &self.targets.depth_view,
                &self.targets.depth_bind_group,
            ),
            Some(low) => (
                &low.color_view,
                wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                &low.depth_view,
                &low.depth_bind_group,
            ),
        };
        let depth_attachment =
            (!options.spherical).then_some(wgpu::RenderPassDepthStencilAttachment {
                view: depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Load,
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            });
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("particles"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: color_load,
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: depth_attachment,
            timestamp_writes: self.timer.pass(PARTICLE_PASS),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        let writes = TargetWrites::of(&[HDR_FORMAT]);
        self.timer
            .count_fragments(&mut pass, PARTICLE_PASS, writes, |pass| {
                if options.spherical {
                    pass.set_pipeline(&self.particle_pipelines.spherical);
                    pass.set_bind_group(2, depth_bind_group, &[]);
                } else {
                    pass.set_pipeline(&self.particle_pipelines.flat);
                }
                pass.set_bind_group(0, &self.faces[0].frame_bind_group, &[]);
                pass.set_bind_group(1, &self.lights.read_bind_group, &[]);
                if particle_count > 0 {
                    pass.set_vertex_buffer(0, self.particles.slice(..));
                    pass.draw(0..gpu_data::BILLBOARD_VERTICES, 0..particle_count);
                }
            });
        drop(pass);
        if low.is_some() {
            self.record_upsample(encoder, scene, particles, camera, options.particle_res);
        }
    }

    /// The low-resolution particle pass' depth: the opaque depth downsampled (nearest of each
    /// block) into the low-resolution target's.
    pub(super) fn record_downsample(&mut self, encoder: &mut wgpu::CommandEncoder) {
        let low = self.low_res.as_ref().expect("made by ensure_low_res");
        let pipelines = self.mixed_res.as_ref().expect("made with the targets");
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("particles.downsample"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &low.depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: self.timer.pass("downsample"),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&pipelines.downsample);
        pass.set_bind_group(0, &self.faces[0].frame_bind_group, &[]);
        pass.set_bind_group(1, &low.downsample_bind_group, &[]);
        pass.draw(0..3, 0..1);
    }

    /// Composites the low-resolution particle pass into the frame, only where the smoke can be:
    /// its screen bounds, widened by one low-resolution texel (the upsample's bilinear
    /// footprint) and a pixel.
    pub(super) fn record_upsample(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        scene: &Scene,
        particles: &[Particle],
        camera: &CameraMatrices,
        res: ParticleRes,
    ) {
        let low = self.low_res.as_ref().expect("made by ensure_low_res");
        let pipelines = self.mixed_res.as_ref().expect("made with the targets");
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("particles.upsample"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &self.targets.hdr_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Load,
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: self.timer.pass("upsample"),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        let rect = mixed_res::smoke_rect(
            camera,
            scene.camera.near_m,
            particles,
            (self.targets.width, self.targets.height),
            res.divisor() + 1,
        );
        if let Some([x, y, w, h]) = rect {
            pass.set_scissor_rect(x, y, w, h);
            pass.set_pipeline(&pipelines.upsample);
            pass.set_bind_group(0, &self.faces[0].frame_bind_group, &[]);
            pass.set_bind_group(1, &low.upsample_bind_group, &[]);
            pass.draw(0..3, 0..1);
        }
    }

    /// The tone map (exposure + ACES fit) of the HDR target into the caller's sRGB `output`.
    pub(super) fn record_tonemap(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        output: &wgpu::TextureView,
    ) {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("tonemap"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: output,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: self.timer.pass("tonemap"),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.tonemap_pipeline);
        pass.set_bind_group(0, &self.faces[0].frame_bind_group, &[]);
        pass.set_bind_group(1, &self.targets.tonemap_bind_group, &[]);
        pass.draw(0..3, 0..1);
    }

    /// The low-resolution targets for `res` at the current size, made when missing.
    pub(super) fn ensure_low_res(&mut self, gpu: &Gpu, res: ParticleRes) {
        let size = self.size();
        if self
            .low_res
            .as_ref()
            .is_some_and(|l| l.res == res && l.frame_size == size)
        {
            return;
        }
        let pipelines = self.mixed_res.get_or_insert_with(|| {
            mixed_res::MixedResPipelines::new(&gpu.device, &self.frame_layout)
        });
        self.low_res = Some(mixed_res::LowResTargets::new(
            &gpu.device,
            pipelines,
            &self.depth_layout,
            &self.targets.depth_view,
            size,
            res,
        ));
    }
}

/// Name of the particle pass's timestamps and fragment count.
pub const PARTICLE_PASS: &str = "particles";

/// The particle pass's fragment-shader invocations among a counted frame's tallies.
pub fn particle_fragments(tallies: &[FragmentTally]) -> Option<u64> {
    tallies
        .iter()
        .find(|t| t.pass == PARTICLE_PASS)
        .map(|t| t.fragments)
}

impl Renderer {
    /// Fragment shader invocations of the particle pass in the last frame rendered with
    /// fragment counting on ([`Renderer::set_count_fragments`]; awaited until it finished);
    /// `None` when counting was off, or the technique drew the particles itself (`has`).
    pub async fn particle_fragments(&mut self, gpu: &Gpu) -> Result<Option<u64>, GpuError> {
        Ok(particle_fragments(&self.fragment_counts(gpu).await?))
    }
}
