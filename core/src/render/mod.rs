//! The frame: one render path for the CLI, the tests, the sweep and the viewer.
//!
//! [`Renderer::render`] draws one frame into a caller's `wgpu::TextureView`:
//! 1. the active shadow technique builds its maps from the particles in light space;
//! 2. opaque pass: ground and boxes, lit by the spotlight and shadowed by the smoke, into an HDR
//!    colour target (alpha 0) and a depth texture;
//! 3. particle pass: billboards sorted back to front on the CPU (timed; by view depth, or with
//!    [`SortOrder::HalfAngle`] along the half-angle, the one sort `has` then draws in too),
//!    composited with premultiplied "over" (thesis Eq. 1.5); spherical billboards (thesis
//!    3.2.2.3) read the opaque depth to clip each particle's chord, or, with
//!    `spherical = false`, flat billboards use a hard depth test; the HDR alpha channel ends up
//!    holding the smoke's opacity; with
//!    [`RenderOptions::particle_res`] below 1 the pass draws at a lower resolution and a
//!    depth-aware upsample composites it ([`mixed_res`]);
//! 4. tone map (exposure + ACES fit) into the caller's sRGB target.
//!
//! Long-lived state (pipelines, layouts, targets, buffers) is built in [`Renderer::new`] and when
//! the technique or size changes; a frame only uploads uniforms and particles and records passes.
//!
//! The rooms: this file holds the renderer's state and the frame's order
//! ([`Renderer::render`]); `start.rs` the frame's start (light, sort, uploads, uniforms, the
//! technique's build), `passes.rs` the passes after it, `probe.rs` the transmittance probe,
//! `offscreen.rs` a frame drawn and read back.

pub mod history;
pub mod mixed_res;
mod offscreen;
mod passes;
mod probe;
pub mod reference_check;
pub mod shaded;
pub mod sort;
mod start;

pub use mixed_res::{ParticleRes, parse_particle_res};
pub use offscreen::{OffscreenFrame, OffscreenTarget, render_offscreen};
pub use passes::{PARTICLE_PASS, particle_fragments};
pub use sort::SortOrder;
use start::frame_bind_group;
pub use start::light_direction;

// The frame's building blocks live in `crate::frame` (the techniques share them); re-exported
// here, where callers of the renderer look for them.
pub use crate::frame::{
    CameraMatrices, DEPTH_FORMAT, HDR_FORMAT, OUTPUT_FORMAT, OVER, ParticleLayouts,
    ParticlePipelines, UNDER, geometry, gpu_data, particles,
};

use glam::Vec3;

use crate::frame::occluders::{self, Occluders};
use crate::gpu::{FragmentTally, Gpu, GpuError, GpuTimer, MemoryLedger, PassTimes};
use crate::medium::eye_pass;
use crate::medium::frame::FrameMedium;
use crate::scene::Scene;
use crate::shaders;
use crate::shadow::probe::Probe;
use crate::shadow::{
    self, LightSpace, ShadowError, ShadowTechnique, TechniqueContext, TechniqueParams,
};
use crate::sim::Particle;
use gpu_data::{FrameUniforms, OpaqueVertex, ParticleInstance};
use particles::{LightBuffers, ParticleLighting};

/// Per-frame switches.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Spherical billboards (soft contact with opaque geometry) or flat ones with a depth test.
    pub spherical: bool,
    /// Skip the technique's build when the particles, the light and the technique are the
    /// ones the maps were last built from (shadow maps do not depend on the camera). For the
    /// viewer, where the camera moves most; never for timings, which must measure every build.
    pub reuse_shadow_maps: bool,
    /// The particle pass's resolution: below 1 it draws into a smaller target and a depth-aware
    /// upsample composites it over the frame ([`mixed_res`]). Full (the default) is the thesis.
    pub particle_res: ParticleRes,
    /// The order of the frame's one sort: by view depth (the default), or along the half-angle
    /// so that `has` draws in it without a sort of its own ([`SortOrder`]).
    pub sort: SortOrder,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            spherical: true,
            reuse_shadow_maps: false,
            particle_res: ParticleRes::Full,
            sort: SortOrder::View,
        }
    }
}

/// Which technique to render with.
#[derive(Clone, Debug, PartialEq)]
pub struct TechniqueConfig {
    pub name: String,
    pub params: TechniqueParams,
}

/// A pass recorded in place of the technique's build, with the frame's build inputs
/// ([`Renderer::light_pass_frame`]).
pub type LightPass<'a> =
    &'a mut dyn FnMut(&Gpu, shadow::BuildInputs<'_>) -> Result<(), ShadowError>;

/// CPU-side measurements of one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameStats {
    /// Time to sort the particles back to front, milliseconds (CPU wall time of the sorts only:
    /// the frame's, plus a technique's own).
    pub sort_ms: f64,
    /// The part of `sort_ms` before the frame's GPU clock starts (the frame's one sort): a
    /// technique's own sort runs after it, so the frame's passes already hold it.
    pub untimed_sort_ms: f64,
    /// Sorts of every particle this frame: the frame's one, plus one when the technique draws
    /// the particles in an order of its own (`has`, unless the frame sorted along its
    /// half-angle).
    pub sorts: u32,
    pub particle_count: u32,
    pub light: LightSpace,
    /// The direction light travels to the smoke this frame ([`light_direction`]), which the
    /// half-angle slices against.
    pub light_direction: Vec3,
}

impl FrameStats {
    /// The frame's time as `bench`, `sweep` and `render --bench` report it: its GPU passes
    /// (`times`, from the frame's start after the sort to its last pass, with the CPU work the
    /// GPU waited for in between) plus the sort before that start.
    pub fn frame_ms(&self, times: &crate::gpu::PassTimes) -> f64 {
        times.total_ms() + self.untimed_sort_ms
    }
}

/// Pipelines that depend on the technique's lookup shader.
struct TechniquePipelines {
    opaque: wgpu::RenderPipeline,
    lighting: ParticleLighting,
    /// The eye's march of a density volume, made on the first frame with one.
    eye: Option<eye_pass::EyePipelines>,
}

/// What one light space owns: its frame uniforms (the light's projection for this face) and
/// group 0, the occluders' depth map seen through it, and the technique's maps built in it.
struct LightFace {
    frame_buffer: wgpu::Buffer,
    frame_bind_group: wgpu::BindGroup,
    occluders: Occluders,
    technique: Box<dyn ShadowTechnique>,
}

impl LightFace {
    fn new(
        gpu: &Gpu,
        frame_layout: &wgpu::BindGroupLayout,
        medium: &FrameMedium,
        technique: Box<dyn ShadowTechnique>,
    ) -> Result<Self, ShadowError> {
        let frame_buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame.uniforms"),
            size: std::mem::size_of::<FrameUniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let occluders = Occluders::new(
            gpu,
            &frame_buffer,
            crate::scene::DEFAULT_OCCLUDER_RESOLUTION_PX,
        )?;
        let frame_bind_group =
            frame_bind_group(&gpu.device, frame_layout, &frame_buffer, &occluders, medium);
        Ok(Self {
            frame_buffer,
            frame_bind_group,
            occluders,
            technique,
        })
    }
}

/// Size-dependent targets.
struct Targets {
    width: u32,
    height: u32,
    hdr: wgpu::Texture,
    hdr_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    depth_bind_group: wgpu::BindGroup,
    tonemap_bind_group: wgpu::BindGroup,
}

/// Everything needed to draw frames; see the module docs.
pub struct Renderer {
    frame_layout: wgpu::BindGroupLayout,
    /// One per light space: a spotlight's one, a point light's six cube faces. The camera's
    /// passes bind the first one's group 0 (the camera half of every face's uniforms is the same).
    faces: Vec<LightFace>,
    depth_layout: wgpu::BindGroupLayout,
    hdr_layout: wgpu::BindGroupLayout,
    tonemap_pipeline: wgpu::RenderPipeline,
    targets: Targets,
    opaque_vertices: wgpu::Buffer,
    opaque_vertex_count: u32,
    opaque_source: Vec<OpaqueVertex>,
    particles: wgpu::Buffer,
    particle_capacity: u64,
    instances: Vec<ParticleInstance>,
    /// The half-angle slicing `instances` were sorted along this frame, if they were
    /// ([`SortOrder::HalfAngle`]).
    slicing: Option<shadow::half_angle::Slicing>,
    particle_layouts: ParticleLayouts,
    /// Lighting of the sorted instances, computed each frame before the particle pass.
    lights: LightBuffers,
    /// The shadow's temporal history at the particles' lighting points ([`history`]), and the
    /// frame's sort (each instance's particle index), which its probe maps points by.
    history: history::ShadowHistory,
    order: Vec<u32>,
    /// The frame's own buffers that grow with it (the lighting), which every technique's frame
    /// holds alike: not charged to a technique.
    frame_memory: MemoryLedger,
    /// The particle pass's draw pipelines (independent of the technique).
    particle_pipelines: ParticlePipelines,
    technique_config: TechniqueConfig,
    pipelines: TechniquePipelines,
    timer: GpuTimer,
    /// The transmittance probe for the active technique, built on first use.
    probe: Option<Probe>,
    /// What the technique's maps were last built from (see [`RenderOptions::reuse_shadow_maps`]).
    built_from: Option<u64>,
    /// Mixed-resolution particles: the pipelines (built on first use) and the low-resolution
    /// targets of the current size and [`ParticleRes`].
    mixed_res: Option<mixed_res::MixedResPipelines>,
    low_res: Option<mixed_res::LowResTargets>,
    /// The scene's density volume (its voxels in group 0, binding 4; its parameters in the frame's uniforms), and the eye pass' layouts and
    /// buffers (made on the first frame with a volume, for its size and steps).
    medium: FrameMedium,
    eye_layouts: eye_pass::EyeLayouts,
    eye_targets: Option<eye_pass::EyeTargets>,
}

impl Renderer {
    /// Builds pipelines and targets for `width` x `height` output in `output_format`.
    pub async fn new(
        gpu: &Gpu,
        width: u32,
        height: u32,
        output_format: wgpu::TextureFormat,
        technique: &TechniqueConfig,
    ) -> Result<Self, ShadowError> {
        let device = &gpu.device;
        // Group 0: the frame's uniforms, then the occluders' map, sampler and boxes.
        let [map_entry, sampler_entry, boxes_entry] = occluders::frame_layout_entries();
        // Then the density volume's grid and settings (crate::medium::frame).
        let medium_entries = crate::medium::frame::layout_entries();
        let medium = FrameMedium::new(gpu).map_err(|e| ShadowError::Volume(e.to_string()))?;
        let frame_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("frame.layout"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX_FRAGMENT | wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                map_entry,
                sampler_entry,
                boxes_entry,
                medium_entries[0],
            ],
        });
        let depth_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("particles.depth_layout"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Depth,
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            }],
        });
        let hdr_layout = crate::frame::fullscreen::texture_layout(device, "tonemap.layout");
        let tonemap_pipeline = crate::frame::fullscreen::pipeline(
            device,
            "tonemap.pipeline",
            &shaders::module(
                device,
                "tonemap",
                &shaders::compose("render/tonemap.wgsl", &[]),
            ),
            ("vs_main", "fs_main"),
            &[Some(&frame_layout), Some(&hdr_layout)],
            output_format.into(),
        );
        let targets = Targets::new(device, &depth_layout, &hdr_layout, width, height);
        let particle_layouts = ParticleLayouts::new(device);
        let particle_pipelines = ParticlePipelines::new(
            device,
            "particles",
            &frame_layout,
            &particle_layouts,
            &depth_layout,
            OVER,
        );

        let technique_impl = shadow::create(
            &TechniqueContext {
                gpu,
                frame_layout: &frame_layout,
                depth_layout: &depth_layout,
                particle_layouts: &particle_layouts,
            },
            &technique.name,
            &technique.params,
        )
        .await?;
        let pipelines = TechniquePipelines::new(
            device,
            &frame_layout,
            &particle_layouts,
            technique_impl.as_ref(),
            &technique.params,
        );
        let faces = vec![LightFace::new(gpu, &frame_layout, &medium, technique_impl)?];

        let particle_capacity = 1024;
        let particles = particle_buffer(device, particle_capacity);
        let mut frame_memory = MemoryLedger::for_device(&gpu.limits);
        let lights = LightBuffers::new(
            device,
            &mut frame_memory,
            &particle_layouts,
            &particles,
            particle_capacity,
            1,
            true,
            "particles",
        )?;
        let history =
            history::ShadowHistory::new(device, &mut frame_memory, &particle_layouts.history)?;
        Ok(Self {
            history,
            order: Vec::new(),
            frame_memory,
            opaque_vertices: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("opaque.vertices"),
                size: 4,
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            opaque_vertex_count: 0,
            opaque_source: Vec::new(),
            particles,
            particle_capacity,
            lights,
            particle_layouts,
            particle_pipelines,
            instances: Vec::new(),
            slicing: None,
            frame_layout,
            faces,
            depth_layout,
            hdr_layout,
            tonemap_pipeline,
            targets,
            technique_config: technique.clone(),
            pipelines,
            timer: GpuTimer::new(gpu),
            probe: None,
            built_from: None,
            mixed_res: None,
            low_res: None,
            medium,
            eye_layouts: eye_pass::EyeLayouts::new(device),
            eye_targets: None,
        })
    }

    /// Switches technique or parameters; builds pipelines only when something changed.
    pub async fn set_technique(
        &mut self,
        gpu: &Gpu,
        config: &TechniqueConfig,
    ) -> Result<(), ShadowError> {
        if *config == self.technique_config {
            return Ok(());
        }
        // Every face its own instance (its own maps), all built before any replaces the old.
        let mut techniques = Vec::with_capacity(self.faces.len());
        for _ in 0..self.faces.len() {
            techniques.push(self.create_technique(gpu, config).await?);
        }
        self.pipelines = TechniquePipelines::new(
            &gpu.device,
            &self.frame_layout,
            &self.particle_layouts,
            techniques[0].as_ref(),
            &config.params,
        );
        for (face, technique) in self.faces.iter_mut().zip(techniques) {
            face.technique = technique;
        }
        self.technique_config = config.clone();
        self.probe = None;
        self.built_from = None;
        self.history.reset();
        Ok(())
    }

    async fn create_technique(
        &self,
        gpu: &Gpu,
        config: &TechniqueConfig,
    ) -> Result<Box<dyn ShadowTechnique>, ShadowError> {
        shadow::create(
            &TechniqueContext {
                gpu,
                frame_layout: &self.frame_layout,
                depth_layout: &self.depth_layout,
                particle_layouts: &self.particle_layouts,
            },
            &config.name,
            &config.params,
        )
        .await
    }

    /// Resizes the internal targets (the caller's output view must match); the old targets
    /// stay when the device refuses the new ones.
    pub async fn resize(&mut self, gpu: &Gpu, width: u32, height: u32) -> Result<(), GpuError> {
        if (width, height) != (self.targets.width, self.targets.height) {
            self.targets = gpu
                .scoped(async {
                    Targets::new(
                        &gpu.device,
                        &self.depth_layout,
                        &self.hdr_layout,
                        width,
                        height,
                    )
                })
                .await
                .map_err(|r| r.during(format!("resizing the frame to {width}x{height}")))?;
            self.low_res = None;
            self.eye_targets = None;
        }
        Ok(())
    }

    /// The active technique (a point light's first cube face's instance).
    pub fn technique(&self) -> &dyn ShadowTechnique {
        self.faces[0].technique.as_ref()
    }

    /// The technique's counters from the last frame ([`ShadowTechnique::counters`]): the
    /// spotlight's as they are; under a point light every face's, each name suffixed with its
    /// face (`tile_entries.+x`), since a face's counts are its own smoke's.
    pub fn counters(&self) -> Vec<(String, u64)> {
        let faces = self.face_counters();
        if faces.len() == 1 {
            return faces[0]
                .iter()
                .map(|&(name, v)| (name.to_owned(), v))
                .collect();
        }
        faces
            .iter()
            .zip(shadow::light_space::CUBE_FACE_NAMES)
            .flat_map(|(counters, face)| {
                counters
                    .iter()
                    .map(move |&(name, v)| (format!("{name}.{face}"), v))
            })
            .collect()
    }

    /// The technique's counters in each light face (a point light's in
    /// [`crate::shadow::light_space::cube_face`]'s order).
    pub fn face_counters(&self) -> Vec<Vec<(&'static str, u64)>> {
        self.faces.iter().map(|f| f.technique.counters()).collect()
    }

    /// Light spaces the technique builds its maps in: 1 for a spotlight, 6 (cube faces) for a
    /// point light.
    pub fn light_faces(&self) -> usize {
        self.faces.len()
    }

    /// Bytes the technique allocated in each light face (a point light's cube faces in
    /// [`crate::shadow::light_space::cube_face`]'s order).
    pub fn face_shadow_bytes(&self) -> Vec<u64> {
        self.faces
            .iter()
            .map(|f| f.technique.memory().peak_bytes())
            .collect()
    }

    /// Bytes the technique holds over every light face at its peak (resident: scratch
    /// included, [`crate::gpu::MemoryLedger::peak_bytes`]), and how many of those held now are
    /// transient (build scratch the lookup never reads).
    pub fn shadow_bytes(&self) -> (u64, u64) {
        self.faces.iter().fold((0, 0), |(total, transient), f| {
            let m = f.technique.memory();
            (total + m.peak_bytes(), transient + m.transient_bytes())
        })
    }

    /// Side of the occluders' depth map the lighting reads; `None` for the reference, which
    /// tests the boxes exactly and draws no map.
    /// Texels of a `res`² map, summed over the light's faces, whose ray crosses the smoke of
    /// `particles` (and the scene's density volume) in the scene's framing.
    pub fn texels_covering_smoke(&self, scene: &Scene, particles: &[Particle], res: u32) -> u64 {
        let bounds = self.medium.bounds();
        LightSpace::faces_with(&scene.light, particles, bounds, scene.shadow.framing)
            .iter()
            .map(|face| face.texels_covering_smoke(particles, bounds, res))
            .sum()
    }

    pub fn occluder_map_px(&self) -> Option<u32> {
        self.faces[0].occluders.map_px()
    }

    /// Bytes of the opaque occluders' depth maps and boxes over every light face, apart from
    /// the technique's.
    pub fn occluder_bytes(&self) -> u64 {
        self.faces
            .iter()
            .map(|f| f.occluders.memory().total_bytes())
            .sum()
    }

    /// The HDR frame of the last render (premultiplied radiance, alpha = smoke opacity).
    pub fn hdr_texture(&self) -> &wgpu::Texture {
        &self.targets.hdr
    }

    /// Output size in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.targets.width, self.targets.height)
    }

    /// GPU pass times of the last frame (awaited until it finished); empty without timestamps.
    pub async fn gpu_times(&mut self, gpu: &Gpu) -> Result<PassTimes, GpuError> {
        self.timer.read(gpu).await
    }

    /// Without waiting: the pass times of the newest frame that has finished since the last
    /// call, if any (the viewer calls this every frame).
    pub fn poll_gpu_times(&mut self, gpu: &Gpu) -> Option<PassTimes> {
        self.timer.poll(gpu)
    }

    /// Turns counting the fragment-shader invocations of the build passes on or off for the
    /// frames rendered from now on; returns whether it is on (never without
    /// pipeline-statistics queries). Read the counts with [`Renderer::fragment_counts`].
    pub fn set_count_fragments(&mut self, gpu: &Gpu, on: bool) -> bool {
        self.timer.set_count_fragments(gpu, on)
    }

    /// The fragment counts of the last frame, per pass name (awaited until it finished);
    /// empty when counting was off.
    pub async fn fragment_counts(&mut self, gpu: &Gpu) -> Result<Vec<FragmentTally>, GpuError> {
        self.timer.read_fragments(gpu).await
    }

    /// Layout of group 0 (the frame uniforms), for a pass recorded by
    /// [`Renderer::light_pass_frame`].
    pub fn frame_layout(&self) -> &wgpu::BindGroupLayout {
        &self.frame_layout
    }

    /// Records and submits a frame's start (light fit, uniforms, sort, upload) with `pass`
    /// recorded where the technique's build would be, and nothing after it: the bench measures
    /// the cheapest possible build over the same light-facing billboards this way
    /// (`crate::bench`). Its times and counts read as a frame's.
    pub async fn light_pass_frame(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        pass: LightPass<'_>,
    ) -> Result<FrameStats, ShadowError> {
        let frame = gpu.scoped(async {
            let (mut encoder, stats, _) = self
                .begin_frame(gpu, scene, particles, false, SortOrder::View, Some(pass))
                .await?;
            self.timer.resolve(&mut encoder);
            gpu.queue.submit([encoder.finish()]);
            Ok::<_, ShadowError>(stats)
        });
        frame
            .await
            .map_err(|r| ShadowError::Gpu(r.during("recording a light pass").to_string()))?
    }

    /// Renders one frame of `scene` with `particles` into `output` (size = [`Renderer::size`]).
    /// What the device refuses while recording and submitting the frame (a buffer it cannot
    /// grow, a validation error) is a [`ShadowError::Gpu`] line, not a panic.
    pub async fn render(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        options: &RenderOptions,
        output: &wgpu::TextureView,
    ) -> Result<FrameStats, ShadowError> {
        let frame = gpu.scoped(self.render_unscoped(gpu, scene, particles, options, output));
        frame.await.map_err(|r| {
            let c = &self.technique_config;
            ShadowError::Gpu(
                r.during(format!(
                    "rendering a frame with {} at {} channels and {}x{}",
                    c.name, c.params.channels, c.params.resolution_px, c.params.resolution_px
                ))
                .to_string(),
            )
        })?
    }

    /// The frame as its stages, in order: check the options, the shared start (light fit,
    /// uniforms, sort, upload, the technique's build: [`Renderer::begin_frame`]), the
    /// particles' lighting, the opaque pass, the particle pass (the renderer's, or the
    /// technique's own), the tone map, then one submission.
    async fn render_unscoped(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        options: &RenderOptions,
        output: &wgpu::TextureView,
    ) -> Result<FrameStats, ShadowError> {
        self.check_options(options)?;
        let (mut encoder, mut stats, camera) = self
            .begin_frame(
                gpu,
                scene,
                particles,
                options.reuse_shadow_maps,
                options.sort,
                None,
            )
            .await?;
        let owns_particle_pass = self.faces[0].technique.particle_pass().is_some();
        if !owns_particle_pass {
            self.record_lighting(gpu, &mut encoder, stats.particle_count);
        }
        self.record_opaque(&mut encoder, scene.shading.background);
        self.record_volume(gpu, &mut encoder)?;
        if owns_particle_pass {
            self.record_owned_particle_pass(
                gpu,
                &mut encoder,
                particles,
                &camera,
                options,
                &mut stats,
            )?;
        } else {
            self.record_particle_pass(
                gpu,
                &mut encoder,
                scene,
                particles,
                &camera,
                options,
                stats.particle_count,
            );
        }
        self.record_tonemap(&mut encoder, output);
        self.timer.resolve(&mut encoder);
        gpu.queue.submit([encoder.finish()]);
        Ok(stats)
    }

    /// Forgets the maps the last build made, so that the next frame builds its own even where
    /// it could reuse them (`reuse_shadow_maps`): a frame then renders exactly as one that does
    /// not reuse, and a probe after it reads the maps it built.
    pub fn forget_maps(&mut self) {
        self.built_from = None;
    }

    /// Forgets the shadow's temporal history ([`history`]): the next frame's particles start
    /// afresh, as at the first frame of a technique.
    pub fn reset_history(&mut self) {
        self.history.reset();
    }

    /// Loads `scene`'s density volume, if it has one and it is not the one loaded, as a frame
    /// of it does first (so that its grid is there before any frame: `Renderer::medium`).
    pub async fn load_volume(&mut self, gpu: &Gpu, scene: &Scene) -> Result<(), ShadowError> {
        self.prepare_medium(gpu, scene, 0).await
    }

    /// The frame's density volume, if the scene has one (its grid and settings).
    pub fn medium(&self) -> &FrameMedium {
        &self.medium
    }
}

fn particle_buffer(device: &wgpu::Device, capacity: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("particles.instances"),
        size: capacity * std::mem::size_of::<ParticleInstance>() as u64,
        usage: wgpu::BufferUsages::VERTEX
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    })
}

impl Targets {
    fn new(
        device: &wgpu::Device,
        depth_layout: &wgpu::BindGroupLayout,
        hdr_layout: &wgpu::BindGroupLayout,
        width: u32,
        height: u32,
    ) -> Self {
        let texture = |label, format| {
            device.create_texture(&crate::gpu::texture_2d_descriptor(
                label,
                (width, height),
                format,
                wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_SRC,
            ))
        };
        let hdr = texture("frame.hdr", HDR_FORMAT);
        let depth = texture("frame.depth", DEPTH_FORMAT);
        let hdr_view = hdr.create_view(&Default::default());
        let depth_view = depth.create_view(&Default::default());
        let depth_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("particles.depth_bind_group"),
            layout: depth_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&depth_view),
            }],
        });
        let tonemap_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("tonemap.bind_group"),
            layout: hdr_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&hdr_view),
            }],
        });
        Self {
            width,
            height,
            hdr,
            hdr_view,
            depth_view,
            depth_bind_group,
            tonemap_bind_group,
        }
    }
}

impl TechniquePipelines {
    fn new(
        device: &wgpu::Device,
        frame_layout: &wgpu::BindGroupLayout,
        particle_layouts: &ParticleLayouts,
        technique: &dyn ShadowTechnique,
        params: &shadow::TechniqueParams,
    ) -> Self {
        let name = technique.name();
        let entry = shadow::find(name).expect("a live technique is registered");
        let imports = entry.frame_imports(params);
        let imports = imports.pairs();
        let opaque_module = shaders::module(
            device,
            &format!("opaque[{name}]"),
            &shaders::compose("render/opaque.wgsl", &imports),
        );
        let tech_layout = technique.bind_group_layout();
        let opaque_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("opaque.pipeline_layout"),
            bind_group_layouts: &[Some(frame_layout), Some(tech_layout)],
            immediate_size: 0,
        });
        let opaque = geometry::mesh_pipeline(
            device,
            "opaque.pipeline",
            &opaque_module,
            &opaque_layout,
            wgpu::Face::Back,
            DEPTH_FORMAT,
            &[Some(HDR_FORMAT.into())],
        );
        let lighting = ParticleLighting::new(
            device,
            name,
            frame_layout,
            tech_layout,
            &imports,
            particle_layouts,
        );
        Self {
            opaque,
            lighting,
            eye: None,
        }
    }
}
