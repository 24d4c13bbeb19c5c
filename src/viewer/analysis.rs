//! The viewer's background worker: everything that must read pixels or values back from the
//! GPU — the live error against `exact`, the difference and FLIP images of a comparison, the
//! transmittance probe, full-resolution screenshots — runs here, on its own renderers sharing the
//! device, so the UI thread never waits on a readback. Requests are superseded: when several of
//! one kind queue up, only the newest is answered.

use crate::Wait;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, Sender, TryRecvError};

use glam::Vec3;

use crate::diff::{self, Metrics};
use smokeshadow_core::gpu::Gpu;
use smokeshadow_core::render::{
    OUTPUT_FORMAT, OffscreenTarget, RenderOptions, Renderer, TechniqueConfig,
};
use smokeshadow_core::scene::Scene;
use smokeshadow_core::shadow::LightSpace;
use smokeshadow_core::sim::{Particle, Simulation};

/// One frame to render: the scene (camera and light as the viewer has them), its particles.
#[derive(Clone)]
pub struct Frame {
    pub scene: Scene,
    pub particles: Arc<Vec<Particle>>,
    pub options: RenderOptions,
}

/// What the UI asks for.
pub enum Request {
    /// Image metrics of `a` against `exact` (and of `b` against `a`, with the x4 difference and
    /// FLIP map images, when `b` is given; and with `motion`, the frame that many seconds
    /// earlier rendered too, for `a`'s change beside `exact`'s).
    Compare {
        id: u64,
        frame: Frame,
        a: TechniqueConfig,
        b: Option<TechniqueConfig>,
        exact: TechniqueConfig,
        motion: Option<f32>,
    },
    /// T along the light ray through `point` for each configuration, `samples` points across
    /// the smoke's depth range.
    Probe {
        id: u64,
        frame: Frame,
        configs: Vec<TechniqueConfig>,
        point: Vec3,
        samples: u32,
    },
    /// Renders `config` for `frame` (at the scene's output size) and sends the image back: the
    /// viewer shows `exact` this way, since its build reads its list sizes back from the GPU.
    Render {
        id: u64,
        /// 0 for A, 1 for B: a newer request for the same side supersedes an older one.
        side: u8,
        frame: Frame,
        config: TechniqueConfig,
    },
    /// Renders `config` at the scene's full size and writes it to `path` as PNG.
    Screenshot {
        frame: Frame,
        config: TechniqueConfig,
        path: std::path::PathBuf,
    },
}

impl Request {
    fn kind(&self) -> u8 {
        match self {
            Request::Compare { .. } => 0,
            Request::Probe { .. } => 1,
            Request::Screenshot { .. } => 2,
            Request::Render { side, .. } => 3 + side,
        }
    }
}

/// T(z) of one configuration along the probed ray.
#[derive(Clone, Debug)]
pub struct ProbeSeries {
    pub label: String,
    /// (distance from the light in metres, T).
    pub points: Vec<[f64; 2]>,
}

/// What the worker answers.
pub enum Reply {
    Compare {
        id: u64,
        /// A's image at the frame's full size.
        image_a: image::RgbImage,
        a_vs_exact: Metrics,
        /// B against A: metrics, the x4 difference and the FLIP map.
        b_vs_a: Option<Box<(Metrics, image::RgbImage, image::RgbImage)>>,
        /// A's change from the earlier frame beside `exact`'s (`motion`), and when that frame is.
        motion: Option<Box<(smokeshadow_core::motion::ChangePictures, f32)>>,
        /// Seconds the worker took.
        seconds: f64,
    },
    Probe {
        id: u64,
        point: Vec3,
        /// Distance from the light to the probed point.
        point_distance_m: f32,
        series: Vec<ProbeSeries>,
    },
    Render {
        id: u64,
        image: image::RgbImage,
        /// Bytes the technique allocated.
        bytes: u64,
    },
    Screenshot {
        path: std::path::PathBuf,
    },
    /// A request failed; one line for the UI.
    Error(String),
}

/// Handle to the worker thread.
pub struct Analysis {
    requests: Sender<Request>,
    replies: Receiver<Reply>,
    pending: Arc<AtomicUsize>,
}

impl Analysis {
    /// Starts the worker on `gpu` (the same device the UI renders with).
    pub fn new(gpu: Arc<Gpu>) -> Self {
        let (requests, inbox) = std::sync::mpsc::channel::<Request>();
        let (outbox, replies) = std::sync::mpsc::channel::<Reply>();
        let pending = Arc::new(AtomicUsize::new(0));
        let counter = pending.clone();
        std::thread::Builder::new()
            .name("smokeshadow-analysis".into())
            .spawn(move || Worker::new(gpu).serve(&inbox, &outbox, &counter))
            .expect("the analysis thread starts");
        Self {
            requests,
            replies,
            pending,
        }
    }

    pub fn send(&self, request: Request) {
        self.pending.fetch_add(1, Ordering::SeqCst);
        if self.requests.send(request).is_err() {
            self.pending.fetch_sub(1, Ordering::SeqCst);
        }
    }

    /// The next reply, if one is ready.
    pub fn try_recv(&self) -> Option<Reply> {
        self.replies.try_recv().ok()
    }

    /// Whether requests are queued or being worked on.
    pub fn busy(&self) -> bool {
        self.pending.load(Ordering::SeqCst) > 0
    }
}

/// The worker's renderers, kept between requests (pipelines are built once per technique).
struct Worker {
    gpu: Arc<Gpu>,
    renderers: Vec<(TechniqueConfig, (u32, u32), Renderer, OffscreenTarget)>,
    /// The emitters' simulation of the last earlier frame it made, and what it simulates (a
    /// later request steps it on from there).
    sim: Option<(smokeshadow_core::sim::SimInputs, Simulation)>,
}

impl Worker {
    fn new(gpu: Arc<Gpu>) -> Self {
        Self {
            gpu,
            renderers: Vec::new(),
            sim: None,
        }
    }

    /// `frame` as it was `dt_s` earlier (not before t = 0): the scene at that time, its
    /// particles simulated to it (or a particle file's frame then).
    fn earlier(&mut self, frame: &Frame, dt_s: f32) -> anyhow::Result<Frame> {
        let t = (frame.scene.sim.duration_s - dt_s).max(0.0);
        let scene = frame.scene.at_time(t);
        let particles = match &scene.particles {
            Some(source) => source.particles_at(t)?,
            None => {
                let inputs = Simulation::inputs(&scene);
                let sim = match &mut self.sim {
                    Some((kept, sim)) if *kept == inputs => sim,
                    slot => &mut slot.insert((inputs, Simulation::new(&scene))).1,
                };
                sim.advance_to(t);
                sim.particles()
            }
        };
        Ok(Frame {
            scene,
            particles: Arc::new(particles),
            options: frame.options,
        })
    }

    fn serve(mut self, inbox: &Receiver<Request>, outbox: &Sender<Reply>, pending: &AtomicUsize) {
        let mut queue: Vec<Request> = Vec::new();
        loop {
            if queue.is_empty() {
                match inbox.recv() {
                    Ok(r) => queue.push(r),
                    Err(_) => return,
                }
            }
            loop {
                match inbox.try_recv() {
                    Ok(r) => queue.push(r),
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => return,
                }
            }
            // Newest of each kind wins (screenshots are all kept).
            let request = queue.remove(0);
            let superseded =
                request.kind() != 2 && queue.iter().any(|r| r.kind() == request.kind());
            let reply = if superseded {
                None
            } else {
                Some(
                    self.handle(request)
                        .unwrap_or_else(|err| Reply::Error(format!("{err:#}"))),
                )
            };
            pending.fetch_sub(1, Ordering::SeqCst);
            if let Some(reply) = reply
                && outbox.send(reply).is_err()
            {
                return;
            }
        }
    }

    /// Renders `config` for `frame` at the scene's output size and reads the image back.
    fn render(
        &mut self,
        frame: &Frame,
        config: &TechniqueConfig,
    ) -> anyhow::Result<image::RgbImage> {
        let size = (frame.scene.output.width_px, frame.scene.output.height_px);
        let gpu = self.gpu.clone();
        let (_, _, renderer, target) = self.renderer(config, size)?;
        // Each frame on its own: the worker's frames are no sequence for a shadow history.
        renderer.reset_history();
        renderer
            .render(
                &gpu,
                &frame.scene,
                &frame.particles,
                &frame.options,
                &target.view,
            )
            .wait()?;
        Ok(target.read_rgb(&gpu).wait()?)
    }

    /// A renderer for `config` at `size`: reused when one matches, else one of the three kept is
    /// replaced (most requests alternate between A, B and `exact`).
    fn renderer(
        &mut self,
        config: &TechniqueConfig,
        size: (u32, u32),
    ) -> anyhow::Result<&mut (TechniqueConfig, (u32, u32), Renderer, OffscreenTarget)> {
        if let Some(i) = self
            .renderers
            .iter()
            .position(|(c, s, _, _)| c == config && *s == size)
        {
            let entry = self.renderers.remove(i);
            self.renderers.push(entry);
        } else {
            let renderer =
                Renderer::new(&self.gpu, size.0, size.1, OUTPUT_FORMAT, config).wait()?;
            let target = OffscreenTarget::new(&self.gpu, size.0, size.1);
            if self.renderers.len() >= 3 {
                self.renderers.remove(0);
            }
            self.renderers
                .push((config.clone(), size, renderer, target));
        }
        Ok(self.renderers.last_mut().expect("just pushed"))
    }

    fn handle(&mut self, request: Request) -> anyhow::Result<Reply> {
        match request {
            Request::Compare {
                id,
                frame,
                a,
                b,
                exact,
                motion,
            } => {
                let start = std::time::Instant::now();
                let image_a = self.render(&frame, &a)?;
                let image_exact = self.render(&frame, &exact)?;
                let motion = match motion {
                    None => None,
                    Some(dt_s) => {
                        let before = self.earlier(&frame, dt_s)?;
                        let a0 = self.render(&before, &a)?;
                        let r0 = self.render(&before, &exact)?;
                        let pictures = smokeshadow_core::motion::ChangePictures::of(
                            &a0,
                            &image_a,
                            &r0,
                            &image_exact,
                        );
                        Some(Box::new((pictures, before.scene.sim.duration_s)))
                    }
                };
                let a_vs_exact = diff::compare(&image_exact, &image_a)?.metrics;
                let b_vs_a = match b {
                    None => None,
                    Some(b) => {
                        let image_b = self.render(&frame, &b)?;
                        let comparison = diff::compare(&image_a, &image_b)?;
                        let x4 =
                            diff::enhanced_difference(&image_a, &image_b, diff::DEFAULT_ENHANCE);
                        let heat = diff::flip_heatmap(&comparison);
                        Some(Box::new((comparison.metrics, x4, heat)))
                    }
                };
                Ok(Reply::Compare {
                    id,
                    image_a,
                    a_vs_exact,
                    b_vs_a,
                    motion,
                    seconds: start.elapsed().as_secs_f64(),
                })
            }
            Request::Probe {
                id,
                frame,
                configs,
                point,
                samples,
            } => {
                let light = LightSpace::cone(&frame.scene.light, &frame.particles);
                let origin = frame.scene.light.position;
                let dir = (point - origin).normalize_or(Vec3::NEG_Y);
                let n = samples.max(2);
                let distances: Vec<f32> = (0..n)
                    .map(|i| {
                        light.near_m + (light.far_m - light.near_m) * i as f32 / (n - 1) as f32
                    })
                    .collect();
                let points: Vec<Vec3> = distances.iter().map(|&t| origin + dir * t).collect();
                let size = (frame.scene.output.width_px, frame.scene.output.height_px);
                let mut series = Vec::new();
                for config in &configs {
                    let gpu = self.gpu.clone();
                    let (_, _, renderer, _) = self.renderer(config, size)?;
                    let t = renderer
                        .probe(&gpu, &frame.scene, &frame.particles, &points)
                        .wait()?;
                    series.push(ProbeSeries {
                        label: if config.name == smokeshadow_core::shadow::reference().name {
                            config.name.clone()
                        } else {
                            format!("{} {}", config.name, config.params.channels)
                        },
                        points: distances
                            .iter()
                            .zip(t)
                            .map(|(&d, t)| [f64::from(d), f64::from(t)])
                            .collect(),
                    });
                }
                Ok(Reply::Probe {
                    id,
                    point,
                    point_distance_m: point.distance(origin),
                    series,
                })
            }
            Request::Render {
                id, frame, config, ..
            } => {
                let image = self.render(&frame, &config)?;
                let size = (frame.scene.output.width_px, frame.scene.output.height_px);
                let bytes = self.renderer(&config, size)?.2.shadow_bytes().0;
                Ok(Reply::Render { id, image, bytes })
            }
            Request::Screenshot {
                frame,
                config,
                path,
            } => {
                let image = self.render(&frame, &config)?;
                crate::output::write_png_rgb(&path, &image)?;
                Ok(Reply::Screenshot { path })
            }
        }
    }
}
