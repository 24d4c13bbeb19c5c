//! `smokeshadow sweep`: technique x channels x shadow resolution x splat mode -> time, bytes and
//! error, as CSV, JSON, SVG charts and an HTML report ([`crate::sweep`]). With no options: the
//! thesis experiment on the embedded scene. `--scenes` sweeps several scenes into a gallery,
//! `--shard K/N` runs a part of a sweep, `--merge` assembles the parts.

use crate::Wait;
use std::path::{Path, PathBuf};

use crate::sweep::{self, CellTiming, Grid, Shard, SweepOptions, SweepOutcome, SweepResults};
use smokeshadow_core::gpu::{AdapterPreference, Gpu};
use smokeshadow_core::scene::Scene;
use smokeshadow_core::shadow::SplatMode;

#[derive(Clone, Debug, clap::Args)]
pub struct SweepArgs {
    /// Scene file (TOML), or the name of an embedded scene (`smokeshadow info` lists them); the
    /// embedded thesis scene when omitted.
    #[arg(conflicts_with = "scenes")]
    pub scene: Option<PathBuf>,
    /// Several scenes, comma-separated names or paths, or `all` for the gallery
    /// (`scene::GALLERY`): each scene's sweep goes to `DIR/<scene>/`, and a gallery report
    /// ranking the techniques across them to `DIR`.
    #[arg(long, value_delimiter = ',', value_name = "LIST")]
    pub scenes: Option<Vec<String>>,
    /// Run only shard K of N: the cells whose stable index (position in the full plan, over
    /// every scene) is K mod N. Writes cells and `shards/K-of-N.json`, not the report; shards
    /// may share one output folder. `--merge` assembles them.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<Shard>,
    /// Assemble the tables, charts and reports from the cells of these shard folders into
    /// `-o` (no GPU needed); refuses shards of different sweeps, and names missing cells.
    #[arg(long, num_args = 1.., value_name = "DIR",
          conflicts_with_all = ["scene", "scenes", "shard", "resume", "exr", "techniques",
                                "channels", "bytes_per_texel", "memory", "shadow_res", "splat", "particle_res", "params", "param_set", "frames",
                                "warmup", "cell_seconds", "size", "particles", "animate", "fps", "orbit", "light_orbit", "framing", "shadow_history"])]
    pub merge: Option<Vec<PathBuf>>,
    #[command(flatten)]
    pub particles: super::ParticlesArg,
    /// Techniques, comma-separated, `all` for every contender (`none` and `exact` are always
    /// measured, as the frame-time baseline and the reference).
    #[arg(long, value_delimiter = ',', default_values_t = smokeshadow_core::shadow::default_sweep())]
    pub techniques: Vec<String>,
    /// Channel budgets, comma-separated; a budget below a technique's minimum skips that cell
    /// (noted in the report).
    #[arg(long, value_delimiter = ',', default_value = "24,16,8,6")]
    pub channels: Vec<u32>,
    /// Byte budgets per shadow-map texel, comma-separated, or `none`: each technique runs at
    /// the largest configuration whose resident bytes fit each, at its precision (`--param
    /// osm_precision=single`, ...), and the report's answer compares at these; the channel
    /// budgets stay the thesis' view. A technique that fits no configuration is skipped with
    /// the bytes it needs.
    /// Default 48,24,12, or none with `--memory`.
    #[arg(long, value_name = "BYTES,...|none", value_parser = parse_byte_budgets)]
    pub bytes_per_texel: Option<ByteBudgets>,
    /// Memory budgets in total bytes, comma-separated, with a unit (`12MiB,6MiB,3MiB`; B, KiB,
    /// MiB, GiB, KB, MB, GB): at each `--shadow-res`, each technique at the largest
    /// configuration whose resident bytes fit (a whole number of bytes a texel there), and the
    /// answer at each names every technique at the resolution `smokeshadow tune` chose for it
    /// on the training scenes (the shipped `docs/tuned_params.toml`'s `[shapes]`, or a
    /// `--params FILE`'s), or, where tune chose none of the swept, at its most accurate of them
    /// here, marked "best here". Replaces the default `--bytes-per-texel`.
    #[arg(long, value_name = "SIZE,...", value_delimiter = ',', value_parser = sweep::parse_memory)]
    pub memory: Vec<u64>,
    /// Shadow-map resolutions, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "512")]
    pub shadow_res: Vec<u32>,
    /// Splat modes, comma-separated (techniques that ignore it run once): segment, the
    /// reference's density model, or point, the thesis'.
    #[arg(long, value_delimiter = ',', value_enum, default_value = "segment")]
    pub splat: Vec<SplatMode>,
    /// Resolutions of the particle pass, comma-separated: 1, 1/2, 1/4 of the frame's per axis,
    /// each its own cell (`has`, which draws its own particle pass, runs at 1 only).
    #[arg(long, value_delimiter = ',', value_name = "RES,...", default_value = "1",
          value_parser = smokeshadow_core::render::parse_particle_res)]
    pub particle_res: Vec<smokeshadow_core::render::ParticleRes>,
    #[command(flatten)]
    pub params: super::ParamArgs,
    /// Timed frames per cell (medians over these).
    #[arg(long, default_value_t = SweepOptions::default().timing.frames, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub frames: u32,
    /// Untimed warm-up frames before them, after the cell's transmittance probe has built the
    /// maps once (they reuse its maps; the first frame compiles the lighting's shaders).
    #[arg(long, default_value_t = SweepOptions::default().timing.warmup)]
    pub warmup: u32,
    /// Time a cell's frames for at most this many seconds: no frame starts that, as long as the
    /// cell's average, would end past them (but at least 3 frames, or 2 when each took longer
    /// than this), so slow techniques do not hold the sweep; `frames_timed` says how many it
    /// took.
    #[arg(long, default_value_t = SweepOptions::default().timing.cell_seconds, value_parser = positive_seconds)]
    pub cell_seconds: f64,
    /// Output size as WIDTHxHEIGHT (default: the scene's).
    #[arg(long)]
    pub size: Option<super::Size>,
    /// Output folder (created if missing).
    #[arg(long, short = 'o', default_value = "sweep")]
    pub output: PathBuf,
    /// Smoke in motion: also render every cell over the consecutive frames from START to END
    /// (scene time in seconds, e.g. `7.1..7.87`), `exact` at each, in this one process, and
    /// give each cell its temporal measures (`temporal_error`, its 99.9th percentile, pops, the
    /// shadow's T, FLIP over time: docs/sweeps.md's "Smoke in motion"). The still measures stay at
    /// the scene's own time.
    #[arg(long, value_name = "START..END")]
    pub animate: Option<String>,
    /// Degrees the camera turns about the vertical through its target over `--animate`'s span
    /// (default 0): every build's draw order turns with the view (`avsm`'s insertion, the
    /// rounding of additive sums).
    #[arg(long, requires = "animate", allow_negative_numbers = true)]
    pub orbit: Option<f32>,
    /// Degrees the light turns about the vertical through its target over `--animate`'s span
    /// (default 0): every map's frustum, slices and texels move with it.
    #[arg(long, requires = "animate", allow_negative_numbers = true)]
    pub light_orbit: Option<f32>,
    /// How the light's maps frame the smoke, over the scene's `shadow.framing`: `fit` (each
    /// frame), `stable` (fitted, then held in steps as the smoke moves, the shimmer fix engines
    /// use) or `cone` (the thesis' whole cone).
    #[arg(long, value_enum)]
    pub framing: Option<smokeshadow_core::scene::Framing>,
    /// The shadow's temporal history weight w, over the scene's `shadow.history`: every
    /// technique's T at the particles' lighting points blended with its last,
    /// T' = (1 − w) T + w T'_prev (0.9: engines' default; 0: off). `exact` is never filtered,
    /// and a technique that lights the particles itself (`has`) is skipped.
    #[arg(long, value_name = "W", value_parser = history_weight)]
    pub shadow_history: Option<f32>,
    /// Frames per second of `--animate` (default: a particle or volume sequence's own rate, else 30).
    #[arg(long, requires = "animate")]
    pub fps: Option<f32>,
    /// Keep the cells an earlier (interrupted) run finished with the same settings.
    #[arg(long)]
    pub resume: bool,
    /// Also write each cell's linear HDR frame (premultiplied radiance, the smoke's opacity in
    /// alpha) as OpenEXR beside its PNG; the report links them.
    #[arg(long)]
    pub exr: bool,
}

pub fn run(args: &SweepArgs, adapter: &AdapterPreference) -> anyhow::Result<()> {
    if let Some(dirs) = &args.merge {
        // No GPU: merging reads cells.
        let outcome = sweep::merge(dirs, &args.output)?;
        print_outcome(&outcome, &args.output, "merged");
        if let SweepOutcome::Whole { scenes, .. } = &outcome {
            for note in exact_notes(scenes) {
                println!("{note}");
            }
        }
        return Ok(());
    }
    let names: Vec<PathBuf> = match &args.scenes {
        None => vec![],
        Some(list) => {
            let mut names: Vec<String> = Vec::new();
            for name in list {
                let expanded: Vec<String> = match name.as_str() {
                    "all" => smokeshadow_core::scene::GALLERY
                        .iter()
                        .map(|n| n.to_string())
                        .collect(),
                    _ => vec![name.clone()],
                };
                for n in expanded {
                    if !names.contains(&n) {
                        names.push(n);
                    }
                }
            }
            if names.is_empty() {
                anyhow::bail!("--scenes is empty: give scene names or paths, or all");
            }
            names.into_iter().map(PathBuf::from).collect()
        }
    };
    let scenes: Vec<Scene> = match args.scenes {
        None => vec![prepare(args, args.scene.as_deref())?],
        Some(_) => names
            .iter()
            .map(|n| {
                prepare(args, Some(n))
                    .map_err(|err| anyhow::anyhow!("--scenes {}: {err:#}", n.display()))
            })
            .collect::<anyhow::Result<_>>()?,
    };
    // A file sequence's own frames, unless told otherwise.
    let fps = args.fps.unwrap_or_else(|| {
        scenes
            .iter()
            .find_map(Scene::sequence_rate_hz)
            .unwrap_or(smokeshadow_core::motion::DEFAULT_FPS)
    });
    let animate = args
        .animate
        .as_deref()
        .map(|range| {
            smokeshadow_core::motion::Span::parse(range, fps)?
                .with_orbit(args.orbit.unwrap_or(0.0))?
                .with_light_orbit(args.light_orbit.unwrap_or(0.0))
        })
        .transpose()
        .map_err(anyhow::Error::msg)?;
    let options = SweepOptions {
        grid: Grid {
            techniques: smokeshadow_core::shadow::expand_all(&args.techniques),
            channels: args.channels.clone(),
            bytes_per_texel: match (&args.bytes_per_texel, args.memory.is_empty()) {
                (Some(b), _) => b.0.clone(),
                (None, true) => sweep::DEFAULT_BYTES_PER_TEXEL.to_vec(),
                (None, false) => Vec::new(),
            },
            memory: args.memory.clone(),
            shadow_res: args.shadow_res.clone(),
            splats: args.splat.clone(),
            particle_res: args.particle_res.clone(),
        },
        timing: CellTiming {
            frames: args.frames,
            warmup: args.warmup,
            cell_seconds: args.cell_seconds,
            animate,
        },
        resume: args.resume,
        exr: args.exr,
        gallery: args.scenes.is_some(),
        shard: args.shard,
        // A parameter file's shapes where it has them, else those the shipped defaults were
        // chosen with.
        shapes: args
            .params
            .set
            .as_ref()
            .map(|s| s.1.clone())
            .filter(|s| !s.is_empty())
            .unwrap_or_else(crate::tune::shipped_shapes),
    };
    let gpu = Gpu::new(adapter).wait()?;
    let outcome = sweep::run(&gpu, &scenes, &options, &args.output)?;
    print_outcome(&outcome, &args.output, &gpu.describe());
    Ok(())
}

/// A scene as the sweep runs it: `--particles`, `--param` and `--size` applied.
fn prepare(args: &SweepArgs, scene: Option<&Path>) -> anyhow::Result<Scene> {
    let mut scene = super::load_scene(scene, args.particles)?;
    args.params.apply(&mut scene);
    if let Some(framing) = args.framing {
        scene.shadow.framing = framing;
    }
    if let Some(weight) = args.shadow_history {
        scene.shadow.history = weight;
    }
    if let Some(size) = args.size {
        scene.output.width_px = size.width;
        scene.output.height_px = size.height;
    }
    Ok(scene)
}

/// Prints what a sweep produced: a shard's one line, or every scene's table and, for a
/// gallery, ending with the aggregate ranking.
/// For merged shards: a note per scene whose cells were compared with different `exact`
/// images (shards on machines whose lavapipe rounds differently): each cell's errors are
/// against its own machine's reference, which the report's numbers should be read with.
fn exact_notes(scenes: &[SweepResults]) -> Vec<String> {
    scenes
        .iter()
        .filter_map(|r| {
            let mut seen: Vec<(&str, &str)> = Vec::new();
            for c in &r.cells {
                if let Some(m) = &c.measured_against {
                    let key = (m.exact_image_sha256.as_str(), m.machine.adapter.as_str());
                    if !seen.iter().any(|(h, _)| *h == key.0) {
                        seen.push(key);
                    }
                }
            }
            (seen.len() > 1).then(|| {
                let adapters: Vec<&str> = seen.iter().map(|(_, a)| *a).collect();
                format!(
                    "note: {}'s cells were compared with {} different exact images (adapters: {}); each cell's errors are against the exact its own shard rendered",
                    r.metadata.scene,
                    seen.len(),
                    adapters.join(", ")
                )
            })
        })
        .collect()
}

fn print_outcome(outcome: &SweepOutcome, dir: &Path, machine: &str) {
    match outcome {
        SweepOutcome::Shard(m) => {
            println!(
                "shard {}: {} cells measured, {} reused, in {:.1} s on {}; merge the shards with: smokeshadow sweep --merge {} -o DIR",
                m.shard,
                m.measured,
                m.reused,
                m.wall_s,
                machine,
                dir.display()
            );
        }
        SweepOutcome::Whole { scenes, gallery } => {
            for r in scenes {
                let folder = match gallery {
                    Some(_) => dir.join(&r.metadata.scene),
                    None => dir.to_owned(),
                };
                print_table(r, &folder);
            }
            if let Some(g) = gallery {
                println!(
                    "\ngallery of {} scenes: {}",
                    scenes.len(),
                    dir.join("index.html").display()
                );
                for line in &g.advice {
                    println!("- {line}");
                }
                println!(
                    "\nranking at equal bytes across scenes (rank by FLIP vs exact within each scene and budget):"
                );
                let moving = g.ranking.iter().any(|r| r.motion_median_rank.is_some());
                println!(
                    "{:<16} {:>18} {:>12} {:>11} {:<16} {:>7}{}",
                    "technique",
                    "budget",
                    "median rank",
                    "worst rank",
                    "worst on",
                    "scenes",
                    if moving { "  in motion" } else { "" }
                );
                for row in &g.ranking {
                    let mut t = row.technique.clone();
                    if scenes
                        .iter()
                        .flat_map(|r| &r.cells)
                        .any(|c| c.shadow_res != row.shadow_res || c.splat != row.splat)
                    {
                        t = format!("{t} {} {}", row.shadow_res, row.splat.name());
                    }
                    println!(
                        "{:<16} {:>18} {:>12} {:>11} {:<16} {:>7}{}",
                        t,
                        row.budget.to_string(),
                        format!("{}", row.median_rank),
                        row.worst_rank,
                        row.worst_scene,
                        row.scenes,
                        match (moving, row.motion_median_rank) {
                            (true, Some(m)) => format!(" {m:>10}"),
                            (true, None) => format!(" {:>10}", "-"),
                            (false, _) => String::new(),
                        }
                    );
                }
            }
        }
    }
}

/// One scene's table.
fn print_table(results: &SweepResults, folder: &Path) {
    println!(
        "{}: {} cells in {:.1} s on {}; report: {}",
        results.metadata.scene,
        results.cells.len(),
        results.metadata.wall_s,
        results.metadata.adapter,
        folder.join("index.html").display()
    );
    println!(
        "{:<10} {:>4} {:>5} {:>8} {:>5} {:>11} {:>11} {:>10} {:>10} {:>9} {:>9} {:>11} {:>9}",
        "technique",
        "ch",
        "res",
        "splat",
        "prtcl",
        "resident B",
        "transient",
        "frame ms",
        "wall ms",
        "overhead",
        "FLIP own",
        "FLIP exact",
        "RMS T"
    );
    let opt = |v: Option<f64>| v.map_or("-".to_owned(), |v| format!("{v:.4}"));
    for c in &results.cells {
        println!(
            "{:<10} {:>4} {:>5} {:>8} {:>5} {:>11} {:>11} {:>10.2} {:>10.2} {:>9} {:>9} {:>11} {:>9}",
            c.technique,
            c.channels,
            c.shadow_res,
            c.splat.name(),
            c.particle_res.name(),
            c.resident_bytes,
            c.transient_bytes,
            c.frame_ms.median,
            c.wall_ms.median,
            c.overhead_ratio
                .map_or("-".to_owned(), |r| format!("{r:.2}x")),
            opt(c.vs_own_24.map(|e| e.flip_mean)),
            opt(c.vs_exact.map(|e| e.flip_mean)),
            opt(c.rms_transmittance_error),
        );
        let what = format!("{} at {} channels", c.technique, c.channels);
        if let Some(warning) = results
            .metadata
            .timestamp_queries
            .then(|| {
                smokeshadow_core::gpu::clock_warning(
                    &what,
                    c.frame_ms.median,
                    c.wall_ms.median,
                    results.metadata.clock_floor_ms,
                )
            })
            .flatten()
        {
            println!("  {warning}");
        }
    }
    for s in &results.skipped {
        println!("skipped {} at {}: {}", s.technique, s.budget(), s.reason);
    }
    // The answers at equal bytes, equal memory and equal time (on this adapter), as the report
    // gives them: each cell as `technique channels[ at res²] (FLIP[, ratio])`, or `none` when no
    // cell answers.
    let line = |cells: &[&sweep::CellResult], detail: Detail, none: &str| {
        let ranked: Vec<String> = cells
            .iter()
            .map(|c| {
                let flip = c.vs_exact.map_or(f64::NAN, |e| e.flip_mean);
                match detail {
                    Detail::Flip => format!("{} {} ({flip:.4})", c.technique, c.channels),
                    Detail::Resolution(total) => format!(
                        "{} {} at {}²{} ({flip:.4})",
                        c.technique,
                        c.channels,
                        c.shadow_res,
                        match sweep::answer::shape_tuned(results, total, c) {
                            true => "",
                            false => " best here",
                        }
                    ),
                    Detail::Ratio => format!(
                        "{} {} ({flip:.4}, {:.2}x)",
                        c.technique,
                        c.channels,
                        c.overhead_ratio.unwrap_or(f64::NAN)
                    ),
                }
            })
            .collect();
        match ranked.is_empty() {
            true => none.to_owned(),
            false => ranked.join(", "),
        }
    };
    // An animated sweep's answer in motion under each still one: the same cells by temporal
    // error.
    let stable = |cells: &[&sweep::CellResult]| {
        let ranked = sweep::answer::most_stable(cells);
        if ranked.is_empty() {
            return;
        }
        let listed: Vec<String> = ranked
            .iter()
            .map(|c| {
                let m = c.motion.as_ref().expect("most_stable keeps moving cells");
                format!(
                    "{} {} ({:.2e}, {:.0} pops)",
                    c.technique, c.channels, m.temporal_error, m.pops_per_frame
                )
            })
            .collect();
        println!(
            "  in motion, by temporal error vs exact (pops a frame): {}",
            listed.join(", ")
        );
    };
    println!("{}", sweep::report::same_footing(results, false));
    if let Some(m) = &results.metadata.motion {
        println!(
            "in motion: every cell and exact over the {}; exact changes by {:.2e} a frame (mean |ΔL|, linear luminance)",
            m.change.span.describe(),
            m.change.luminance
        );
    }
    for b in sweep::answer::byte_budgets(results) {
        let at = sweep::answer::at_byte_budget(results, b);
        println!(
            "at {b} bytes a texel, by FLIP vs exact: {}",
            line(&at, Detail::Flip, "no technique fits")
        );
        stable(&at);
    }
    for total in sweep::answer::memory_budgets(results) {
        let at = sweep::answer::at_memory_budget(results, total);
        println!(
            "at {} in all, by FLIP vs exact (each at the map resolution tune chose on the \
             training scenes, or, marked \"best here\", its most accurate on this scene where \
             tune chose none of the swept): {}",
            crate::report::bytes(total),
            line(&at, Detail::Resolution(total), "no technique fits")
        );
        stable(&at);
    }
    if results.cells.iter().any(|c| c.overhead_ratio.is_some()) {
        for &ratio in sweep::answer::TIME_BUDGETS {
            let at = sweep::answer::at_time_budget(results, ratio);
            println!(
                "within {ratio:.1}x none's frame time on {}, by FLIP vs exact: {}",
                results.metadata.adapter,
                line(&at, Detail::Ratio, "no technique is that fast")
            );
            stable(&at);
        }
    }
}

/// What an answer line gives of each cell beside its FLIP.
#[derive(Clone, Copy)]
enum Detail {
    Flip,
    /// Its map resolution, and whether `tune` chose it (the answer at this total memory).
    Resolution(u64),
    /// Its frame time over `none`'s (the answer at equal time).
    Ratio,
}

/// `--bytes-per-texel`'s budgets (empty for `none`).
#[derive(Clone, Debug, PartialEq)]
pub struct ByteBudgets(pub Vec<u32>);

fn parse_byte_budgets(s: &str) -> Result<ByteBudgets, String> {
    if s.trim() == "none" {
        return Ok(ByteBudgets(Vec::new()));
    }
    let mut out = Vec::new();
    for part in s.split(',') {
        match part.trim().parse::<u32>() {
            Ok(b) if (1..=1024).contains(&b) => {
                if !out.contains(&b) {
                    out.push(b);
                }
            }
            _ => {
                return Err(format!(
                    "\"{}\" is not a byte budget: give whole bytes per texel, 1..=1024, or none",
                    part.trim()
                ));
            }
        }
    }
    Ok(ByteBudgets(out))
}

/// Parses `--cell-seconds`: a positive, finite number of seconds.
fn positive_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("\"{s}\" is not a positive number of seconds")),
    }
}

/// `--shadow-history`: a weight in [0, [`crate::scene::MAX_HISTORY`]].
fn history_weight(s: &str) -> Result<f32, String> {
    let max = smokeshadow_core::scene::MAX_HISTORY;
    match s.parse::<f32>() {
        Ok(w) if (0.0..=max).contains(&w) => Ok(w),
        _ => Err(format!(
            "{s} is no history weight: a number from 0 (off) to {max} (0.9 is engines' default)"
        )),
    }
}
