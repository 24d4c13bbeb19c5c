//! smokeshadow in a web page: the core, compiled to WebAssembly, renders on the browser's WebGPU
//! adapter (the user's own GPU) what the command line renders on the host's.
//!
//! The page (`web/static/`) holds one [`Page`]: a device on the browser's adapter with the
//! adapter's own limits (as the native apps ask for them), a scene (the embedded thesis scene,
//! a gallery scene, or files dropped on the page, read through [`Files::memory`]) and the last
//! comparison. [`Page::compare`] renders the scene with a technique and with `exact`, and
//! measures what the command line measures: FLIP and the pixel statistics of the two images
//! (`diff::compare`), the RMS difference of T at the shaded points (`render::shaded`), the
//! technique's resident bytes (scratch included), and its GPU pass times from timestamp
//! queries. `exact` checks itself against the f64 closed form before anything is measured
//! against it. Every failure is one line for the page to show; the page keeps working.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;

use serde::Serialize;
use wasm_bindgen::prelude::*;

use smokeshadow_core::diff;
use smokeshadow_core::files::Files;
use smokeshadow_core::gpu::{Gpu, PassTimes, clock_warning};
use smokeshadow_core::particles;
use smokeshadow_core::render::shaded::{frame_points, rms_difference};
use smokeshadow_core::render::{
    OUTPUT_FORMAT, OffscreenTarget, RenderOptions, Renderer, TechniqueConfig, reference_check,
};
use smokeshadow_core::scene::{EMBEDDED, Scene, TechniqueParams};
use smokeshadow_core::shadow;
use smokeshadow_core::sim::{self, Particle};
use smokeshadow_core::sweep::cell::{Bench, Reference};
use smokeshadow_core::sweep::plan::{self, CellTiming, Grid};
use smokeshadow_core::sweep::{
    CellResult, ImageError, Machine, RunRecord, SceneHeader, SweepResults, answer, charts, table,
};

/// Panics reach the browser's console with their message (a bug, never a user's input: those
/// are one-line errors).
#[wasm_bindgen(start)]
pub fn start() {
    std::panic::set_hook(Box::new(|info| {
        web_sys::console::error_1(&format!("smokeshadow panicked: {info}").into());
    }));
}

/// The page's state: one device, one scene, the last comparison.
#[wasm_bindgen]
pub struct Page {
    state: Rc<RefCell<State>>,
}

struct State {
    gpu: Rc<Gpu>,
    scene: Rc<Loaded>,
    /// `exact`'s frame of the scene, rendered once per scene (and size).
    exact: Option<Rc<Measured>>,
    /// Files dropped on the page, by name, until the next drop.
    dropped: BTreeMap<PathBuf, Vec<u8>>,
    /// The images of the last comparison, RGBA: technique, exact, FLIP map.
    images: BTreeMap<&'static str, Vec<u8>>,
    busy: bool,
    /// Why the device is gone, once it is: nothing more can run on it (wgpu's WebGPU backend
    /// cannot even create a buffer), so every comparison after says so until a reload.
    lost: Option<String>,
}

impl State {
    /// Starts a job on the GPU (a comparison, a sweep): refused in one line while the device is
    /// lost or another job runs.
    fn begin(&mut self) -> Result<(), JsValue> {
        if let Some(lost) = &self.lost {
            return Err(to_js(anyhow::anyhow!(
                "{lost}; reload the page for a new device"
            )));
        }
        if self.busy {
            return Err(to_js(anyhow::anyhow!(
                "a comparison or sweep is already running; wait for it"
            )));
        }
        self.busy = true;
        Ok(())
    }

    /// Ends the job: a GPU error nothing caught (on the host it would end the process) is its
    /// one line, and a lost device is remembered.
    fn end(&mut self, gpu: &Gpu) -> Result<(), JsValue> {
        self.busy = false;
        match gpu.take_uncaptured_error() {
            Some(error) => {
                if error.starts_with(smokeshadow_core::gpu::DEVICE_LOST) {
                    self.lost = Some(error.clone());
                }
                Err(to_js(anyhow::anyhow!(error)))
            }
            None => Ok(()),
        }
    }
}

/// A scene with its particles.
struct Loaded {
    scene: Scene,
    particles: Vec<Particle>,
    /// How the page names it ("the embedded thesis scene", a file's name).
    origin: String,
    /// A dropped sequence's frames (empty for anything else).
    frames: Vec<i64>,
}

/// One technique's frame of a scene and what was measured of it.
struct Measured {
    image: image::RgbImage,
    /// T at the shaded points, as the frame's lighting used it.
    shaded_t: Vec<f32>,
    summary: FrameSummary,
}

#[derive(Clone, Serialize)]
struct FrameSummary {
    technique: String,
    channels_used: u32,
    resolution_px: u32,
    /// Bytes the technique holds at its peak, scratch included, and how many of them are
    /// transient (build scratch the lookup never reads).
    shadow_bytes: u64,
    transient_bytes: u64,
    /// The frame's GPU passes from timestamp queries (`None` without them) and its time as the
    /// command line reports it (passes plus the CPU sort).
    passes: Option<Vec<(String, f64)>>,
    frame_ms: Option<f64>,
    /// Wall time of the timed frame, submission to read-back.
    wall_ms: f64,
    /// Where the timestamps and the clock disagree (`gpu::clock_warning`, as the command line
    /// checks them): what the page shows instead of trusting the GPU time.
    clock_warning: Option<String>,
    /// `exact`'s check against the closed form.
    reference_check: Option<String>,
}

#[derive(Serialize)]
struct ComparisonSummary {
    scene: String,
    width: u32,
    height: u32,
    particles: usize,
    technique: FrameSummary,
    exact: FrameSummary,
    flip_mean: f64,
    flip_q1: f64,
    flip_median: f64,
    flip_q3: f64,
    rmse_srgb: f64,
    /// `None` for identical images (an infinite PSNR).
    psnr_db: Option<f64>,
    /// RMS of T − T_exact over the shaded points.
    rms_transmittance_error: f64,
    shaded_points: usize,
}

/// One line from an error and its causes.
fn line(err: impl std::fmt::Display) -> JsError {
    JsError::new(&err.to_string().replace('\n', " "))
}

fn to_js(err: anyhow::Error) -> JsValue {
    JsValue::from(line(format!("{err:#}")))
}

#[wasm_bindgen]
impl Page {
    /// Asks the browser for its WebGPU adapter and a device with the adapter's limits and the
    /// optional features the tool uses, and loads the embedded thesis scene.
    pub async fn open() -> Result<Page, JsError> {
        let instance = smokeshadow_core::gpu::instance();
        let adapter = instance
            .request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                ..Default::default()
            })
            .await
            .map_err(|e| line(format!("this browser offers no WebGPU adapter ({e})")))?;
        let gpu = Gpu::from_adapter(&adapter).await.map_err(line)?;
        let scene = load(Scene::thesis_plume(), "the embedded thesis scene").map_err(line)?;
        Ok(Page {
            state: Rc::new(RefCell::new(State {
                gpu: Rc::new(gpu),
                scene: Rc::new(scene),
                exact: None,
                dropped: BTreeMap::new(),
                images: BTreeMap::new(),
                busy: false,
                lost: None,
            })),
        })
    }

    /// The adapter, the features the tool looks for and the limits it leans on, as JSON.
    pub fn adapter(&self) -> String {
        let state = self.state.borrow();
        let gpu = &state.gpu;
        let info = &gpu.info;
        let features = [
            ("timestamp-query", wgpu::Features::TIMESTAMP_QUERY),
            ("float32-filterable", wgpu::Features::FLOAT32_FILTERABLE),
            ("float32-blendable", wgpu::Features::FLOAT32_BLENDABLE),
            ("shader-f16", wgpu::Features::SHADER_F16),
            ("subgroups", wgpu::Features::SUBGROUP),
        ]
        .map(|(name, f)| (name, gpu.features.contains(f)));
        let l = &gpu.limits;
        let limits = [
            (
                "maxStorageBuffersPerShaderStage",
                u64::from(l.max_storage_buffers_per_shader_stage),
            ),
            (
                "maxColorAttachmentBytesPerSample",
                u64::from(l.max_color_attachment_bytes_per_sample),
            ),
            ("maxColorAttachments", u64::from(l.max_color_attachments)),
            (
                "maxStorageBufferBindingSize",
                l.max_storage_buffer_binding_size,
            ),
            ("maxBufferSize", l.max_buffer_size),
            (
                "maxTextureDimension2D",
                u64::from(l.max_texture_dimension_2d),
            ),
            (
                "maxTextureDimension3D",
                u64::from(l.max_texture_dimension_3d),
            ),
            (
                "maxComputeInvocationsPerWorkgroup",
                u64::from(l.max_compute_invocations_per_workgroup),
            ),
        ];
        let name = [&info.name, &info.driver, &info.driver_info]
            .into_iter()
            .filter(|s| !s.is_empty())
            .cloned()
            .collect::<Vec<_>>()
            .join(" ");
        serde_json::json!({
            "name": if name.is_empty() { format!("{:?} adapter", info.device_type) } else { name },
            "device_type": format!("{:?}", info.device_type),
            "backend": format!("{:?}", info.backend),
            "features": features.iter().map(|(n, has)| serde_json::json!({"name": n, "present": has})).collect::<Vec<_>>(),
            "limits": limits.iter().map(|(n, v)| serde_json::json!({"name": n, "value": v})).collect::<Vec<_>>(),
        })
        .to_string()
    }

    /// The registry as JSON: each technique's name, description, channel range, whether the
    /// default comparison includes it, and why it cannot shadow the current scene, if so.
    pub fn techniques(&self) -> String {
        let state = self.state.borrow();
        let loaded = &state.scene;
        let volume = loaded.scene.volume.is_some();
        let default_sweep = shadow::default_sweep();
        let list: Vec<_> = shadow::REGISTRY
            .iter()
            .map(|e| {
                serde_json::json!({
                    "name": e.name,
                    "description": e.description,
                    "min_channels": e.min_channels,
                    "max_channels": e.max_channels,
                    "in_default_compare": e.in_default_compare,
                    "in_default_sweep": default_sweep.iter().any(|n| n == e.name),
                    "caption_24": (e.budget_caption)(24.clamp(e.min_channels, e.max_channels)),
                    "refusal": e.refusal(volume, loaded.particles.len()).map(|r| r.to_string()),
                })
            })
            .collect();
        serde_json::Value::Array(list).to_string()
    }

    /// The embedded scenes' names (the gallery, the thesis', the held-out and training ones).
    pub fn scenes() -> Vec<String> {
        EMBEDDED
            .iter()
            .map(|(name, _)| (*name).to_owned())
            .collect()
    }

    /// What the page holds now, one line.
    pub fn scene(&self) -> String {
        describe(&self.state.borrow().scene)
    }

    /// Picks an embedded scene by name.
    pub fn pick_scene(&self, name: &str) -> Result<String, JsError> {
        let scene =
            Scene::embedded(name).ok_or_else(|| line(format!("no embedded scene \"{name}\"")))?;
        self.replace(load(scene, &format!("the embedded scene {name}")).map_err(line)?)
    }

    /// Holds a dropped file's bytes under its name, for [`Page::open_dropped`].
    pub fn add_file(&self, name: &str, bytes: Vec<u8>) {
        self.state
            .borrow_mut()
            .dropped
            .insert(PathBuf::from(name), bytes);
    }

    /// Forgets the dropped files (before the next drop).
    pub fn clear_files(&self) {
        self.state.borrow_mut().dropped.clear();
    }

    /// Opens what was dropped as the command line opens a file: a scene file (`.toml`, which
    /// may name the other dropped files), or else the first particle (PLY, CSV) or volume
    /// (OpenVDB) file by name, framed and lit as `smokeshadow render FILE` frames it. A bad
    /// file is one line; the scene before it stays.
    pub fn open_dropped(&self) -> Result<String, JsError> {
        let dropped = self.state.borrow().dropped.clone();
        let names: Vec<PathBuf> = dropped.keys().cloned().collect();
        let first = names
            .iter()
            .find(|p| p.extension().is_some_and(|e| e == "toml"))
            .or_else(|| names.first())
            .cloned()
            .ok_or_else(|| line("no file was dropped"))?;
        let files = Files::memory(dropped);
        // Numbered particle or volume files without a scene file: the sequence, at its first
        // frame.
        let texts: Vec<String> = names.iter().map(|n| n.display().to_string()).collect();
        if let Some((pattern, frames)) = particles::sequence_of(&texts) {
            let scene = particles::scene_for_sequence(&pattern, &frames, frames[0], &files)
                .map_err(|e| line(format!("{e:#}")))?;
            let loaded = load_sequence(scene, &pattern, &frames, frames[0]).map_err(line)?;
            return self.replace(loaded);
        }
        let scene = particles::open_scene(Some(Path::new(&first)), &files)
            .map_err(|e| line(format!("{e:#}")))?;
        let origin = first.display().to_string();
        self.replace(load(scene, &origin).map_err(line)?)
    }

    /// A dropped sequence's frames, as JSON (`[]` for any other scene).
    pub fn frames(&self) -> String {
        serde_json::to_string(&self.state.borrow().scene.frames).expect("frames serialise")
    }

    /// Shows `frame` of the dropped sequence, framed and lit as its other frames.
    pub fn show_frame(&self, frame: f64) -> Result<String, JsError> {
        let loaded = self.state.borrow().scene.clone();
        let frame = frame as i64;
        if !loaded.frames.contains(&frame) {
            return Err(line(format!(
                "frame {frame} is not one of the dropped sequence's ({:?})",
                loaded.frames
            )));
        }
        let mut scene = loaded.scene.clone();
        particles::show_sequence_frame(&mut scene, frame);
        let pattern = match (&scene.particles, &scene.volume) {
            (Some(p), _) => p.file.clone(),
            (None, Some(v)) => v.file.clone(),
            (None, None) => String::new(),
        };
        self.replace(load_sequence(scene, &pattern, &loaded.frames, frame).map_err(line)?)
    }

    /// Renders the scene at `width` x `height` (0: the scene's size) with `technique` at
    /// `channels` and a `resolution_px` shadow map (0: the scene's), and with `exact`; resolves
    /// to the comparison as JSON ([`Page::image`] then holds the three images).
    pub fn compare(
        &self,
        technique: String,
        channels: u32,
        resolution_px: u32,
        width: u32,
        height: u32,
    ) -> js_sys::Promise {
        let state = self.state.clone();
        wasm_bindgen_futures::future_to_promise(async move {
            let (gpu, loaded, cached) = {
                let mut s = state.borrow_mut();
                s.begin()?;
                (s.gpu.clone(), s.scene.clone(), s.exact.clone())
            };
            let result = compare(
                &gpu,
                &loaded,
                cached,
                &technique,
                channels,
                resolution_px,
                (width, height),
            )
            .await;
            let mut s = state.borrow_mut();
            s.end(&gpu)?;
            let (summary, exact, images) = result.map_err(to_js)?;
            if Rc::ptr_eq(&s.scene, &loaded) {
                s.exact = Some(exact);
            }
            s.images = images;
            Ok(JsValue::from(
                serde_json::to_string(&summary).expect("the summary serialises"),
            ))
        })
    }

    /// Sweeps the scene as the command line's `sweep` plans and measures it: `none`, then at
    /// each map resolution each of the request's techniques at each channel count, byte budget
    /// per shadow-map texel and memory budget in all, each cell after `exact` (the request is
    /// JSON: `techniques`, `channels`, `bytes_per_texel`, `memory` (sizes such as "12MiB"),
    /// `resolutions`, `width`, `height`, `frames` and `adapter`). `progress(done, total, label)`
    /// is called before each cell. Resolves to JSON: `results.json`'s and `results.csv`'s text,
    /// the answer at each byte, memory and frame-time budget, and the charts' SVG.
    pub fn sweep(&self, request: &str, progress: js_sys::Function) -> js_sys::Promise {
        let state = self.state.clone();
        let request: Result<SweepRequest, _> = serde_json::from_str(request);
        wasm_bindgen_futures::future_to_promise(async move {
            let SweepRequest {
                techniques,
                channels,
                bytes_per_texel,
                memory,
                resolutions,
                width,
                height,
                frames,
                adapter,
            } = request.map_err(|e| to_js(anyhow::anyhow!("the sweep's request: {e}")))?;
            // (before the job starts: a bad size leaves nothing running)
            let memory = memory
                .iter()
                .map(|m| plan::parse_memory(m).map_err(|e| anyhow::anyhow!("memory budget {e}")))
                .collect::<anyhow::Result<Vec<u64>>>()
                .map_err(to_js)?;
            let (gpu, loaded) = {
                let mut s = state.borrow_mut();
                s.begin()?;
                (s.gpu.clone(), s.scene.clone())
            };
            let report = |done: usize, total: usize, label: &str| {
                let _ = progress.call3(
                    &JsValue::NULL,
                    &JsValue::from(done as u32),
                    &JsValue::from(total as u32),
                    &JsValue::from(label),
                );
            };
            // 0, or none given: the scene's map resolution.
            let mut shadow_res: Vec<u32> = Vec::new();
            for r in resolutions {
                let r = match r {
                    0 => loaded.scene.shadow.resolution_px,
                    r => r,
                };
                if !shadow_res.contains(&r) {
                    shadow_res.push(r);
                }
            }
            if shadow_res.is_empty() {
                shadow_res.push(loaded.scene.shadow.resolution_px);
            }
            let grid = Grid {
                techniques,
                channels,
                bytes_per_texel,
                memory,
                shadow_res,
                splats: vec![shadow::SplatMode::Segment],
                particle_res: vec![smokeshadow_core::render::ParticleRes::Full],
            };
            let timing = CellTiming {
                frames,
                warmup: 1,
                cell_seconds: 0.5,
                animate: None,
            };
            let size = (width, height);
            let result = sweep(&gpu, &loaded, &grid, &timing, size, &adapter, &report).await;
            let mut s = state.borrow_mut();
            s.end(&gpu)?;
            let out = result.map_err(to_js)?;
            Ok(JsValue::from(out.to_string()))
        })
    }

    /// One of the last comparison's images as RGBA bytes: "technique", "exact" or "flip" (the
    /// FLIP map through FLIP's magma colour map). Empty before a comparison.
    pub fn image(&self, which: &str) -> Vec<u8> {
        self.state
            .borrow()
            .images
            .get(which)
            .cloned()
            .unwrap_or_default()
    }
}

impl Page {
    fn replace(&self, loaded: Loaded) -> Result<String, JsError> {
        let mut s = self.state.borrow_mut();
        if s.busy {
            return Err(line(
                "a comparison or sweep is running; pick the scene when it is done",
            ));
        }
        let description = describe(&loaded);
        s.scene = Rc::new(loaded);
        s.exact = None;
        s.images.clear();
        Ok(description)
    }
}

fn load(scene: Scene, origin: &str) -> anyhow::Result<Loaded> {
    let particles = particles::frame_particles(&scene, sim::simulate)?;
    Ok(Loaded {
        scene,
        particles,
        origin: origin.to_owned(),
        frames: Vec::new(),
    })
}

/// A dropped sequence's scene at `frame` of `frames`, named by its pattern.
fn load_sequence(
    scene: Scene,
    pattern: &str,
    frames: &[i64],
    frame: i64,
) -> anyhow::Result<Loaded> {
    let (first, last) = (frames[0], frames[frames.len() - 1]);
    let origin = format!(
        "{pattern}, frame {frame} of the {} dropped, {first}..{last}",
        frames.len()
    );
    Ok(Loaded {
        frames: frames.to_vec(),
        ..load(scene, &origin)?
    })
}

fn describe(loaded: &Loaded) -> String {
    let scene = &loaded.scene;
    let holds = match (&scene.volume, loaded.particles.len()) {
        (Some(_), 0) => "a density volume".to_owned(),
        (Some(_), n) => format!("{n} particles and a density volume"),
        (None, n) => format!("{n} particles"),
    };
    format!(
        "{} ({}): {holds}, {}x{} px",
        scene.name, loaded.origin, scene.output.width_px, scene.output.height_px
    )
}

type Images = BTreeMap<&'static str, Vec<u8>>;

async fn compare(
    gpu: &Gpu,
    loaded: &Loaded,
    cached_exact: Option<Rc<Measured>>,
    technique: &str,
    channels: u32,
    resolution_px: u32,
    size: (u32, u32),
) -> anyhow::Result<(ComparisonSummary, Rc<Measured>, Images)> {
    let mut scene = loaded.scene.clone();
    if size.0 > 0 && size.1 > 0 {
        scene.output.width_px = size.0;
        scene.output.height_px = size.1;
    }
    let (w, h) = (scene.output.width_px, scene.output.height_px);
    let config = technique_config(&scene, technique, channels, resolution_px)?;
    if let Some(refusal) =
        shadow::find(technique)?.refusal(scene.volume.is_some(), loaded.particles.len())
    {
        anyhow::bail!(refusal);
    }
    let reference = shadow::reference().name;
    let exact = match cached_exact {
        Some(e) if e.image.dimensions() == (w, h) => e,
        _ => {
            let config = technique_config(&scene, reference, 24, 0)?;
            Rc::new(measure(gpu, &scene, &loaded.particles, &config).await?)
        }
    };
    let measured = measure(gpu, &scene, &loaded.particles, &config).await?;
    let comparison = diff::compare(&exact.image, &measured.image)?;
    let heat = diff::flip_heatmap(&comparison);
    let m = &comparison.metrics;
    let rgba = |img: &image::RgbImage| image::DynamicImage::ImageRgb8(img.clone()).into_rgba8();
    let images: Images = [
        ("technique", rgba(&measured.image).into_raw()),
        ("exact", rgba(&exact.image).into_raw()),
        ("flip", rgba(&heat).into_raw()),
    ]
    .into_iter()
    .collect();
    let summary = ComparisonSummary {
        scene: describe(loaded),
        width: w,
        height: h,
        particles: loaded.particles.len(),
        technique: measured.summary.clone(),
        exact: exact.summary.clone(),
        flip_mean: m.flip_mean,
        flip_q1: m.flip_q1,
        flip_median: m.flip_weighted_median,
        flip_q3: m.flip_q3,
        rmse_srgb: m.rmse_srgb,
        psnr_db: m.psnr_srgb_db.is_finite().then_some(m.psnr_srgb_db),
        rms_transmittance_error: rms_difference(&measured.shaded_t, &exact.shaded_t),
        shaded_points: exact.shaded_t.len(),
    };
    Ok((summary, exact, images))
}

/// The command line's configuration of `name` for `scene` (`TechniqueArgs::config`): the
/// scene's shadow settings at `channels`, at `resolution_px` when not 0.
fn technique_config(
    scene: &Scene,
    name: &str,
    channels: u32,
    resolution_px: u32,
) -> anyhow::Result<TechniqueConfig> {
    let entry = shadow::find(name)?;
    let channels = match entry.uses_budget {
        true => channels,
        false => channels.clamp(entry.min_channels, entry.max_channels),
    };
    shadow::check_channels(entry, channels)?;
    let params = TechniqueParams {
        resolution_px: match resolution_px {
            0 => scene.shadow.resolution_px,
            r => r,
        },
        ..scene.shadow.params(channels)
    };
    Ok(TechniqueConfig {
        name: entry.name.to_owned(),
        params,
    })
}

/// Renders one frame after one untimed (the pipelines compiled, the maps sized), reads it
/// back, and measures it as the sweep does.
async fn measure(
    gpu: &Gpu,
    scene: &Scene,
    particles: &[Particle],
    config: &TechniqueConfig,
) -> anyhow::Result<Measured> {
    let (w, h) = (scene.output.width_px, scene.output.height_px);
    let options = RenderOptions::default();
    let mut renderer = Renderer::new(gpu, w, h, OUTPUT_FORMAT, config).await?;
    let target = OffscreenTarget::new(gpu, w, h);
    renderer
        .render(gpu, scene, particles, &options, &target.view)
        .await?;
    renderer.gpu_times(gpu).await?;
    let start = web_time::Instant::now();
    let stats = renderer
        .render(gpu, scene, particles, &options, &target.view)
        .await?;
    let times: PassTimes = renderer.gpu_times(gpu).await?;
    let wall_ms = start.elapsed().as_secs_f64() * 1e3;
    let image = target.read_rgb(gpu).await?;
    let (points, owners) = frame_points(&renderer, scene, particles);
    let shaded_t = renderer
        .probe_shaded(gpu, scene, particles, &points, &owners)
        .await?;
    let reference_check = match config.name == shadow::reference().name {
        true => Some(
            reference_check::verify(&mut renderer, gpu, scene, particles)
                .await?
                .to_string(),
        ),
        false => None,
    };
    let (shadow_bytes, transient_bytes) = renderer.shadow_bytes();
    let timed = gpu.has_timestamps() && !times.passes.is_empty();
    let frame_ms = stats.frame_ms(&times);
    let clock_warning = match timed {
        true => clock_warning(&config.name, frame_ms, wall_ms, gpu.clock_floor_ms().await),
        false => None,
    };
    let t = renderer.technique();
    Ok(Measured {
        image,
        shaded_t,
        summary: FrameSummary {
            technique: t.name().to_owned(),
            channels_used: t.channels_used(),
            resolution_px: config.params.resolution_px,
            shadow_bytes,
            transient_bytes,
            passes: timed.then(|| {
                times
                    .passes
                    .iter()
                    .map(|(n, ms)| ((*n).to_owned(), *ms))
                    .collect()
            }),
            frame_ms: timed.then_some(frame_ms),
            wall_ms,
            clock_warning,
            reference_check,
        },
    })
}

/// What [`Page::sweep`] is asked to sweep.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct SweepRequest {
    techniques: Vec<String>,
    channels: Vec<u32>,
    /// Byte budgets per shadow-map texel (may be empty).
    bytes_per_texel: Vec<u32>,
    /// Memory budgets in all, as the command line's `--memory` writes them ("12MiB"; may be
    /// empty).
    #[serde(default)]
    memory: Vec<String>,
    /// The map resolutions (0, or none: the scene's) and the frame's size (0 x 0: the scene's).
    resolutions: Vec<u32>,
    width: u32,
    height: u32,
    /// Timed frames a cell, at most (the command line's `--frames`).
    frames: u32,
    /// The adapter's name as the browser gives it.
    #[serde(default)]
    adapter: String,
}

/// A `results.json`-sized view of a sweep for the page: the results, the CSV, the answer at each
/// byte, memory and frame-time budget (ranked as the CLI ranks them) and the charts' SVG.
async fn sweep(
    gpu: &Gpu,
    loaded: &Loaded,
    grid: &Grid,
    timing: &CellTiming,
    size: (u32, u32),
    adapter: &str,
    progress: &dyn Fn(usize, usize, &str),
) -> anyhow::Result<serde_json::Value> {
    // RFC 3339 to the second, as the command line writes it ("2026-12-07T23:30:58Z").
    let started = js_sys::Date::new_0()
        .to_iso_string()
        .as_string()
        .map(|iso| format!("{}Z", iso.split('.').next().unwrap_or(&iso)))
        .unwrap_or_default();
    let clock = web_time::Instant::now();
    timing.check()?;
    let mut scene = loaded.scene.clone();
    if size.0 > 0 && size.1 > 0 {
        scene.output.width_px = size.0;
        scene.output.height_px = size.1;
    }
    let (plans, skipped) = plan::plan(&scene, grid)?;
    let total = plans.len() + 1;
    let particles = &loaded.particles;
    progress(0, total, "exact");
    // `exact`, its T at the shaded points and its check against the closed form, as the
    // command line's sweep starts a scene.
    let mut reference =
        Reference::render(gpu, &scene, particles, grid.shadow_res[0], grid.splats[0]).await?;
    let check = reference_check::verify(&mut reference.renderer, gpu, &scene, particles).await?;
    // wgpu leaves a browser adapter's name empty: the page's, from the browser, stands in.
    let mut machine = Machine::of(gpu).await;
    if machine.adapter.is_empty() {
        machine.adapter = adapter.to_owned();
    }
    let mut against = reference.measured_against(&check, machine);
    let Reference {
        mut renderer,
        target,
        image: exact_image,
        points,
        owners,
        t: exact_t,
        bytes: exact_bytes,
        tiles: exact_tiles,
    } = reference;
    let bench = Bench {
        gpu,
        scene: &scene,
        particles,
        target: &target,
        points: &points,
        owners: &owners,
        exact_t: &exact_t,
    };
    let scene_sha256 = scene.content_hash();
    // The technique's own 24-channel images, by cell name, as the command line keeps them.
    let mut own_images: BTreeMap<String, image::RgbImage> = BTreeMap::new();
    // FLIP and RMSE only, as the command line's sweep compares (no SSIM).
    let error =
        |reference: &image::RgbImage, test: &image::RgbImage| -> anyhow::Result<ImageError> {
            Ok(ImageError::of(
                &diff::compare_with(reference, test, diff::Ssim::Skip)?.metrics,
            ))
        };
    let mut cells: Vec<CellResult> = Vec::with_capacity(plans.len());
    for (i, p) in plans.iter().enumerate() {
        progress(i + 1, total, &p.name);
        let key = plan::settings_key(&scene, &scene_sha256, timing, p);
        let prepared = bench.prepare(&mut renderer, p, timing.warmup).await?;
        let (mut cell, image) = bench
            .time(&mut renderer, p, prepared, timing, key, &mut against)
            .await?;
        if p.config.name != shadow::frame_baseline().name {
            cell.vs_exact = Some(error(&exact_image, &image)?);
            cell.vs_full_res = Some(ImageError::NONE);
            // The 24-channel cell is its own baseline; the others are compared with it, kept
            // from its cell or rendered now.
            cell.vs_own_24 = Some(match p.config.params.channels == plan::BASELINE_CHANNELS {
                true => {
                    own_images.insert(p.name.clone(), image.clone());
                    ImageError::NONE
                }
                false => {
                    let baseline = p.own_baseline(&scene);
                    if !own_images.contains_key(&baseline.name) {
                        let own = bench.render_image(&mut renderer, &baseline).await?;
                        own_images.insert(baseline.name.clone(), own);
                    }
                    error(&own_images[&baseline.name], &image)?
                }
            });
        }
        cells.push(cell);
    }
    progress(total, total, "done");
    let header = SceneHeader::of(
        &scene,
        particles.len() as u32,
        scene_sha256,
        smokeshadow_core::sweep::shipped_shapes(),
    );
    let run = RunRecord {
        tool_version: env!("CARGO_PKG_VERSION"),
        frames: timing.frames,
        warmup: timing.warmup,
        fallback: Some(&against.machine),
        exact: Some((exact_bytes, exact_tiles)),
        started,
        wall_s: clock.elapsed().as_secs_f64(),
        shards: Vec::new(),
        exact_image: "images/exact.png".to_owned(),
        exact_hdr_image: None,
    };
    let results = SweepResults::assemble(&header, run, &cells, skipped);
    let csv = String::from_utf8(table::results_csv(&results)?)?;
    let json = table::results_json(&results)?;
    let row = |c: &CellResult| {
        serde_json::json!({
            "technique": c.technique,
            "channels": c.channels,
            "channels_used": c.channels_used,
            "shadow_res": c.shadow_res,
            "flip_vs_exact": answer::flip_exact(c),
            "rms_transmittance_error": c.rms_transmittance_error,
            "resident_bytes": c.resident_bytes,
            "frame_ms": c.frame_ms.median,
            "overhead_ratio": c.overhead_ratio,
        })
    };
    let answers: Vec<serde_json::Value> = answer::byte_budgets(&results)
        .into_iter()
        .map(|b| {
            let ranked: Vec<_> = answer::at_byte_budget(&results, b)
                .into_iter()
                .map(row)
                .collect();
            serde_json::json!({"bytes_per_texel": b, "ranked": ranked})
        })
        .collect();
    // At equal memory in all, each technique at the map resolution `tune` chose for it on the
    // training scenes where that was swept (`shape_tuned`), as the command line answers.
    let memory_answers: Vec<serde_json::Value> = answer::memory_budgets(&results)
        .into_iter()
        .map(|total| {
            let ranked: Vec<_> = answer::at_memory_budget(&results, total)
                .into_iter()
                .map(|c| {
                    let mut r = row(c);
                    r["shape_tuned"] = answer::shape_tuned(&results, total, c).into();
                    r
                })
                .collect();
            serde_json::json!({"bytes": total, "ranked": ranked})
        })
        .collect();
    let time_answers: Vec<serde_json::Value> = answer::TIME_BUDGETS
        .iter()
        .map(|&ratio| {
            let ranked: Vec<_> = answer::at_time_budget(&results, ratio)
                .into_iter()
                .map(row)
                .collect();
            serde_json::json!({"ratio": ratio, "ranked": ranked})
        })
        .collect();
    let charts: Vec<serde_json::Value> = charts::draw_charts(&results)?
        .into_iter()
        .map(|(chart, svg)| {
            serde_json::json!({"title": chart.title, "caption": chart.caption, "svg": svg})
        })
        .collect();
    // Each cell not measured and why, one line each.
    let skipped: Vec<String> = results
        .skipped
        .iter()
        .map(|s| format!("{} at {}: {}", s.technique, s.budget(), s.reason))
        .collect();
    Ok(serde_json::json!({
        "csv": csv,
        "json": json,
        "cells": results.cells.len(),
        "skipped": skipped,
        "answers": answers,
        "memory_answers": memory_answers,
        "time_answers": time_answers,
        "charts": charts,
        "adapter": results.metadata.adapter,
        "wall_s": results.metadata.wall_s,
        "exact_check": check.to_string(),
    }))
}
