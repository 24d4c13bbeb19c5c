//! One cell's measurement on a renderer, up to its comparisons: the technique, `T` at the shaded
//! points and the warm-up frames ([`Bench::prepare`]), then the timed frames and the cell's
//! record with its image ([`Bench::time`]). The CLI's sweep and the web page's both measure
//! their cells here, so that a cell's times, bytes and T error mean one thing in both; each
//! compares the image with `exact` and the technique's own 24-channel image its own way (the
//! CLI writes the difference images, the page keeps them in memory).

use super::plan::{CellTiming, Plan, timed_enough};
use super::{CellResult, Machine, MeasuredAgainst, Timing};
use crate::gpu::Gpu;
use crate::render::reference_check::ReferenceCheck;
use crate::render::shaded::{frame_points, rms_difference};
use crate::render::{OUTPUT_FORMAT, OffscreenTarget, RenderOptions, Renderer};
use crate::scene::Scene;
use crate::shadow;
use crate::sim::Particle;

/// What every cell of a scene is measured on and against: the scene and its particles, the
/// target the frames are drawn into, and the points T is probed at with `exact`'s T there.
pub struct Bench<'a> {
    pub gpu: &'a Gpu,
    pub scene: &'a Scene,
    pub particles: &'a [Particle],
    pub target: &'a OffscreenTarget,
    /// The shaded points, the particle each lights (its owner, for `Renderer::probe_shaded`),
    /// and `exact`'s T at them.
    pub points: &'a [glam::Vec3],
    pub owners: &'a [u32],
    pub exact_t: &'a [f32],
}

/// What [`Bench::prepare`] measured before a cell's timed frames.
pub struct Prepared {
    /// T at the shaded points (not for `none`).
    pub probed: Option<Vec<f32>>,
    pub particle_fragments: Option<u64>,
}

impl Bench<'_> {
    /// The frame of `plan`'s cell, untimed: how a cell's baselines are rendered when nothing
    /// has them yet.
    pub async fn render_image(
        &self,
        renderer: &mut Renderer,
        plan: &Plan,
    ) -> anyhow::Result<image::RgbImage> {
        renderer.set_technique(self.gpu, &plan.config).await?;
        renderer
            .render(
                self.gpu,
                self.scene,
                self.particles,
                &plan.options(),
                &self.target.view,
            )
            .await?;
        Ok(self.target.read_rgb(self.gpu).await?)
    }

    /// Everything a cell does before its timed frames: the technique, the transmittance probe
    /// and the warm-up frames.
    ///
    /// The probe comes first: it builds the maps once (compiling the build's shaders), and the
    /// warm-up frames reuse them, so that a technique whose build takes seconds pays for it once
    /// before the timed frames rather than once per warm-up frame. None of it is timed. The
    /// last warm-up frame counts the particle pass's fragments (never a timed frame).
    pub async fn prepare(
        &self,
        renderer: &mut Renderer,
        plan: &Plan,
        warmup: u32,
    ) -> anyhow::Result<Prepared> {
        renderer.set_technique(self.gpu, &plan.config).await?;
        let probed = match plan.config.name == shadow::frame_baseline().name {
            true => None,
            false => Some(
                renderer
                    .probe_shaded(
                        self.gpu,
                        self.scene,
                        self.particles,
                        self.points,
                        self.owners,
                    )
                    .await?,
            ),
        };
        let warm = RenderOptions {
            reuse_shadow_maps: true,
            ..plan.options()
        };
        let mut particle_fragments = None;
        for i in 0..warmup {
            let count = i + 1 == warmup && renderer.set_count_fragments(self.gpu, true);
            renderer
                .render(
                    self.gpu,
                    self.scene,
                    self.particles,
                    &warm,
                    &self.target.view,
                )
                .await?;
            if count {
                particle_fragments = renderer.particle_fragments(self.gpu).await?;
                renderer.set_count_fragments(self.gpu, false);
            }
            self.gpu.wait_idle()?;
        }
        Ok(Prepared {
            probed,
            particle_fragments,
        })
    }

    /// Times the cell `prepare` readied (the last one it readied) until [`timed_enough`],
    /// building its maps every frame, and reads its image: the cell's record without its
    /// comparisons (`vs_exact`, `vs_own_24`, `vs_full_res` and their files are `None`) and the
    /// image to compare. For `none` it first records its median frame time in `against`,
    /// which every cell after is measured against.
    pub async fn time(
        &self,
        renderer: &mut Renderer,
        plan: &Plan,
        prepared: Prepared,
        timing: &CellTiming,
        key: String,
        against: &mut MeasuredAgainst,
    ) -> anyhow::Result<(CellResult, image::RgbImage)> {
        let options = plan.options();
        let (mut shadow_ms, mut render_ms, mut sort_ms, mut frame_ms, mut wall_ms) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let (mut particles_ms, mut upsample_ms) = (Vec::new(), Vec::new());
        let cell_start = web_time::Instant::now();
        while !timed_enough(
            &wall_ms.iter().map(|ms| ms / 1e3).collect::<Vec<f64>>(),
            cell_start.elapsed().as_secs_f64(),
            timing.frames,
            timing.cell_seconds,
        ) {
            let start = web_time::Instant::now();
            let stats = renderer
                .render(
                    self.gpu,
                    self.scene,
                    self.particles,
                    &options,
                    &self.target.view,
                )
                .await?;
            let times = renderer.gpu_times(self.gpu).await?;
            wall_ms.push(start.elapsed().as_secs_f64() * 1e3);
            let shadow = times.get("shadow").unwrap_or(0.0);
            shadow_ms.push(shadow);
            particles_ms.push(times.get("particles").unwrap_or(0.0));
            upsample_ms.push(
                times.get("downsample").unwrap_or(0.0) + times.get("upsample").unwrap_or(0.0),
            );
            render_ms.push(times.total_ms() - shadow);
            sort_ms.push(stats.sort_ms);
            frame_ms.push(stats.frame_ms(&times));
        }
        if plan.config.name == shadow::frame_baseline().name {
            against.none_frame_ms = Timing::of(&frame_ms).median;
        }
        let (resident_bytes, transient_bytes) = renderer.shadow_bytes();
        let image = self.target.read_rgb(self.gpu).await?;
        let params = &plan.config.params;
        let mut cell = CellResult {
            technique: plan.config.name.clone(),
            channels: params.channels,
            byte_budgets: plan.byte_budgets.clone(),
            memory_budgets: plan.memory_budgets.clone(),
            channel_axis: plan.channel_axis,
            channels_used: renderer.technique().channels_used(),
            shadow_res: params.resolution_px,
            splat: params.splat,
            particle_res: plan.particle_res,
            resident_bytes,
            transient_bytes,
            smoke_texels: renderer.texels_covering_smoke(
                self.scene,
                self.particles,
                params.resolution_px,
            ),
            gpu_shadow_ms: Timing::of(&shadow_ms),
            gpu_render_ms: Timing::of(&render_ms),
            cpu_sort_ms: Timing::of(&sort_ms),
            frame_ms: Timing::of(&frame_ms),
            wall_ms: Timing::of(&wall_ms),
            particles_ms: Timing::of(&particles_ms),
            upsample_ms: Timing::of(&upsample_ms),
            particle_fragments: prepared.particle_fragments,
            frames_timed: frame_ms.len() as u32,
            overhead_ratio: None,
            shadow_ratio: None,
            vs_own_24: None,
            vs_exact: None,
            vs_full_res: None,
            rms_transmittance_error: prepared.probed.map(|t| rms_difference(&t, self.exact_t)),
            image: plan.image(),
            diff_own_24: None,
            flip_own_24: None,
            diff_exact: None,
            flip_exact: None,
            hdr_image: None,
            settings_key: key,
            measured_against: Some(against.clone()),
            motion: None,
        };
        cell.set_ratios(None);
        Ok((cell, image))
    }
}

/// `exact` as a sweep starts a scene: rendered once into the target every cell is then drawn
/// into, with its image, the shaded points and its T at them, and its bytes and light tiles.
pub struct Reference {
    /// Left on `exact`; each cell sets its own technique.
    pub renderer: Renderer,
    pub target: OffscreenTarget,
    pub image: image::RgbImage,
    pub points: Vec<glam::Vec3>,
    pub owners: Vec<u32>,
    pub t: Vec<f32>,
    pub bytes: u64,
    pub tiles: u32,
}

impl Reference {
    /// Renders `exact` over `particles` at the scene's output size, its grid's first map
    /// resolution and splat, and probes its T at the frame's shaded points.
    pub async fn render(
        gpu: &Gpu,
        scene: &Scene,
        particles: &[Particle],
        resolution_px: u32,
        splat: shadow::SplatMode,
    ) -> anyhow::Result<Self> {
        let (w, h) = (scene.output.width_px, scene.output.height_px);
        let reference = shadow::reference().name;
        let mut config = Plan::new(scene, reference, 1, resolution_px, splat).config;
        config.name = reference.to_owned();
        let mut renderer = Renderer::new(gpu, w, h, OUTPUT_FORMAT, &config).await?;
        let target = OffscreenTarget::new(gpu, w, h);
        renderer
            .render(
                gpu,
                scene,
                particles,
                &RenderOptions::default(),
                &target.view,
            )
            .await?;
        let bytes = renderer.shadow_bytes().0;
        let tiles = renderer
            .technique()
            .counters()
            .iter()
            .find(|(n, _)| *n == "tiles_per_side")
            .map_or(0, |(_, v)| *v as u32);
        let image = target.read_rgb(gpu).await?;
        let (points, owners) = frame_points(&renderer, scene, particles);
        let t = renderer
            .probe_shaded(gpu, scene, particles, &points, &owners)
            .await?;
        Ok(Self {
            renderer,
            target,
            image,
            points,
            owners,
            t,
            bytes,
            tiles,
        })
    }

    /// What every cell measured against it records: its figures, its self-check (`check`) and
    /// the machine; no shard, no motion, `none`'s frame time not yet known.
    pub fn measured_against(&self, check: &ReferenceCheck, machine: Machine) -> MeasuredAgainst {
        MeasuredAgainst {
            none_frame_ms: f64::NAN,
            exact_bytes: self.bytes,
            exact_tiles: self.tiles,
            exact_image_sha256: super::image_sha256(&self.image),
            exact_check_points: check.points,
            exact_check_worst: Some(check.worst_difference),
            machine,
            shard: None,
            motion: None,
        }
    }
}
