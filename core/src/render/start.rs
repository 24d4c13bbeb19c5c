//! The frame's start, shared by a frame and a probe ([`Renderer::begin_frame`]): the light
//! matched to the technique (one face for a spotlight, six for a point light), the particles'
//! sort and upload, the opaque geometry, the medium, the frame's uniforms and group 0, the
//! light faces' fit and the technique's build (skipped when its inputs are the last build's).

use web_time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use super::{
    CameraMatrices, FrameStats, LightFace, LightPass, ParticleRes, RenderOptions, Renderer,
    SortOrder, TechniqueConfig, geometry, particle_buffer, sort,
};
use crate::frame::gpu_data::{FrameUniforms, ParticleInstance};
use crate::frame::occluders::{self, Occluders};
use crate::frame::particles::LightBuffers;
use crate::gpu::Gpu;
use crate::medium::frame::FrameMedium;
use crate::scene::{LightKind, Scene};
use crate::shadow::{self, LightSpace, ShadowError};
use crate::sim::Particle;

impl Renderer {
    /// The start every frame shares: fit the light space, upload the uniforms, sort the particles
    /// back to front for the camera in `sort`'s order (timed) and upload them, and record the
    /// technique's build.
    /// `build`, when given, is recorded instead of the technique's build (the bench's light
    /// pass, see [`Renderer::light_pass_frame`]).
    pub(super) async fn begin_frame(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        reuse_shadow_maps: bool,
        sort: SortOrder,
        build: Option<LightPass<'_>>,
    ) -> Result<(wgpu::CommandEncoder, FrameStats, CameraMatrices), ShadowError> {
        let (width, height) = self.size();
        self.upload_opaque(gpu, scene);
        self.match_light(gpu, &scene.light).await?;
        self.prepare_medium(gpu, scene, particles.len()).await?;

        let camera = CameraMatrices::new(scene, width, height);
        let lights = LightSpace::faces_with(
            &scene.light,
            particles,
            self.medium.bounds(),
            scene.shadow.framing,
        );
        let reads_occluder_map = shadow::find(&self.technique_config.name).map_or(true, |e| {
            e.reads_occluder_map(&self.technique_config.params)
        });
        for (face, light) in self.faces.iter_mut().zip(&lights) {
            if face.occluders.prepare(gpu, scene, reads_occluder_map)? {
                face.frame_bind_group = frame_bind_group(
                    &gpu.device,
                    &self.frame_layout,
                    &face.frame_buffer,
                    &face.occluders,
                    &self.medium,
                );
            }
            gpu.queue.write_buffer(
                &face.frame_buffer,
                0,
                bytemuck::bytes_of(&frame_uniforms(
                    scene,
                    &camera,
                    light,
                    (width, height),
                    self.medium.frame_params(),
                )),
            );
        }

        // Back-to-front by depth along the view or the half-angle; ties keep pool order so the
        // result is deterministic. The time covers the keys and the sort
        // (`sort::back_to_front`), not the gather below.
        let light_dir = light_direction(&scene.light, particles);
        let (axis, slicing) = sort::depth_axis(sort, camera.forward, light_dir);
        self.slicing = slicing;
        let sort_start = Instant::now();
        let order = sort::back_to_front(particles, camera.position, axis);
        let sort_ms = sort_start.elapsed().as_secs_f64() * 1e3;
        // The shadow's temporal history: the scene's weight, refused by a technique that lights
        // the particles in its own pass (`has`), never applied to the reference or `none`.
        let entry = shadow::find(&self.technique_config.name).ok();
        if let Some(refusal) = entry.and_then(|e| e.history_refusal(scene.shadow.history)) {
            return Err(refusal);
        }
        let weight = match entry.is_some_and(|e| e.role == shadow::Role::Contender) {
            true => scene.shadow.history,
            false => 0.0,
        };
        self.history.prepare(
            gpu,
            &mut self.frame_memory,
            &self.particle_layouts.history,
            weight,
            particles,
            &order,
        )?;
        // The frame's GPU clock starts here, in a submission of its own: everything after the
        // sort (the gather and upload below, the builds' mid-frame readbacks) is on it.
        self.timer.begin_frame(gpu);
        self.instances.clear();
        self.instances.par_extend(
            order
                .par_iter()
                .map(|&i| ParticleInstance::from_particle(&particles[i as usize])),
        );
        self.upload_particles(gpu)?;
        self.order = order;
        let particle_count = particles.len() as u32;

        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame.encoder"),
            });
        self.timer.begin_encoder(&mut encoder);
        for face in &self.faces {
            face.occluders.record(
                &mut encoder,
                &mut self.timer,
                &self.opaque_vertices,
                self.opaque_vertex_count,
            );
        }
        // Hashing every particle costs milliseconds at a million: only frames that may reuse
        // the maps pay for it (a frame that does not leaves `built_from` unset).
        let build_key = reuse_shadow_maps
            .then(|| build_key(particles, &scene.light, &lights[0], &self.technique_config));
        if build_key.is_none() || self.built_from != build_key {
            self.built_from = None;
            let volume = self.medium.bounds();
            match build {
                // The bench's light pass: once, in the first light space.
                Some(build) => build(
                    gpu,
                    shadow::BuildInputs {
                        encoder: &mut encoder,
                        timer: &mut self.timer,
                        frame_bind_group: &self.faces[0].frame_bind_group,
                        particles: &self.particles,
                        particle_count,
                        instances: &self.instances,
                        light: &lights[0],
                        volume,
                    },
                )?,
                None => {
                    for (face, light) in self.faces.iter_mut().zip(&lights) {
                        face.technique
                            .build(
                                gpu,
                                shadow::BuildInputs {
                                    encoder: &mut encoder,
                                    timer: &mut self.timer,
                                    frame_bind_group: &face.frame_bind_group,
                                    particles: &self.particles,
                                    particle_count,
                                    instances: &self.instances,
                                    light,
                                    volume,
                                },
                            )
                            .await?;
                    }
                    self.built_from = build_key;
                }
            }
        }
        let stats = FrameStats {
            sort_ms,
            untimed_sort_ms: sort_ms,
            sorts: 1,
            particle_count,
            light: lights[0],
            light_direction: light_dir,
        };
        Ok((encoder, stats, camera))
    }

    pub(super) fn upload_opaque(&mut self, gpu: &Gpu, scene: &Scene) {
        let mesh = geometry::opaque_mesh(scene);
        if bytemuck::cast_slice::<_, u8>(&mesh)
            == bytemuck::cast_slice::<_, u8>(&self.opaque_source)
        {
            return;
        }
        let bytes: &[u8] = bytemuck::cast_slice(&mesh);
        if self.opaque_vertices.size() < bytes.len() as u64 {
            self.opaque_vertices = gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("opaque.vertices"),
                size: bytes.len() as u64,
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
        }
        gpu.queue.write_buffer(&self.opaque_vertices, 0, bytes);
        self.opaque_vertex_count = mesh.len() as u32;
        self.opaque_source = mesh;
    }

    pub(super) fn upload_particles(&mut self, gpu: &Gpu) -> Result<(), ShadowError> {
        let needed = self.instances.len() as u64;
        if needed > self.particle_capacity {
            self.particle_capacity = needed.next_power_of_two();
            self.particles = particle_buffer(&gpu.device, self.particle_capacity);
            self.lights = LightBuffers::new(
                &gpu.device,
                &mut self.frame_memory,
                &self.particle_layouts,
                &self.particles,
                self.particle_capacity,
                1,
                true,
                "particles",
            )?;
        }
        if needed > 0 {
            gpu.queue
                .write_buffer(&self.particles, 0, bytemuck::cast_slice(&self.instances));
        }
        Ok(())
    }

    /// Makes one light face per light space of `light` (a point light's six cube faces, a
    /// spotlight's one), each with its own instance of the technique.
    pub(super) async fn match_light(
        &mut self,
        gpu: &Gpu,
        light: &crate::scene::Spotlight,
    ) -> Result<(), ShadowError> {
        let wanted = light.kind.faces();
        self.faces.truncate(wanted);
        while self.faces.len() < wanted {
            let technique = self
                .create_technique(gpu, &self.technique_config.clone())
                .await?;
            self.faces.push(LightFace::new(
                gpu,
                &self.frame_layout,
                &self.medium,
                technique,
            )?);
            self.built_from = None;
        }
        Ok(())
    }

    /// Makes the frame's volume the scene's (loading it when its source changed; every face's
    /// group 0 is made again then), and refuses a technique that cannot shadow it.
    pub(super) async fn prepare_medium(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: usize,
    ) -> Result<(), ShadowError> {
        let entry = shadow::find(&self.technique_config.name)?;
        if let Some(refusal) = entry.refusal(scene.volume.is_some(), particles) {
            return Err(refusal);
        }
        // The grid at the scene's time (the procedural cloud's wind moves it).
        let volume = scene
            .volume
            .as_ref()
            .map(|v| v.at_time(scene.sim.duration_s));
        let changed = self
            .medium
            .prepare(gpu, volume.as_ref())
            .await
            .map_err(|e| ShadowError::Volume(e.to_string()))?;
        if changed {
            for face in &mut self.faces {
                face.frame_bind_group = frame_bind_group(
                    &gpu.device,
                    &self.frame_layout,
                    &face.frame_buffer,
                    &face.occluders,
                    &self.medium,
                );
            }
            self.built_from = None;
        }
        Ok(())
    }

    /// Refuses the options the active technique cannot draw with: a technique that draws the
    /// particles itself draws them at full resolution only.
    pub(super) fn check_options(&mut self, options: &RenderOptions) -> Result<(), ShadowError> {
        if options.particle_res != ParticleRes::Full
            && self.faces[0].technique.particle_pass().is_some()
        {
            return Err(ShadowError::ParticleResUnsupported {
                technique: self.faces[0].technique.name(),
                res: options.particle_res.name(),
            });
        }
        Ok(())
    }
}

/// Identifies the inputs of a technique's build: the particles, the spotlight and its fitted
/// light space, the technique's configuration.
/// The technique in each of `faces`, with the face's group 0, for the owner of the particle pass
/// or the probe in the first face.
pub(super) fn other_faces(faces: &mut [LightFace]) -> Vec<shadow::OtherFace<'_>> {
    faces
        .iter_mut()
        .map(|f| shadow::OtherFace {
            frame_bind_group: &f.frame_bind_group,
            technique: f.technique.as_mut(),
        })
        .collect()
}

/// The direction light travels to the smoke (the half-angle's light direction): the spotlight's
/// axis, or from a point light to the particles' centroid.
pub fn light_direction(light: &crate::scene::Spotlight, particles: &[Particle]) -> Vec3 {
    let axis = (light.target - light.position).normalize();
    match light.kind {
        LightKind::Spot => axis,
        LightKind::Point => {
            let count = particles.len().max(1) as f32;
            let centroid = particles.iter().map(|p| p.position).sum::<Vec3>() / count;
            (centroid - light.position).try_normalize().unwrap_or(axis)
        }
    }
}

pub(super) fn build_key(
    particles: &[Particle],
    spot: &crate::scene::Spotlight,
    light: &LightSpace,
    config: &TechniqueConfig,
) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for p in particles {
        for v in [
            p.position.x,
            p.position.y,
            p.position.z,
            p.radius_m,
            p.density_per_m,
        ] {
            v.to_bits().hash(&mut h);
        }
    }
    for v in spot
        .position
        .to_array()
        .iter()
        .chain(&spot.target.to_array())
    {
        v.to_bits().hash(&mut h);
    }
    for v in light.clip_from_world.to_cols_array() {
        v.to_bits().hash(&mut h);
    }
    format!("{config:?}").hash(&mut h);
    h.finish()
}

pub(super) fn frame_uniforms(
    scene: &Scene,
    camera: &CameraMatrices,
    light: &LightSpace,
    (width, height): (u32, u32),
    grid: crate::medium::gpu_grid::GridParams,
) -> FrameUniforms {
    let l = &scene.light;
    let (cos_outer, cos_inner) = match l.kind {
        LightKind::Spot => {
            let cone = l.cone_angle_deg.to_radians();
            let cos_outer = cone.cos();
            (
                cos_outer,
                (cone * (1.0 - l.penumbra)).cos().max(cos_outer + 1e-4),
            )
        }
        // Below any cosine: the cone's smoothstep is 1 in every direction.
        LightKind::Point => (-2.0, -1.5),
    };
    let axis = (l.target - l.position).normalize_or(Vec3::NEG_Y);
    let clip_from_world = camera.clip_from_world();
    let s = &scene.shading;
    let (occluder_clip_from_world, occluder_far_m) =
        occluders::clip_from_world(scene, light.cone_view_from_world, light.cone_tan_half_fov);
    FrameUniforms {
        clip_from_world: clip_from_world.to_cols_array_2d(),
        world_from_clip: clip_from_world.inverse().to_cols_array_2d(),
        light_clip_from_world: light.clip_from_world.to_cols_array_2d(),
        occluder_clip_from_world: occluder_clip_from_world.to_cols_array_2d(),
        world_from_light_clip: light.clip_from_world.inverse().to_cols_array_2d(),
        camera_pos: camera.position.extend(scene.camera.near_m).to_array(),
        camera_forward: camera.forward.extend(scene.camera.far_m).to_array(),
        viewport: [
            width as f32,
            height as f32,
            1.0 / width as f32,
            1.0 / height as f32,
        ],
        light_pos: l.position.extend(cos_outer).to_array(),
        light_dir: axis.extend(cos_inner).to_array(),
        light_radiance: (l.color * l.intensity).extend(s.hg_g).to_array(),
        light_depth: [
            light.near_m,
            light.far_m,
            1.0 / (light.far_m - light.near_m),
            light.face.map_or(-1.0, f32::from),
        ],
        ambient: s.ambient.extend(s.exposure).to_array(),
        background: s.background.extend(0.0).to_array(),
        occluders: [
            occluder_far_m,
            1.0 / occluder_far_m,
            scene.shadow.occluder_resolution_px as f32,
            scene.boxes.len() as f32,
        ],
        ground: [
            scene.ground.height_m,
            0.5 * scene.ground.size_m,
            occluders::epsilon_m(l.position, light.far_m),
            0.0,
        ],
        grid,
    }
}

/// Group 0: the frame's uniforms, the occluders' map, sampler and boxes, and the density
/// volume's voxels.
pub(super) fn frame_bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    frame_buffer: &wgpu::Buffer,
    occluders: &Occluders,
    medium: &FrameMedium,
) -> wgpu::BindGroup {
    let [map, sampler, boxes] = occluders.frame_entries();
    let [grid_density] = medium.bind_entries();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("frame.bind_group"),
        layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: frame_buffer.as_entire_binding(),
            },
            map,
            sampler,
            boxes,
            grid_density,
        ],
    })
}
