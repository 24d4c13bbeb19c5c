//! `smokeshadow render`: one frame of a scene with a technique, written to PNG; with `--bench N`
//! also N timed frames after a warm-up, reporting GPU pass times from timestamp queries.

use crate::Wait;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;

use super::{ParticlesArg, Size, TechniqueArgs};
use smokeshadow_core::gpu::{AdapterPreference, Gpu};
use smokeshadow_core::render::{
    OUTPUT_FORMAT, OffscreenTarget, ParticleRes, RenderOptions, Renderer, SortOrder,
    reference_check,
};
use smokeshadow_core::scene::Scene;

#[derive(Clone, Debug, clap::Args)]
pub struct RenderArgs {
    /// Scene file (TOML), or the name of an embedded scene (`smokeshadow info` lists them); the
    /// embedded thesis scene when omitted.
    pub scene: Option<PathBuf>,
    #[command(flatten)]
    pub particles: ParticlesArg,
    #[command(flatten)]
    pub technique: TechniqueArgs,
    /// Output size as WIDTHxHEIGHT (default: the scene's output size).
    #[arg(long)]
    pub size: Option<Size>,
    /// Draw flat billboards with a hard depth test instead of spherical billboards.
    #[arg(long)]
    pub no_spherical: bool,
    /// The light's kind (default: the scene's `light.kind`): `point` lights every direction
    /// from the light's position, every technique building its maps on six cube faces.
    #[arg(long, value_enum)]
    pub light: Option<smokeshadow_core::scene::LightKind>,
    /// Resolution of the particle pass: 1, 1/2 or 1/4 of the frame's per axis, composited over
    /// it with a depth-aware upsample (`has` draws its own particle pass: 1 only).
    #[arg(long, value_name = "RES", default_value = "1", value_parser = smokeshadow_core::render::parse_particle_res)]
    pub particle_res: ParticleRes,
    /// The order of the frame's one sort: `view` (back to front by view depth) or
    /// `half-angle` (along the half-angle between view and light, the order `has` draws in, so
    /// that it needs no sort of its own; the eye's order is then approximate).
    #[arg(long, value_enum, default_value_t = SortOrder::View)]
    pub sort: SortOrder,
    /// Output PNG.
    #[arg(long, short = 'o', default_value = "smoke.png")]
    pub output: PathBuf,
    /// Also write the linear HDR frame (premultiplied radiance, the smoke's opacity in alpha)
    /// as OpenEXR beside the PNG (same name, `.exr`), for tev, Nuke or any HDR viewer.
    #[arg(long)]
    pub exr: bool,
    /// Render this many timed frames after the warm-up and print per-pass times.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub bench: Option<u32>,
    /// Warm-up frames before timing (the first frames compile shaders).
    #[arg(long, default_value_t = 5)]
    pub warmup: u32,
    /// With `--bench`: write the timed frames' GPU passes as a Chrome trace event file (JSON)
    /// that Perfetto (ui.perfetto.dev) or chrome://tracing opens.
    #[arg(long, requires = "bench")]
    pub trace: Option<PathBuf>,
}

pub fn run(args: &RenderArgs, adapter: &AdapterPreference) -> anyhow::Result<()> {
    let mut scene = super::load_scene(args.scene.as_deref(), args.particles)?;
    if let Some(size) = args.size {
        scene.output.width_px = size.width;
        scene.output.height_px = size.height;
    }
    if let Some(kind) = args.light {
        scene.light.kind = kind;
    }
    let technique = args.technique.config(&scene)?;
    if args.output.is_dir() {
        anyhow::bail!(
            "output {} is a folder; give a .png file path",
            args.output.display()
        );
    }
    if args.exr
        && args
            .output
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
    {
        anyhow::bail!(
            "output {} would be overwritten by --exr (it writes the HDR frame beside the PNG, as .exr); give a .png path",
            args.output.display()
        );
    }
    if let Some(trace) = &args.trace
        && trace.is_dir()
    {
        anyhow::bail!(
            "trace {} is a folder; give a .json file path",
            trace.display()
        );
    }
    let gpu = Gpu::new(adapter).wait()?;
    log::info!("adapter: {}", gpu.describe());
    if args.trace.is_some() && !gpu.has_timestamps() {
        anyhow::bail!(
            "--trace needs GPU timestamp queries, which {} does not have",
            gpu.info.name
        );
    }

    let sim_start = Instant::now();
    let particles = crate::particles::scene_particles(&scene)?;
    let sim_ms = sim_start.elapsed().as_secs_f64() * 1e3;

    let options = RenderOptions {
        spherical: !args.no_spherical,
        particle_res: args.particle_res,
        sort: args.sort,
        ..RenderOptions::default()
    };
    let (w, h) = (scene.output.width_px, scene.output.height_px);
    let mut renderer = Renderer::new(&gpu, w, h, OUTPUT_FORMAT, &technique).wait()?;
    let target = OffscreenTarget::new(&gpu, w, h);

    if let Some(frames) = args.bench {
        let timed = bench(
            &gpu,
            &mut renderer,
            &scene,
            &particles,
            &options,
            &target,
            args.warmup,
            frames,
        )?;
        if let Some(path) = &args.trace {
            let t = renderer.technique();
            let title = format!(
                "smokeshadow {} / {} channels, {} ({} particles, {w}x{h})",
                t.name(),
                t.channels_used(),
                scene.name,
                particles.len()
            );
            let trace = smokeshadow_core::gpu::trace::chrome_trace(&timed, &title);
            crate::output::write_atomic(path, serde_json::to_string(&trace)?.as_bytes())?;
            println!(
                "wrote {} ({} frames' GPU passes, Chrome trace events)",
                path.display(),
                timed.len()
            );
        }
    }
    renderer
        .render(&gpu, &scene, &particles, &options, &target.view)
        .wait()?;
    let image = smokeshadow_core::gpu::read_texture_rgba8(&gpu, &target.texture).wait()?;
    // The reference checks itself before its image is written (nothing is left on a failure).
    let check =
        reference_check::verify_if_reference(&mut renderer, &gpu, &scene, &particles).wait()?;
    crate::output::write_png(&args.output, &image)?;
    if args.exr {
        let path = crate::output::exr_beside(&args.output);
        let hdr =
            smokeshadow_core::gpu::read_texture_rgba16f(&gpu, renderer.hdr_texture()).wait()?;
        crate::output::write_exr(&path, &hdr)?;
        println!(
            "wrote {} (linear HDR, premultiplied, smoke opacity in alpha)",
            path.display()
        );
    }
    let t = renderer.technique();
    println!(
        "wrote {} ({w}x{h}, {} particles {} in {sim_ms:.0} ms, technique {} with {} channels, {} bytes of shadow memory{} + {}, {} billboards{})",
        args.output.display(),
        particles.len(),
        match &scene.particles {
            Some(source) => format!(
                "read from {}",
                source.path_at(scene.sim.duration_s).display()
            ),
            None => format!("simulated to t = {} s", scene.sim.duration_s),
        },
        t.name(),
        t.channels_used(),
        renderer.shadow_bytes().0,
        transient_note(&renderer),
        match renderer.occluder_map_px() {
            Some(side) => format!(
                "{} of the occluders' {side}² depth map",
                renderer.occluder_bytes()
            ),
            None => format!(
                "{} of the occluders' boxes, tested exactly (no depth map)",
                renderer.occluder_bytes()
            ),
        },
        if options.spherical {
            "spherical"
        } else {
            "flat"
        },
        match options.particle_res {
            ParticleRes::Full => String::new(),
            res => format!(" at {res} resolution"),
        },
    );
    if let (Some(grid), Some(spec)) = (renderer.medium().grid(), renderer.medium().spec()) {
        let voxels = format!("{}x{}x{} voxels", grid.dims.x, grid.dims.y, grid.dims.z);
        // A shape is sampled in closed form: its grid only bounds the marches.
        let extent = match grid.analytic {
            Some(_) => format!("in closed form, marched over a box of {voxels}"),
            None => voxels,
        };
        println!(
            "volume: {} ({extent}, {} bytes on the device), {} eye steps, {} build steps",
            spec.summary().trim_start_matches("volume: "),
            renderer.medium().bytes(),
            spec.eye_steps,
            spec.build_steps
        );
    }
    if let Some(check) = check {
        println!("{check}");
    }
    let faces = renderer.face_counters();
    for (counters, face) in faces
        .iter()
        .zip(smokeshadow_core::shadow::light_space::CUBE_FACE_NAMES)
    {
        if !counters.is_empty() {
            let list: Vec<String> = counters.iter().map(|(k, v)| format!("{k} {v}")).collect();
            let face = match faces.len() {
                1 => String::new(),
                _ => format!(", cube face {face}"),
            };
            println!("{} counters{face}: {}", t.name(), list.join(", "));
        }
    }
    Ok(())
}

/// " over the 6 faces of a cube" for a point light's maps, and " (N of them transient)" when
/// part of the bytes is build scratch the lookup never reads.
fn transient_note(renderer: &smokeshadow_core::render::Renderer) -> String {
    let faces = match renderer.light_faces() {
        1 => String::new(),
        n => format!(" over the {n} faces of a cube"),
    };
    match renderer.shadow_bytes().1 {
        0 => faces,
        t => format!("{faces} ({t} of them transient)"),
    }
}

#[allow(clippy::too_many_arguments)]
fn bench(
    gpu: &Gpu,
    renderer: &mut Renderer,
    scene: &Scene,
    particles: &[smokeshadow_core::sim::Particle],
    options: &RenderOptions,
    target: &OffscreenTarget,
    warmup: u32,
    frames: u32,
) -> anyhow::Result<Vec<smokeshadow_core::gpu::PassTimes>> {
    // The last warm-up frame counts the particle pass's fragments (never a timed frame).
    let mut particle_fragments = None;
    for i in 0..warmup {
        let count = i + 1 == warmup && renderer.set_count_fragments(gpu, true);
        renderer
            .render(gpu, scene, particles, options, &target.view)
            .wait()?;
        if count {
            particle_fragments = renderer.particle_fragments(gpu).wait()?;
            renderer.set_count_fragments(gpu, false);
        }
        gpu.wait_idle()?;
    }
    let mut pass_samples: Vec<(&'static str, Vec<f64>)> = Vec::new();
    let mut sort = Vec::new();
    let mut sorts = 0;
    let mut gpu_total = Vec::new();
    let mut frame = Vec::new();
    let mut wall = Vec::new();
    let mut timed = Vec::new();
    for _ in 0..frames {
        let start = Instant::now();
        let stats = renderer
            .render(gpu, scene, particles, options, &target.view)
            .wait()?;
        let times = renderer
            .gpu_times(gpu)
            .wait()
            .context("reading GPU timestamps")?;
        wall.push(start.elapsed().as_secs_f64() * 1e3);
        sort.push(stats.sort_ms);
        sorts = stats.sorts;
        gpu_total.push(times.total_ms());
        frame.push(stats.frame_ms(&times));
        for &(name, ms) in &times.passes {
            match pass_samples.iter_mut().find(|(n, _)| *n == name) {
                Some((_, v)) => v.push(ms),
                None => pass_samples.push((name, vec![ms])),
            }
        }
        timed.push(times);
    }
    let t = renderer.technique();
    println!(
        "bench: {} x {} ({} particles), technique {} / {} channels, {} bytes{}; {frames} frames after {warmup} warm-up",
        scene.output.width_px,
        scene.output.height_px,
        particles.len(),
        t.name(),
        t.channels_used(),
        renderer.shadow_bytes().0,
        transient_note(renderer),
    );
    if !gpu.has_timestamps() {
        println!("  GPU pass times: not available (the adapter has no timestamp queries)");
    }
    println!("  {:<22} {:>9} {:>9} {:>9}", "ms", "median", "min", "max");
    let row = |name: &str, v: &mut Vec<f64>| {
        let s = Summary::of(v);
        println!(
            "  {:<22} {:>9.3} {:>9.3} {:>9.3}",
            name, s.median, s.min, s.max
        );
    };
    for (name, v) in &mut pass_samples {
        row(&format!("gpu {name}"), v);
    }
    if gpu.has_timestamps() {
        row("gpu frame (all passes)", &mut gpu_total);
    }
    row(
        &format!("cpu sort ({} x {})", options.sort, sorts),
        &mut sort,
    );
    // The frame as the sweep counts it (GPU passes + the CPU sort before them) against the
    // clock.
    let (frame_median, wall_median) = (
        Summary::of(&mut frame).median,
        Summary::of(&mut wall).median,
    );
    row("wall frame", &mut wall);
    if gpu.has_timestamps() {
        let what = format!("{} frames", t.name());
        if let Some(warning) = smokeshadow_core::gpu::clock_warning(
            &what,
            frame_median,
            wall_median,
            gpu.clock_floor_ms().wait(),
        ) {
            println!("  {warning}");
        }
    }
    if let Some(n) = particle_fragments {
        println!(
            "  particle fragments     {n} (fragment shader invocations of the particle pass at {} resolution)",
            options.particle_res
        );
    }
    Ok(timed)
}

/// Median, min and max of a sample.
pub struct Summary {
    pub median: f64,
    pub min: f64,
    pub max: f64,
}

impl Summary {
    pub fn of(v: &mut [f64]) -> Self {
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = if n == 0 {
            f64::NAN
        } else if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        };
        Self {
            median,
            min: v.first().copied().unwrap_or(f64::NAN),
            max: v.last().copied().unwrap_or(f64::NAN),
        }
    }
}
