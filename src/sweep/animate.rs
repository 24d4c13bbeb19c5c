//! The animated sweep (`--animate START..END`, [`crate::motion`]): `exact` rendered once per
//! scene over the span, each frame's particles, points and reference kept; then every cell
//! rendered over the same frames on the sweep's one renderer (its pipelines built once, its
//! maps built every frame), each frame's image and T compared with the reference's.
//!
//! A frame of the span is the scene at that time ([`Scene::at_time`]): the emitters simulated
//! forward step by step (one [`Simulation`] over the whole span), a particle sequence's frame
//! nearest the time.

use crate::Wait;
use std::sync::Arc;

use anyhow::Context;
use glam::Vec3;
use image::RgbImage;

use crate::progress::Progress;
use smokeshadow_core::gpu::Gpu;
use smokeshadow_core::motion::{FrameSample, Recorder, ReferenceChange, Span, linear_luminance};
use smokeshadow_core::render::shaded::{lit_opaque_points, particle_lighting_points};
use smokeshadow_core::render::{OffscreenTarget, RenderOptions, Renderer};
use smokeshadow_core::scene::Scene;
use smokeshadow_core::sim::{Particle, Simulation};

/// The most particles whose lighting points a frame's transmittance is compared at (every
/// k-th particle beyond it): the reference's T of every frame is held in memory.
const MAX_POINT_PARTICLES: usize = 16_384;
/// The most bytes the reference's frames may hold (particles, points, images, samples).
const MAX_HELD_BYTES: u64 = 2 << 30;

/// One frame of the span: the scene at its time, its particles and the points its shadow is
/// compared at.
pub(super) struct Frame {
    pub scene: Scene,
    pub particles: Vec<Particle>,
    /// The lit ground's points first (the same every frame: `fixed`), then the lighting
    /// points of every k-th particle.
    pub points: Vec<Vec3>,
    pub owners: Vec<u32>,
    pub fixed: usize,
}

impl Frame {
    /// The frame as any other (its own build and draw, whatever the renderer built before),
    /// read back, then T at its points from the same maps: the image and what the measures
    /// take of it.
    fn render(
        &self,
        gpu: &Gpu,
        renderer: &mut Renderer,
        target: &OffscreenTarget,
        options: &RenderOptions,
    ) -> anyhow::Result<(RgbImage, FrameSample)> {
        renderer.forget_maps();
        let options = RenderOptions {
            reuse_shadow_maps: true,
            ..*options
        };
        renderer
            .render(gpu, &self.scene, &self.particles, &options, &target.view)
            .wait()?;
        let image = target.read_rgb(gpu).wait()?;
        let transmittance = renderer
            .probe_shaded(
                gpu,
                &self.scene,
                &self.particles,
                &self.points,
                &self.owners,
            )
            .wait()?;
        let sample = FrameSample {
            luminance: linear_luminance(&image),
            transmittance,
            fixed_points: self.fixed,
        };
        Ok((image, sample))
    }
}

/// `exact` over the span: what every cell's frames are compared with.
pub(super) struct ExactFrames {
    pub frames: Vec<Frame>,
    pub samples: Vec<FrameSample>,
    /// Its 8-bit frames, shared with each cell's comparison thread (FLIP per frame).
    pub images: Arc<Vec<RgbImage>>,
    pub change: ReferenceChange,
    /// The worst |ΔT| of its self-check over every frame, and the fewest points one compared.
    pub check_worst: f64,
    pub check_points: usize,
}

/// The span's frames of `scene`: the emitters stepped forward once over the span, or the
/// particle file read at each time.
fn frames(scene: &Scene, span: &Span, (w, h): (u32, u32)) -> anyhow::Result<Vec<Frame>> {
    let mut sim = scene.particles.is_none().then(|| Simulation::new(scene));
    let camera = smokeshadow_core::render::CameraMatrices::new(scene, w, h);
    let ground = lit_opaque_points(
        scene,
        &camera,
        w,
        h,
        smokeshadow_core::render::shaded::SHADED_STRIDE_PX,
    );
    let mut out = Vec::new();
    for t in span.times() {
        let at = span.scene_at(scene, t);
        let eye = at.camera.position;
        let particles = match (&mut sim, &at.particles) {
            (Some(sim), _) => {
                sim.advance_to(t);
                sim.particles()
            }
            (None, Some(source)) => source
                .particles_at(t)
                .with_context(|| format!("--animate: the particles at t = {t} s"))?,
            (None, None) => unreachable!("a scene without a particle file simulates"),
        };
        let stride = particles.len().div_ceil(MAX_POINT_PARTICLES).max(1);
        let mut points = ground.clone();
        let mut owners = vec![smokeshadow_core::shadow::NO_OWNER; ground.len()];
        for (i, p) in particles.iter().enumerate().step_by(stride) {
            points.extend(particle_lighting_points(eye, std::slice::from_ref(p)));
            owners.extend([i as u32; 4]);
        }
        out.push(Frame {
            scene: at,
            particles,
            points,
            owners,
            fixed: ground.len(),
        });
    }
    Ok(out)
}

impl ExactFrames {
    /// Renders `exact` (the `renderer`'s technique) at every frame of `span`, checks it against
    /// the closed form at each, and keeps what the cells are compared with. Refuses a span
    /// whose frames would hold more than [`MAX_HELD_BYTES`].
    pub fn render(
        gpu: &Gpu,
        renderer: &mut Renderer,
        target: &OffscreenTarget,
        scene: &Scene,
        span: Span,
        progress: &mut Progress,
    ) -> anyhow::Result<Self> {
        let size = renderer.size();
        let frames = progress.suspend(|| frames(scene, &span, size))?;
        let pixels = u64::from(size.0) * u64::from(size.1);
        let held: u64 = frames
            .iter()
            .map(|f| {
                (f.particles.len() * std::mem::size_of::<Particle>()) as u64
                    + f.points.len() as u64 * 20
                    + pixels * 7
            })
            .sum();
        if held > MAX_HELD_BYTES {
            anyhow::bail!(
                "--animate: {} of {} at {}x{} hold {} in memory (the reference's frames): at most {}; give fewer frames or a smaller --size",
                span.describe(),
                scene.name,
                size.0,
                size.1,
                crate::report::bytes(held),
                crate::report::bytes(MAX_HELD_BYTES)
            );
        }
        let (mut samples, mut images) = (Vec::new(), Vec::new());
        let (mut check_worst, mut check_points) = (0.0f64, usize::MAX);
        for f in &frames {
            let (image, sample) = f.render(gpu, renderer, target, &RenderOptions::default())?;
            let check = progress.suspend(|| {
                smokeshadow_core::render::reference_check::verify(
                    renderer,
                    gpu,
                    &f.scene,
                    &f.particles,
                )
                .wait()
            })?;
            check_worst = check_worst.max(check.worst_difference);
            check_points = check_points.min(check.points);
            samples.push(sample);
            images.push(image);
        }
        let change = ReferenceChange::of(span, &samples);
        Ok(Self {
            frames,
            samples,
            images: Arc::new(images),
            change,
            check_worst,
            check_points,
        })
    }

    /// Renders the `renderer`'s technique at every frame ([`Frame::render`]) and records each
    /// against the reference's: the recorder and the frames, for the FLIP per frame on the
    /// cell's comparison thread ([`finish`]).
    pub fn record(
        &self,
        gpu: &Gpu,
        renderer: &mut Renderer,
        target: &OffscreenTarget,
        options: &RenderOptions,
    ) -> anyhow::Result<(Recorder, Vec<RgbImage>)> {
        let mut recorder = Recorder::new();
        let mut images = Vec::with_capacity(self.frames.len());
        // The span's first frame has no history of its own (`[shadow] history`), whatever the
        // renderer drew before it.
        renderer.reset_history();
        for f in &self.frames {
            let (image, sample) = f.render(gpu, renderer, target, options)?;
            recorder.push(sample, &self.samples);
            images.push(image);
        }
        Ok((recorder, images))
    }
}

/// The cell's motion from what [`ExactFrames::record`] gave: the FLIP of every frame against
/// the reference's (in parallel), then the measures.
pub(super) fn finish(
    recorder: Recorder,
    images: &[RgbImage],
    exact: &[RgbImage],
) -> anyhow::Result<smokeshadow_core::motion::Motion> {
    use rayon::prelude::*;
    let flips: Vec<f64> = images
        .par_iter()
        .zip(exact.par_iter())
        .map(|(image, reference)| {
            crate::diff::compare_with(reference, image, crate::diff::Ssim::Skip)
                .map(|c| c.metrics.flip_mean)
        })
        .collect::<Result<_, _>>()?;
    Ok(recorder.finish(&flips))
}

/// The side-by-side's file in a scene's folder.
pub(super) const ANIMATION_FILE: &str = "motion.png";

impl ExactFrames {
    /// Renders each of `cells` (a label, its technique and options) over the span and writes
    /// `exact` and them side by side, each frame at half size, as an animated PNG at `path`
    /// playing at the span's rate (written to a temporary file, then renamed).
    pub fn write_animation(
        &self,
        gpu: &Gpu,
        renderer: &mut Renderer,
        target: &OffscreenTarget,
        cells: &[(&smokeshadow_core::render::TechniqueConfig, RenderOptions)],
        path: &std::path::Path,
    ) -> anyhow::Result<()> {
        let half = |image: &RgbImage| {
            image::imageops::resize(
                image,
                (image.width() / 2).max(1),
                (image.height() / 2).max(1),
                image::imageops::FilterType::Triangle,
            )
        };
        let mut columns: Vec<Vec<RgbImage>> = vec![self.images.iter().map(half).collect()];
        for (config, options) in cells {
            renderer.set_technique(gpu, config).wait()?;
            renderer.reset_history();
            let mut frames = Vec::with_capacity(self.frames.len());
            for f in &self.frames {
                renderer.forget_maps();
                renderer
                    .render(gpu, &f.scene, &f.particles, options, &target.view)
                    .wait()?;
                frames.push(half(&target.read_rgb(gpu).wait()?));
            }
            columns.push(frames);
        }
        let (w, h) = columns[0][0].dimensions();
        let strip = |k: usize| {
            let mut out = RgbImage::new(w * columns.len() as u32, h);
            for (i, column) in columns.iter().enumerate() {
                image::imageops::replace(&mut out, &column[k], i64::from(w) * i as i64, 0);
            }
            out
        };
        let mut bytes = Vec::new();
        {
            let mut encoder = png::Encoder::new(&mut bytes, w * columns.len() as u32, h);
            encoder.set_color(png::ColorType::Rgb);
            encoder.set_depth(png::BitDepth::Eight);
            encoder.set_animated(self.frames.len() as u32, 0)?;
            // 1/fps seconds a frame: 100 / (100 fps), exact to a hundredth of a frame per second
            // (fps is at most 240).
            let fps = self.change.span.fps;
            encoder.set_frame_delay(100, (f64::from(fps) * 100.0).round().max(1.0) as u16)?;
            let mut writer = encoder.write_header()?;
            for k in 0..self.frames.len() {
                writer.write_image_data(strip(k).as_raw())?;
            }
            writer.finish()?;
        }
        crate::output::write_atomic(path, &bytes)
    }
}
