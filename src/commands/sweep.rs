//! `smokeshadow sweep`: technique x channels x shadow resolution x splat mode -> time, bytes and
//! error, as CSV, JSON, SVG charts and an HTML report ([`crate::sweep`]). With no options: the
//! thesis experiment on the embedded scene.

use std::path::PathBuf;

use crate::gpu::{AdapterPreference, Gpu};
use crate::shadow::SplatMode;
use crate::sweep::{self, SweepOptions};

#[derive(Clone, Debug, clap::Args)]
pub struct SweepArgs {
    /// Scene file (TOML), or the name of an embedded scene (`smokeshadow info` lists them); the
    /// embedded thesis scene when omitted.
    pub scene: Option<PathBuf>,
    #[command(flatten)]
    pub particles: super::ParticlesArg,
    /// Techniques, comma-separated, `all` for every contender (`none` and `exact` are always
    /// measured, as the frame-time baseline and the reference).
    #[arg(long, value_delimiter = ',', default_values_t = crate::shadow::default_sweep())]
    pub techniques: Vec<String>,
    /// Channel budgets, comma-separated; a budget below a technique's minimum skips that cell
    /// (noted in the report).
    #[arg(long, value_delimiter = ',', default_value = "24,16,8,6")]
    pub channels: Vec<u32>,
    /// Shadow-map resolutions, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "512")]
    pub shadow_res: Vec<u32>,
    /// Splat modes, comma-separated (techniques that ignore it run once).
    #[arg(long, value_delimiter = ',', value_enum, default_value = "point")]
    pub splat: Vec<SplatMode>,
    #[command(flatten)]
    pub params: super::ParamArgs,
    /// Timed frames per cell (medians over these).
    #[arg(long, default_value_t = SweepOptions::default().frames, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub frames: u32,
    /// Untimed warm-up frames before them, after the cell's transmittance probe has built the
    /// maps once (they reuse its maps; the first frame compiles the lighting's shaders).
    #[arg(long, default_value_t = SweepOptions::default().warmup)]
    pub warmup: u32,
    /// Stop timing a cell after this many seconds of timed frames (but after at least 3, or 2
    /// when each took longer than this), so slow techniques do not hold the sweep;
    /// `frames_timed` says how many it took.
    #[arg(long, default_value_t = SweepOptions::default().cell_seconds, value_parser = positive_seconds)]
    pub cell_seconds: f64,
    /// Output size as WIDTHxHEIGHT (default: the scene's).
    #[arg(long)]
    pub size: Option<super::Size>,
    /// Output folder (created if missing).
    #[arg(long, short = 'o', default_value = "sweep")]
    pub output: PathBuf,
    /// Keep the cells an earlier (interrupted) run finished with the same settings.
    #[arg(long)]
    pub resume: bool,
    /// Also write each cell's linear HDR frame (premultiplied radiance, the smoke's opacity in
    /// alpha) as OpenEXR beside its PNG; the report links them.
    #[arg(long)]
    pub exr: bool,
}

pub fn run(args: &SweepArgs, adapter: &AdapterPreference) -> anyhow::Result<()> {
    let mut scene = super::load_scene(args.scene.as_deref(), args.particles)?;
    args.params.apply(&mut scene);
    if let Some(size) = args.size {
        scene.output.width_px = size.width;
        scene.output.height_px = size.height;
    }
    let options = SweepOptions {
        techniques: crate::shadow::expand_all(&args.techniques),
        channels: args.channels.clone(),
        shadow_res: args.shadow_res.clone(),
        splats: args.splat.clone(),
        frames: args.frames,
        warmup: args.warmup,
        cell_seconds: args.cell_seconds,
        resume: args.resume,
        exr: args.exr,
    };
    let gpu = Gpu::new(adapter)?;
    let results = sweep::run(&gpu, &scene, &options, &args.output)?;
    println!(
        "{} cells in {:.1} s on {}; report: {}",
        results.cells.len(),
        results.metadata.wall_s,
        gpu.describe(),
        args.output.join("index.html").display()
    );
    println!(
        "{:<10} {:>4} {:>5} {:>8} {:>11} {:>11} {:>10} {:>9} {:>9} {:>11} {:>9}",
        "technique",
        "ch",
        "res",
        "splat",
        "bytes",
        "transient",
        "frame ms",
        "overhead",
        "FLIP own",
        "FLIP exact",
        "RMS T"
    );
    let opt = |v: Option<f64>| v.map_or("-".to_owned(), |v| format!("{v:.4}"));
    for c in &results.cells {
        println!(
            "{:<10} {:>4} {:>5} {:>8} {:>11} {:>11} {:>10.2} {:>9} {:>9} {:>11} {:>9}",
            c.technique,
            c.channels,
            c.shadow_res,
            c.splat.name(),
            c.bytes,
            c.transient_bytes,
            c.frame_ms.median,
            c.overhead_ratio
                .map_or("-".to_owned(), |r| format!("{r:.2}x")),
            opt(c.vs_own_24.map(|e| e.flip_mean)),
            opt(c.vs_exact.map(|e| e.flip_mean)),
            opt(c.rms_transmittance_error),
        );
    }
    for s in &results.skipped {
        println!(
            "skipped {} at {} channels: {}",
            s.technique, s.channels, s.reason
        );
    }
    Ok(())
}

/// Parses `--cell-seconds`: a positive, finite number of seconds.
fn positive_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("\"{s}\" is not a positive number of seconds")),
    }
}
