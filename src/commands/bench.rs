//! `smokeshadow bench`: the cost of each term of a frame (simulation, sort, every GPU pass, each
//! technique's frame, its bytes and counters) against the particle count, on the scaling family
//! ([`crate::bench`]); a table, and CSV, JSON and log-log SVG charts in a folder.

use crate::Wait;
use std::path::{Path, PathBuf};

use super::{ParticlesArg, Size};
use crate::bench::{self, BenchOptions, BenchResults};
use smokeshadow_core::gpu::{AdapterPreference, Gpu};

#[derive(Clone, Debug, clap::Args)]
pub struct BenchArgs {
    /// Scene file (TOML), or the name of an embedded scene; `plume_scaled` when omitted. Each
    /// count rescales its emitter (see `--particles`).
    pub scene: Option<PathBuf>,
    /// Particle counts, comma-separated [default: 2500,16384,65536,262144,1000000].
    #[arg(long, value_delimiter = ',', value_name = "N,N,...", value_parser = super::parse_particles,
          conflicts_with = "particles")]
    pub particles_list: Vec<u32>,
    // `--particles N`: the same as a one-count `--particles-list`.
    #[command(flatten)]
    pub particles: ParticlesArg,
    /// Technique (repeatable or comma-separated; `all`: every contender; default: every
    /// technique that shadows particles).
    #[arg(long = "technique", short = 't', value_delimiter = ',')]
    pub techniques: Vec<String>,
    /// Channel budget every technique gets, 1..=32 (a technique whose minimum is above it is
    /// recorded as refused).
    #[arg(long, short = 'c', default_value_t = 24)]
    pub channels: u32,
    /// Timed frames per technique and count (medians over these).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub frames: u32,
    /// Untimed warm-up frames before them (the first frames compile shaders and grow buffers).
    #[arg(long, default_value_t = 3)]
    pub warmup: u32,
    /// Frame size as WIDTHxHEIGHT [default: 512x384, small enough for lavapipe at a million
    /// particles].
    #[arg(long)]
    pub size: Option<Size>,
    /// Output folder (created if missing).
    #[arg(long, short = 'o', default_value = "bench")]
    pub output: PathBuf,
    /// Resolution of the particle pass: 1, 1/2 or 1/4 of the frame's per axis (`has`, which
    /// draws its own, is refused below 1).
    #[arg(long, value_name = "RES", default_value = "1", value_parser = smokeshadow_core::render::parse_particle_res)]
    pub particle_res: smokeshadow_core::render::ParticleRes,
    /// Orders of the frame's one sort, comma-separated: `view` (by view depth) and/or
    /// `half-angle` (the order `has` draws in, shared with it); each technique is measured
    /// with each, and a half-angle frame is also compared with the view-sorted one (FLIP).
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        value_name = "ORDER,...",
        default_value = "view"
    )]
    pub sort: Vec<smokeshadow_core::render::SortOrder>,
    /// Bench a density volume instead of particles: `cloud` (the procedural cloud, baked at
    /// each `--grid-sizes`) or an OpenVDB file (its `density` grid): the cloud's noise and
    /// bake, the light march and the eye's march per grid and light step count, as wall times
    /// (`bench_volume.csv`).
    /// With `-t/--technique` (e.g. `-t esm,bsm,fom,srm`): whole frames of the volume's scene
    /// per technique (the cloud at each `--coverages`), timed by GPU timestamps, with each
    /// technique's time over `srm`'s and the coverage from which `srm` is the slower
    /// (`bench_volume_frames.csv`), instead of the stages.
    #[arg(long, value_name = "cloud|FILE.vdb",
          conflicts_with_all = ["scene", "particles_list", "particle_res", "sort"])]
    pub volume: Option<String>,
    /// The cloud's grid edge lengths for `--volume cloud` (a layer of N x N/4 x N voxels).
    #[arg(long, value_delimiter = ',', value_name = "N,...", default_value = "64,128,256",
          value_parser = clap::value_parser!(u32).range(4..=512))]
    pub grid_sizes: Vec<u32>,
    /// With `--volume` and `-t`: the maps' resolutions (default: the scene's).
    #[arg(long, value_delimiter = ',', value_name = "N,...",
          value_parser = clap::value_parser!(u32).range(16..=4096), requires = "volume")]
    pub shadow_res: Vec<u32>,
    /// With `--volume` and `-t`: the build's steps along each texel's light ray (default: the
    /// scene's `volume.build_steps`).
    #[arg(long, value_delimiter = ',', value_name = "N,...",
          value_parser = clap::value_parser!(u32).range(1..=4096), requires = "volume")]
    pub build_steps: Vec<u32>,
    /// The cloud's coverages for `--volume cloud`, 0..1 (the dissertation's coverage axis).
    #[arg(long, value_delimiter = ',', value_name = "C,...", default_value = "0.6",
          value_parser = coverage_fraction)]
    pub coverages: Vec<f32>,
    /// Steps towards the light for `--volume` (the light march's, and per eye sample; default
    /// 16,64,256). With `-t`: `srm`'s light samples per lookup, each a row of its own (default
    /// its `srm_light_steps`; the dissertation varied 1-50), the ratios to `srm` taken to the
    /// first.
    #[arg(long, value_delimiter = ',', value_name = "N,...",
          value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub light_steps: Vec<u32>,
    /// The eye march's steps for `--volume`.
    #[arg(long, default_value_t = 128, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub eye_steps: u32,
}

/// The embedded scene a bench runs when none is given.
pub const DEFAULT_SCENE: &str = "plume_scaled";

pub fn run(args: &BenchArgs, adapter: &AdapterPreference) -> anyhow::Result<()> {
    if let Some(source) = &args.volume {
        return run_volume(args, source, adapter);
    }
    let scene_arg = args.scene.as_deref().unwrap_or(Path::new(DEFAULT_SCENE));
    let mut scene = super::load_scene(Some(scene_arg), ParticlesArg::default())?;
    let (w, h) = args
        .size
        .map_or(bench::DEFAULT_SIZE_PX, |s| (s.width, s.height));
    scene.output.width_px = w;
    scene.output.height_px = h;
    let counts = match (args.particles.particles, args.particles_list.is_empty()) {
        (Some(n), _) => vec![n],
        (None, true) => bench::DEFAULT_COUNTS.to_vec(),
        (None, false) => args.particles_list.clone(),
    };
    let techniques = if args.techniques.is_empty() {
        smokeshadow_core::shadow::particle_techniques()
            .map(|e| e.name.to_owned())
            .collect()
    } else {
        smokeshadow_core::shadow::expand_all(&args.techniques)
    };
    let options = BenchOptions {
        counts,
        techniques,
        channels: args.channels,
        frames: args.frames,
        warmup: args.warmup,
        particle_res: args.particle_res,
        sorts: args.sort.clone(),
    };
    let gpu = Gpu::new(adapter).wait()?;
    let results = bench::run(&gpu, &scene, &options)?;
    let written = bench::write(&results, &args.output)?;
    print_table(&results);
    print_bound_table(&results);
    println!(
        "wrote {} files to {} ({}, {})",
        written.len(),
        args.output.display(),
        bench::CSV_FILE,
        bench::JSON_FILE
    );
    Ok(())
}

/// The results as a table: one row per count and technique.
fn print_table(results: &BenchResults) {
    println!(
        "bench: {} at {}x{} (particles at {}), {} channels, shadow map {}², {} frames after {} warm-up, {} CPU threads, {}",
        results.scene,
        results.width_px,
        results.height_px,
        results.particle_res,
        results.channels,
        results.shadow_res,
        results.frames,
        results.warmup,
        results.cpu_threads,
        results.adapter
    );
    if !results.gpu_timestamps {
        println!("  GPU pass times: not available (the adapter has no timestamp queries)");
    }
    println!(
        "  medians in ms; frame = GPU passes + CPU sort; upload = the frame's CPU work after the \
         sort (gather, upload, recording, a build's CPU preparation) while the GPU waits; wall = \
         the clock, {:.3} ms of it a submission's round trip",
        results.clock_floor_ms
    );
    let passes = results.pass_names();
    let width = label_width(results);
    let mut header = format!(
        "{:>9} {:<w$} {:>10} {:>8}",
        "particles",
        "technique",
        "sim",
        "sort",
        w = width
    );
    for p in &passes {
        header.push_str(&format!(" {:>10}", truncate(p, 10)));
    }
    header.push_str(&format!(
        " {:>10} {:>10} {:>10} {:>12}  counters",
        "gpu total", "frame", "wall", "bytes"
    ));
    println!("{header}");
    for count in &results.counts {
        for cell in &count.cells {
            let mut row = format!(
                "{:>9} {:<w$} {:>10.1}",
                count.particles,
                cell.label(),
                count.sim_ms,
                w = width
            );
            match &cell.measured {
                Some(m) => {
                    row.push_str(&format!(" {:>8.3}", m.sort_ms.median));
                    for p in &passes {
                        row.push_str(&match cell.pass_ms(p) {
                            Some(t) => format!(" {:>10.3}", t.median),
                            None => format!(" {:>10}", "-"),
                        });
                    }
                    let counters: Vec<String> = m
                        .counters
                        .iter()
                        .map(|(n, v)| format!("{n}={v}"))
                        .chain(
                            m.particle_fragments
                                .map(|n| format!("particle_fragments={n}")),
                        )
                        .chain(
                            m.vs_view_sort
                                .map(|e| format!("flip_vs_view_sort={:.5}", e.flip_mean)),
                        )
                        .collect();
                    row.push_str(&format!(
                        " {:>10.3} {:>10.3} {:>10.3} {:>12}  {}",
                        m.gpu_total_ms.median,
                        m.frame_ms.median,
                        m.wall_ms.median,
                        m.bytes,
                        counters.join(" ")
                    ));
                }
                None => row.push_str(&format!(
                    "  refused: {}",
                    cell.refused.as_deref().unwrap_or("?")
                )),
            }
            println!("{row}");
            // Without timestamp queries there is no GPU time to compare.
            if let Some(m) = cell.measured.as_ref().filter(|_| results.gpu_timestamps) {
                let what = format!("{} at {} particles", cell.label(), count.particles);
                if let Some(warning) = smokeshadow_core::gpu::clock_warning(
                    &what,
                    m.frame_ms.median,
                    m.wall_ms.median,
                    results.clock_floor_ms,
                ) {
                    println!("  {warning}");
                }
            }
        }
    }
}

/// The builds against the limit ([`bench::bound`]): one row per count and technique that built
/// maps, below the cheapest build at that count.
fn print_bound_table(results: &BenchResults) {
    if !results.counts.iter().any(|c| c.cheapest.is_some()) {
        return;
    }
    let width = label_width(results);
    println!(
        "bound: each build against the cheapest possible one (one additive half-float channel \
         over the same billboards); ns per fragment-shader invocation and per channel written"
    );
    println!(
        "{:>9} {:<w$} {:>3} {:>10} {:>12} {:>8} {:>10} {:>10} {:>8}",
        "particles",
        "technique",
        "ch",
        "build ms",
        "fragments",
        "ns/frag",
        "ns/ch-wr",
        "cheapest",
        "ratio",
        w = width
    );
    for count in &results.counts {
        if let Some(c) = &count.cheapest {
            let fragments = c.work.map_or("-".to_owned(), |w| w.fragments.to_string());
            let ns = c.work.map_or("-".to_owned(), |w| {
                format!("{:.2}", c.build_ms.median * 1e6 / w.fragments.max(1) as f64)
            });
            println!(
                "{:>9} {:<w$} {:>3} {:>10.3} {:>12} {:>8} {:>10} {:>10.3} {:>8.2}",
                count.particles,
                "cheapest",
                1,
                c.build_ms.median,
                fragments,
                ns,
                ns,
                c.build_ms.median,
                1.0,
                w = width
            );
        }
        for cell in &count.cells {
            let Some((m, b)) = cell
                .measured
                .as_ref()
                .and_then(|m| m.bound.as_ref().map(|b| (m, b)))
            else {
                continue;
            };
            println!(
                "{:>9} {:<w$} {:>3} {:>10.3} {:>12} {:>8.2} {:>10.3} {:>10.3} {:>8.2}",
                count.particles,
                cell.label(),
                m.channels_used,
                b.build_ms,
                b.fragments,
                b.ns_per_fragment,
                b.ns_per_channel_write,
                b.cheapest_build_ms,
                b.over_cheapest,
                w = width
            );
        }
    }
}

fn truncate(s: &str, chars: usize) -> String {
    s.chars().take(chars).collect()
}

/// Width of the technique column: the longest cell label.
fn label_width(results: &BenchResults) -> usize {
    results
        .labels()
        .iter()
        .map(String::len)
        .max()
        .unwrap_or(0)
        .max("technique".len())
}

/// `bench --volume`: the density volume's stages (`crate::bench::volume`).
fn run_volume(args: &BenchArgs, source: &str, adapter: &AdapterPreference) -> anyhow::Result<()> {
    use crate::bench::volume::{self, VolumeBenchOptions, VolumeSource};
    if !args.techniques.is_empty() {
        return run_volume_frames(args, source, adapter);
    }
    let options = VolumeBenchOptions {
        source: VolumeSource::parse(source),
        grid_sizes: args.grid_sizes.clone(),
        coverages: args.coverages.clone(),
        light_steps: match args.light_steps.is_empty() {
            true => vec![16, 64, 256],
            false => args.light_steps.clone(),
        },
        eye_steps: args.eye_steps,
        frames: args.frames,
        warmup: args.warmup,
        size_px: args.size.map_or((256, 192), |s| (s.width, s.height)),
    };
    let gpu = Gpu::new(adapter).wait()?;
    let volume::VolumeBench { rows, skipped } = volume::run(&gpu, &options)?;
    println!(
        "bench --volume {source}: eye rays {}x{}, {} eye steps, {} frames after {} warm-up, {}",
        options.size_px.0,
        options.size_px.1,
        options.eye_steps,
        options.frames,
        options.warmup,
        gpu.describe()
    );
    println!("  median wall time in ms, from submission to the results' readback");
    println!(
        "  rmse: the eye march's radiance against the same grid's march with the most light steps"
    );
    println!(
        "{:<14} {:>5} {:>10} {:<32} {:>5} {:>5} {:>10} {:>9}",
        "grid", "cover", "MiB", "stage", "eye", "light", "wall ms", "rmse"
    );
    for r in &rows {
        let rmse = r
            .rmse_vs_most_steps
            .map_or(String::new(), |e| format!("{e:.5}"));
        let coverage = r.coverage.map_or(String::new(), |c| format!("{c}"));
        println!(
            "{:<14} {coverage:>5} {:>10.2} {:<32} {:>5} {:>5} {:>10.1} {:>9}",
            r.grid,
            r.grid_bytes as f64 / (1024.0 * 1024.0),
            r.stage,
            r.eye_steps,
            r.light_steps,
            r.median_ms,
            rmse
        );
    }
    for line in &skipped {
        println!("skipped {line}");
    }
    let path = volume::write_csv(&rows, &args.output)?;
    println!("wrote {}", path.display());
    if let Some(chart) = volume::write_chart(&rows, &args.output)? {
        println!("wrote {}", chart.display());
    }
    Ok(())
}

/// `bench --volume SOURCE -t ...`: the volume's frames per technique and coverage.
fn run_volume_frames(
    args: &BenchArgs,
    source: &str,
    adapter: &AdapterPreference,
) -> anyhow::Result<()> {
    use crate::bench::volume_frames::{self, FrameStudy};
    let (mut scene, coverages) = match source {
        "cloud" => (
            smokeshadow_core::scene::Scene::embedded("cloud").expect("the cloud scene is embedded"),
            args.coverages.iter().map(|&c| Some(c)).collect(),
        ),
        path => (
            crate::particles::scene_for_volume_file(
                Path::new(path),
                &smokeshadow_core::files::Files::host(),
            )?,
            vec![None],
        ),
    };
    if let Some(size) = args.size {
        scene.output.width_px = size.width;
        scene.output.height_px = size.height;
    }
    let techniques = smokeshadow_core::shadow::expand_all(&args.techniques);
    for name in &techniques {
        let entry = smokeshadow_core::shadow::find(name)?;
        if let Some(refusal) = entry.refusal(true, 0) {
            anyhow::bail!("{refusal}");
        }
    }
    let build_steps = match args.build_steps.is_empty() {
        true => vec![scene.volume.as_ref().map_or(64, |v| v.build_steps)],
        false => args.build_steps.clone(),
    };
    let shadow_res = match args.shadow_res.is_empty() {
        true => vec![scene.shadow.resolution_px],
        false => args.shadow_res.clone(),
    };
    let light_steps = match args.light_steps.is_empty() {
        true => vec![smokeshadow_core::shadow::srm::DEFAULT_LIGHT_STEPS],
        false => args.light_steps.clone(),
    };
    // Refused before any frame is rendered, as the scene's own parameters are.
    for &n in &light_steps {
        smokeshadow_core::shadow::set_param(
            &mut smokeshadow_core::shadow::TechniqueParams::new(1, 1),
            smokeshadow_core::shadow::srm::LIGHT_STEPS.key,
            &(n as f32).into(),
        )?;
    }
    let study = FrameStudy {
        scene,
        coverages,
        techniques,
        channels: args.channels,
        shadow_res,
        build_steps,
        light_steps,
        frames: args.frames,
        warmup: args.warmup,
    };
    let gpu = Gpu::new(adapter).wait()?;
    let rows = volume_frames::run(&gpu, &study)?;
    println!(
        "bench --volume {source}: {}x{} frames of `{}`, {} channels, median of {} after {} warm-up, GPU timestamps, {}",
        study.scene.output.width_px,
        study.scene.output.height_px,
        study.scene.name,
        study.channels,
        study.frames,
        study.warmup,
        gpu.describe()
    );
    println!(
        "{:>8} {:<10} {:>5} {:>5} {:>5} {:>8} {:>9} {:>9} {:>9} {:>6} {:>8} {:>9} {:>9}",
        "coverage",
        "technique",
        "res",
        "build",
        "light",
        "MiB",
        "frame ms",
        "build ms",
        "eye ms",
        "/ srm",
        "RMS T",
        "bias edge",
        "bias in"
    );
    for r in &rows {
        println!(
            "{:>8} {:<10} {:>5} {:>5} {:>5} {:>8.2} {:>9.1} {:>9.1} {:>9.1} {:>6} {:>8.5} {:>+9.4} {:>+9.4}",
            r.coverage.map_or(String::new(), |c| format!("{c}")),
            r.technique,
            r.shadow_res,
            r.build_steps,
            r.light_steps.map_or("-".to_owned(), |n| n.to_string()),
            r.bytes as f64 / (1024.0 * 1024.0),
            r.frame_ms,
            r.build_ms,
            r.eye_ms,
            volume_frames::ratio_to_srm(&rows, r).map_or(String::new(), |x| format!("{x:.2}")),
            r.rms_t,
            r.bias_edge,
            r.bias_inside
        );
    }
    if rows.iter().any(|r| r.technique == "srm") && rows.len() > 1 {
        for (name, coverage) in volume_frames::srm_crossovers(&rows) {
            match coverage {
                Some(c) => println!("srm is slower than {name} from coverage {c}"),
                None => println!("srm is faster than {name} at every coverage measured"),
            }
        }
    }
    let path = volume_frames::write_csv(&rows, &args.output)?;
    println!("wrote {}", path.display());
    for chart in volume_frames::write_charts(&rows, &args.output)? {
        println!("wrote {}", chart.display());
    }
    Ok(())
}

/// A coverage in 0..1.
fn coverage_fraction(text: &str) -> Result<f32, String> {
    let c: f32 = text
        .trim()
        .parse()
        .map_err(|_| format!("{text:?} is not a number"))?;
    match (0.0..=1.0).contains(&c) {
        true => Ok(c),
        false => Err(format!("coverage {c} is outside [0, 1]")),
    }
}
