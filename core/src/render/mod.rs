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

pub mod history;
pub mod mixed_res;
pub mod reference_check;
pub mod shaded;
pub mod sort;

pub use mixed_res::{ParticleRes, parse_particle_res};
pub use sort::SortOrder;

// The frame's building blocks live in `crate::frame` (the techniques share them); re-exported
// here, where callers of the renderer look for them.
pub use crate::frame::{
    CameraMatrices, DEPTH_FORMAT, HDR_FORMAT, OUTPUT_FORMAT, OVER, ParticleLayouts,
    ParticlePipelines, UNDER, geometry, gpu_data, particles,
};

use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use crate::frame::occluders::{self, Occluders};
use crate::gpu::{FragmentTally, Gpu, GpuError, GpuTimer, MemoryLedger, PassTimes, TargetWrites};
use crate::medium::eye_pass;
use crate::medium::frame::FrameMedium;
use crate::scene::{LightKind, Scene};
use crate::shaders;
use crate::shadow::probe::Probe;
use crate::shadow::{
    self, LightSpace, ShadowError, ShadowTechnique, TechniqueContext, TechniqueParams,
};
use crate::sim::Particle;
use gpu_data::{FrameUniforms, OpaqueVertex, ParticleInstance};
use particles::{LightBuffers, LitParticle, ParticleLighting};

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
    pub fn new(
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
        )?;
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
    pub fn set_technique(
        &mut self,
        gpu: &Gpu,
        config: &TechniqueConfig,
    ) -> Result<(), ShadowError> {
        if *config == self.technique_config {
            return Ok(());
        }
        // Every face its own instance (its own maps), all built before any replaces the old.
        let techniques = (0..self.faces.len())
            .map(|_| self.create_technique(gpu, config))
            .collect::<Result<Vec<_>, _>>()?;
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

    fn create_technique(
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
    }

    /// Makes one light face per light space of `light` (a point light's six cube faces, a
    /// spotlight's one), each with its own instance of the technique.
    fn match_light(
        &mut self,
        gpu: &Gpu,
        light: &crate::scene::Spotlight,
    ) -> Result<(), ShadowError> {
        let wanted = light.kind.faces();
        self.faces.truncate(wanted);
        while self.faces.len() < wanted {
            let technique = self.create_technique(gpu, &self.technique_config.clone())?;
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

    /// Resizes the internal targets (the caller's output view must match); the old targets
    /// stay when the device refuses the new ones.
    pub fn resize(&mut self, gpu: &Gpu, width: u32, height: u32) -> Result<(), GpuError> {
        if (width, height) != (self.targets.width, self.targets.height) {
            self.targets = gpu
                .scoped(|| {
                    Targets::new(
                        &gpu.device,
                        &self.depth_layout,
                        &self.hdr_layout,
                        width,
                        height,
                    )
                })
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

    /// GPU pass times of the last frame (blocks until it finished); empty without timestamps.
    pub fn gpu_times(&mut self, gpu: &Gpu) -> Result<PassTimes, GpuError> {
        self.timer.read(gpu)
    }

    /// Fragment shader invocations of the particle pass in the last frame rendered with
    /// fragment counting on ([`Renderer::set_count_fragments`]; blocks until it finished);
    /// `None` when counting was off, or the technique drew the particles itself (`has`).
    pub fn particle_fragments(&mut self, gpu: &Gpu) -> Result<Option<u64>, GpuError> {
        Ok(particle_fragments(&self.fragment_counts(gpu)?))
    }

    /// The low-resolution targets for `res` at the current size, made when missing.
    fn ensure_low_res(&mut self, gpu: &Gpu, res: ParticleRes) {
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

    /// The fragment counts of the last frame, per pass name (blocks until it finished);
    /// empty when counting was off.
    pub fn fragment_counts(&mut self, gpu: &Gpu) -> Result<Vec<FragmentTally>, GpuError> {
        self.timer.read_fragments(gpu)
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
    pub fn light_pass_frame(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        pass: LightPass<'_>,
    ) -> Result<FrameStats, ShadowError> {
        let frame = gpu.scoped(|| -> Result<FrameStats, ShadowError> {
            let (mut encoder, stats, _) =
                self.begin_frame(gpu, scene, particles, false, SortOrder::View, Some(pass))?;
            self.timer.resolve(&mut encoder);
            gpu.queue.submit([encoder.finish()]);
            Ok(stats)
        });
        frame.map_err(|r| ShadowError::Gpu(r.during("recording a light pass").to_string()))?
    }

    /// Renders one frame of `scene` with `particles` into `output` (size = [`Renderer::size`]).
    /// What the device refuses while recording and submitting the frame (a buffer it cannot
    /// grow, a validation error) is a [`ShadowError::Gpu`] line, not a panic.
    pub fn render(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        options: &RenderOptions,
        output: &wgpu::TextureView,
    ) -> Result<FrameStats, ShadowError> {
        let frame = gpu.scoped(|| self.render_unscoped(gpu, scene, particles, options, output));
        frame.map_err(|r| {
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
    fn render_unscoped(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        options: &RenderOptions,
        output: &wgpu::TextureView,
    ) -> Result<FrameStats, ShadowError> {
        self.check_options(options)?;
        let (mut encoder, mut stats, camera) = self.begin_frame(
            gpu,
            scene,
            particles,
            options.reuse_shadow_maps,
            options.sort,
            None,
        )?;
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

    /// Makes the frame's volume the scene's (loading it when its source changed; every face's
    /// group 0 is made again then), and refuses a technique that cannot shadow it.
    fn prepare_medium(
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

    /// The eye's march of the density volume over the opaque scene (nothing without one).
    fn record_volume(
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
    pub fn load_volume(&mut self, gpu: &Gpu, scene: &Scene) -> Result<(), ShadowError> {
        self.prepare_medium(gpu, scene, 0)
    }

    /// The frame's density volume, if the scene has one (its grid and settings).
    pub fn medium(&self) -> &FrameMedium {
        &self.medium
    }

    /// Refuses the options the active technique cannot draw with: a technique that draws the
    /// particles itself draws them at full resolution only.
    fn check_options(&mut self, options: &RenderOptions) -> Result<(), ShadowError> {
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

    /// Each particle's lighting, once, with the technique's T (part of rendering them); a point
    /// light's faces each light the points in their face. In the technique's order when it has
    /// one for these particles (the first face's: the order only speeds the lighting up,
    /// whichever face's it is).
    fn record_lighting(
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
    fn record_opaque(&mut self, encoder: &mut wgpu::CommandEncoder, background: Vec3) {
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

    /// The particle pass of a technique that draws the particles itself (`has`: slices lit as
    /// they are drawn); its own sort, when it makes one, joins the frame's sort time.
    fn record_owned_particle_pass(
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
    fn record_particle_pass(
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
    fn record_downsample(&mut self, encoder: &mut wgpu::CommandEncoder) {
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
    fn record_upsample(
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
    fn record_tonemap(&mut self, encoder: &mut wgpu::CommandEncoder, output: &wgpu::TextureView) {
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

    /// The start every frame shares: fit the light space, upload the uniforms, sort the particles
    /// back to front for the camera in `sort`'s order (timed) and upload them, and record the
    /// technique's build.
    /// `build`, when given, is recorded instead of the technique's build (the bench's light
    /// pass, see [`Renderer::light_pass_frame`]).
    fn begin_frame(
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
        self.match_light(gpu, &scene.light)?;
        self.prepare_medium(gpu, scene, particles.len())?;

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
                        face.technique.build(
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
                        )?;
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

    /// Transmittance T(p) from the light to each of `points` (world metres) as the active
    /// technique sees it for this frame of `scene`: the technique builds its maps as for
    /// [`Renderer::render`] (unless they are already this frame's: see
    /// [`RenderOptions::reuse_shadow_maps`]), then a compute shader evaluates the same
    /// `shadow_transmittance` the lighting shaders call.
    pub fn probe(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        points: &[Vec3],
    ) -> anyhow::Result<Vec<f32>> {
        self.probe_scoped(gpu, scene, particles, points, None, false)
    }

    /// As [`Renderer::probe`] at a frame's shaded points, where `owners` names the particle
    /// whose lighting point each point is (`shaded::point_owners`; `shadow::NO_OWNER` for the
    /// opaque points): a technique that lights a particle's points together (`has`) then gives
    /// each the T the frame's lighting used, so the error measured is the error rendered.
    pub fn probe_shaded(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        points: &[Vec3],
        owners: &[u32],
    ) -> anyhow::Result<Vec<f32>> {
        self.probe_scoped(gpu, scene, particles, points, Some(owners), false)
    }

    /// Every particle as the last frame's lighting lit it: its sphere and the smoke's T at its
    /// four lighting points, read back from the lighting buffer (the technique's own for one
    /// that draws the particles itself). Waits for the GPU.
    pub fn lit_particles(&mut self, gpu: &Gpu) -> anyhow::Result<Vec<LitParticle>> {
        if let Some(pass) = self.faces[0].technique.particle_pass() {
            return Ok(pass.lit_particles(gpu)?);
        }
        let lights = self.lights.read(gpu, self.instances.len())?;
        Ok(LitParticle::of(&self.instances, &lights))
    }

    /// As [`Renderer::probe`], but the light's whole visibility at each point as the lighting
    /// computes it: T times the opaque occluders' visibility (their filtered depth map, or for
    /// the reference the exact test). The reference's self-check compares it with the CPU's
    /// closed form (`reference_check`).
    pub fn probe_with_occluders(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        points: &[Vec3],
    ) -> anyhow::Result<Vec<f32>> {
        self.probe_scoped(gpu, scene, particles, points, None, true)
    }

    fn probe_scoped(
        &mut self,
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        points: &[Vec3],
        owners: Option<&[u32]>,
        with_occluders: bool,
    ) -> anyhow::Result<Vec<f32>> {
        let t = gpu
            .scoped(|| self.probe_unscoped(gpu, scene, particles, points, owners, with_occluders));
        t.map_err(|r| {
            r.during(format!(
                "probing {} at {} points",
                self.technique_config.name,
                points.len()
            ))
        })?
    }

    fn probe_unscoped(
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
        let (mut encoder, stats, _) =
            self.begin_frame(gpu, scene, particles, true, SortOrder::View, None)?;
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
            Some(owner) => owner.probe(
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
            )?,
            None => {
                let lookups: Vec<(&wgpu::BindGroup, &wgpu::BindGroup)> = self
                    .faces
                    .iter()
                    .map(|f| (&f.frame_bind_group, f.technique.bind_group()))
                    .collect();
                let pending = probe.record(gpu, &mut encoder, &lookups, points);
                gpu.queue.submit([encoder.finish()]);
                pending.read(gpu)?
            }
        };
        match owners {
            Some(owners) if self.history.active() => self.filtered_at(gpu, results, owners),
            _ => Ok(results),
        }
    }

    /// The probe's T at a filtered frame's shaded points ([`Renderer::probe_shaded`]): at a
    /// particle's lighting points the T the frame's lighting used, its history's
    /// ([`history`]), read back from the lighting; elsewhere the lookup's.
    fn filtered_at(
        &self,
        gpu: &Gpu,
        mut results: Vec<f32>,
        owners: &[u32],
    ) -> anyhow::Result<Vec<f32>> {
        let lights = self.lights.read(gpu, self.instances.len())?;
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

    fn upload_opaque(&mut self, gpu: &Gpu, scene: &Scene) {
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

    fn upload_particles(&mut self, gpu: &Gpu) -> Result<(), ShadowError> {
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

/// Identifies the inputs of a technique's build: the particles, the spotlight and its fitted
/// light space, the technique's configuration.
/// The technique in each of `faces`, with the face's group 0, for the owner of the particle pass
/// or the probe in the first face.
fn other_faces(faces: &mut [LightFace]) -> Vec<shadow::OtherFace<'_>> {
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

fn build_key(
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

fn frame_uniforms(
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
fn frame_bind_group(
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

/// An offscreen output texture the CLI and tests render into and read back.
pub struct OffscreenTarget {
    pub texture: wgpu::Texture,
    pub view: wgpu::TextureView,
}

impl OffscreenTarget {
    pub fn new(gpu: &Gpu, width: u32, height: u32) -> Self {
        let texture = gpu
            .device
            .create_texture(&crate::gpu::texture_2d_descriptor(
                "output",
                (width, height),
                OUTPUT_FORMAT,
                wgpu::TextureUsages::RENDER_ATTACHMENT
                    | wgpu::TextureUsages::COPY_SRC
                    | wgpu::TextureUsages::TEXTURE_BINDING,
            ));
        let view = texture.create_view(&Default::default());
        Self { texture, view }
    }

    /// The tone-mapped frame it holds, read back as 8-bit sRGB (alpha dropped). Waits for the
    /// GPU.
    pub fn read_rgb(&self, gpu: &Gpu) -> Result<image::RgbImage, crate::gpu::GpuError> {
        let rgba = crate::gpu::read_texture_rgba8(gpu, &self.texture)?;
        Ok(image::DynamicImage::ImageRgba8(rgba).into_rgb8())
    }
}

/// The result of [`render_offscreen`].
pub struct OffscreenFrame {
    /// The tone-mapped sRGB frame.
    pub image: image::RgbaImage,
    /// The HDR frame: premultiplied linear radiance, alpha = smoke opacity.
    pub hdr: crate::gpu::Rgba16fImage,
    pub stats: FrameStats,
    pub times: PassTimes,
}

/// Renders one frame offscreen at the scene's output size and reads it back: the path the CLI's
/// `render` and the GPU tests share.
pub fn render_offscreen(
    gpu: &Gpu,
    scene: &Scene,
    particles: &[Particle],
    technique: &TechniqueConfig,
    options: &RenderOptions,
) -> anyhow::Result<OffscreenFrame> {
    let (w, h) = (scene.output.width_px, scene.output.height_px);
    let mut renderer = Renderer::new(gpu, w, h, OUTPUT_FORMAT, technique)?;
    let target = OffscreenTarget::new(gpu, w, h);
    let stats = renderer.render(gpu, scene, particles, options, &target.view)?;
    let times = renderer.gpu_times(gpu)?;
    Ok(OffscreenFrame {
        image: crate::gpu::read_texture_rgba8(gpu, &target.texture)?,
        hdr: crate::gpu::read_texture_rgba16f(gpu, renderer.hdr_texture())?,
        stats,
        times,
    })
}
