//! A technique's transmittance at given points ([`Renderer::probe`]): the frame's start, then
//! the technique's lookup in a compute pass at the points (or at the frame's own lighting
//! points, filtered by the shadow's history as the frame used them).

use glam::Vec3;

use super::start::other_faces;
use super::{CameraMatrices, Renderer, SortOrder};
use crate::frame::particles::LitParticle;
use crate::gpu::Gpu;
use crate::scene::Scene;
use crate::shadow;
use crate::shadow::probe::Probe;
use crate::sim::Particle;

impl Renderer {
    /// Transmittance T(p) from the light to each of `points` (world metres) as the active
    /// technique sees it for this frame of `scene`: the technique builds its maps as for
    /// [`Renderer::render`] (unless they are already this frame's: see
    /// [`super::RenderOptions::reuse_shadow_maps`]), then a compute shader evaluates the same
    /// `shadow_transmittance` the lighting shaders call.
    pub async fn probe(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        points: &[Vec3],
    ) -> anyhow::Result<Vec<f32>> {
        self.probe_scoped(gpu, scene, particles, points, None, false)
            .await
    }

    /// As [`Renderer::probe`] at a frame's shaded points, where `owners` names the particle
    /// whose lighting point each point is (`shaded::point_owners`; `shadow::NO_OWNER` for the
    /// opaque points): a technique that lights a particle's points together (`has`) then gives
    /// each the T the frame's lighting used, so the error measured is the error rendered.
    pub async fn probe_shaded(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        points: &[Vec3],
        owners: &[u32],
    ) -> anyhow::Result<Vec<f32>> {
        self.probe_scoped(gpu, scene, particles, points, Some(owners), false)
            .await
    }

    /// Every particle as the last frame's lighting lit it: its sphere and the smoke's T at its
    /// four lighting points, read back from the lighting buffer (the technique's own for one
    /// that draws the particles itself). Awaits the GPU.
    pub async fn lit_particles(&mut self, gpu: &Gpu) -> anyhow::Result<Vec<LitParticle>> {
        if let Some(pass) = self.faces[0].technique.particle_pass() {
            return Ok(pass.lit_particles(gpu).await?);
        }
        let lights = self.lights.read(gpu, self.instances.len()).await?;
        Ok(LitParticle::of(&self.instances, &lights))
    }

    /// As [`Renderer::probe`], but the light's whole visibility at each point as the lighting
    /// computes it: T times the opaque occluders' visibility (their filtered depth map, or for
    /// the reference the exact test). The reference's self-check compares it with the CPU's
    /// closed form (`reference_check`).
    pub async fn probe_with_occluders(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        points: &[Vec3],
    ) -> anyhow::Result<Vec<f32>> {
        self.probe_scoped(gpu, scene, particles, points, None, true)
            .await
    }

    async fn probe_scoped(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        points: &[Vec3],
        owners: Option<&[u32]>,
        with_occluders: bool,
    ) -> anyhow::Result<Vec<f32>> {
        let t =
            gpu.scoped(self.probe_unscoped(gpu, scene, particles, points, owners, with_occluders));
        t.await.map_err(|r| {
            r.during(format!(
                "probing {} at {} points",
                self.technique_config.name,
                points.len()
            ))
        })?
    }

    async fn probe_unscoped(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        points: &[Vec3],
        owners: Option<&[u32]>,
        with_occluders: bool,
    ) -> anyhow::Result<Vec<f32>> {
        // Maps built for this very frame (a render with `reuse_shadow_maps`, or an earlier
        // probe) are probed as they are; a probe leaves them reusable for the next such render.
        let (mut encoder, stats, _) = self
            .begin_frame(gpu, scene, particles, true, SortOrder::View, None)
            .await?;
        self.timer.resolve(&mut encoder);
        let probe = self.probe.get_or_insert_with(|| {
            Probe::new(
                gpu,
                &self.frame_layout,
                self.faces[0].technique.as_ref(),
                &self.technique_config.params,
            )
        });
        probe.set_with_occluders(with_occluders);
        let (first, rest) = self
            .faces
            .split_first_mut()
            .expect("a light has at least one face");
        let results = match first.technique.probe_pass() {
            Some(owner) => {
                owner
                    .probe(
                        gpu,
                        shadow::ProbeInputs {
                            encoder,
                            frame_bind_group: &first.frame_bind_group,
                            particles,
                            light: &stats.light,
                            light_axis: stats.light_direction,
                            camera_forward: CameraMatrices::new(scene, 1, 1).forward,
                            probe,
                            points,
                            owners,
                            other_faces: other_faces(rest),
                        },
                    )
                    .await?
            }
            None => {
                let lookups: Vec<(&wgpu::BindGroup, &wgpu::BindGroup)> = self
                    .faces
                    .iter()
                    .map(|f| (&f.frame_bind_group, f.technique.bind_group()))
                    .collect();
                let pending = probe.record(gpu, &mut encoder, &lookups, points);
                gpu.queue.submit([encoder.finish()]);
                pending.read(gpu).await?
            }
        };
        match owners {
            Some(owners) if self.history.active() => self.filtered_at(gpu, results, owners).await,
            _ => Ok(results),
        }
    }

    /// The probe's T at a filtered frame's shaded points ([`Renderer::probe_shaded`]): at a
    /// particle's lighting points the T the frame's lighting used, its history's
    /// ([`history`]), read back from the lighting; elsewhere the lookup's.
    async fn filtered_at(
        &self,
        gpu: &Gpu,
        mut results: Vec<f32>,
        owners: &[u32],
    ) -> anyhow::Result<Vec<f32>> {
        let lights = self.lights.read(gpu, self.instances.len()).await?;
        let mut instance_of = vec![0u32; self.order.len()];
        for (instance, &particle) in self.order.iter().enumerate() {
            instance_of[particle as usize] = instance as u32;
        }
        // A particle's four points follow one another in `particle_lighting_points`' order,
        // the lighting's.
        let mut k = 0usize;
        for (j, &owner) in owners.iter().enumerate() {
            if owner == shadow::NO_OWNER {
                continue;
            }
            k = match j > 0 && owners[j - 1] == owner {
                true => k + 1,
                false => 0,
            };
            let light = &lights[instance_of[owner as usize] as usize];
            results[j] = light.radiance[k % 4][3];
        }
        Ok(results)
    }
}
