//! `smokeshadow particles`: writes a scene's particles (its emitters' simulation, or its particle
//! file's frame) as PLY or CSV, at the scene's time, at `--time T`, or as a numbered sequence of
//! frames (`--frames A..B`), so that they can be inspected, edited or read back with
//! `[particles] file = ...`.

use std::path::PathBuf;

use anyhow::Context;

use crate::particles::{self, Format};
use smokeshadow_core::sim::Simulation;

#[derive(Clone, Debug, clap::Args)]
pub struct ParticlesArgs {
    /// Scene file (TOML), the name of an embedded scene, or a particle file; the embedded
    /// thesis scene when omitted.
    pub scene: Option<PathBuf>,
    #[command(flatten)]
    pub particles: super::ParticlesArg,
    /// Output file: `.ply` (binary, or ASCII with `--format ply-ascii`) or `.csv`. With
    /// `--frames`, a pattern with `%04d` (or `%d`) for the frame number.
    #[arg(long, short = 'o')]
    pub output: PathBuf,
    /// The format (default: the output's extension; `.ply` is binary little-endian PLY).
    #[arg(long, value_enum)]
    pub format: Option<Format>,
    /// Simulated time in seconds (default: the scene's `sim.duration_s`).
    #[arg(long, conflicts_with = "frames", value_parser = non_negative_seconds)]
    pub time: Option<f32>,
    /// A numbered sequence: frames A to B (inclusive) at `--fps`, frame n at t = n / fps.
    #[arg(long, value_name = "A..B", value_parser = parse_frames)]
    pub frames: Option<(u32, u32)>,
    /// Frames per second of `--frames`.
    #[arg(long, default_value_t = 24.0, value_parser = positive_rate)]
    pub fps: f32,
}

pub fn run(args: &ParticlesArgs) -> anyhow::Result<()> {
    let mut scene = super::load_scene(args.scene.as_deref(), args.particles)?;
    if args.format.is_none() && Format::of_path(&args.output).is_none() {
        anyhow::bail!(
            "cannot tell the format of {}: name it .ply or .csv, or give --format",
            args.output.display()
        );
    }
    let pattern = args.output.to_string_lossy().into_owned();
    let Some((first, last)) = args.frames else {
        if particles::is_sequence(&pattern) {
            anyhow::bail!("{pattern} is a sequence pattern: give --frames A..B");
        }
        if let Some(t) = args.time {
            scene.sim.duration_s = t;
        }
        let ps = particles::scene_particles(&scene)?;
        particles::write(&args.output, &ps, args.format)?;
        println!(
            "wrote {}: {} at t = {} s",
            args.output.display(),
            particles::Summary::of(&ps),
            scene.sim.duration_s
        );
        return Ok(());
    };
    if !particles::is_sequence(&pattern) {
        anyhow::bail!(
            "--frames writes a numbered sequence: put %04d in the output's name (smoke.%04d.ply)"
        );
    }
    // Emitter scenes step one simulation forward through the frames; file scenes read theirs.
    let mut sim = scene.particles.is_none().then(|| Simulation::new(&scene));
    for frame in first..=last {
        let t = frame as f32 / args.fps;
        let ps = match &mut sim {
            Some(sim) => {
                sim.advance_to(t);
                sim.particles()
            }
            None => {
                scene.sim.duration_s = t;
                particles::scene_particles(&scene)?
            }
        };
        if ps.is_empty() {
            anyhow::bail!(
                "frame {frame} (t = {t} s) has no particles yet: start the sequence later"
            );
        }
        let path = PathBuf::from(particles::frame_name(&pattern, i64::from(frame)));
        particles::write(&path, &ps, args.format).with_context(|| format!("frame {frame}"))?;
    }
    println!(
        "wrote frames {first}..={last} of {pattern} at {} fps (read back with [particles] file = \"{pattern}\", frame_rate_hz = {})",
        args.fps, args.fps
    );
    Ok(())
}

fn parse_frames(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("\"{s}\" is not a frame range A..B (whole numbers, A <= B)");
    let (a, b) = s.split_once("..").ok_or_else(bad)?;
    let b = b.strip_prefix('=').unwrap_or(b);
    let (a, b): (u32, u32) = (
        a.trim().parse().map_err(|_| bad())?,
        b.trim().parse().map_err(|_| bad())?,
    );
    if a > b {
        return Err(bad());
    }
    if b - a >= 100_000 {
        return Err(format!("{s}: at most 100000 frames"));
    }
    Ok((a, b))
}

fn non_negative_seconds(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && (0.0..=600.0).contains(&v) => Ok(v),
        _ => Err(format!("\"{s}\" is not a time in seconds in [0, 600]")),
    }
}

fn positive_rate(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("\"{s}\" is not a positive frame rate")),
    }
}
