//! `smokeshadow probe`: transmittance at a world point, or along the light ray through it, for a
//! technique and for the `exact` reference, both evaluated by the techniques' own lookup shaders
//! on the GPU ([`crate::render::Renderer::probe`]).

use crate::Wait;
use std::path::PathBuf;

use glam::Vec3;
use serde::Serialize;

use super::{ParticlesArg, TechniqueArgs};
use smokeshadow_core::gpu::{AdapterPreference, Gpu};
use smokeshadow_core::render::{OUTPUT_FORMAT, Renderer, TechniqueConfig};
use smokeshadow_core::shadow::LightSpace;

#[derive(Clone, Debug, clap::Args)]
pub struct ProbeArgs {
    /// Scene file (TOML), or the name of an embedded scene (`smokeshadow info` lists them); the
    /// embedded thesis scene when omitted.
    pub scene: Option<PathBuf>,
    #[command(flatten)]
    pub particles: ParticlesArg,
    #[command(flatten)]
    pub technique: TechniqueArgs,
    /// World point X,Y,Z in metres.
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    pub at: Vec3,
    /// Also print N samples of T along the light ray through the point, spanning the smoke's
    /// light-space depth range.
    #[arg(long, value_parser = clap::value_parser!(u32).range(2..=100_000))]
    pub along_light: Option<u32>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

fn parse_point(s: &str) -> Result<Vec3, String> {
    let parts: Vec<f32> = s
        .split(',')
        .map(|v| v.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("\"{s}\" is not X,Y,Z (three numbers, e.g. 0,2.5,0)"))?;
    match parts[..] {
        [x, y, z] if parts.iter().all(|v| v.is_finite()) => Ok(Vec3::new(x, y, z)),
        _ => Err(format!(
            "\"{s}\" is not X,Y,Z (three numbers, e.g. 0,2.5,0)"
        )),
    }
}

/// One probed point.
#[derive(Debug, Serialize)]
pub struct Sample {
    pub point: [f32; 3],
    /// Distance from the spotlight, metres.
    pub distance_m: f32,
    /// Distance normalised to the smoke's light-space bounds (0 near, 1 far).
    pub depth01: f32,
    pub transmittance: f32,
    pub exact: f32,
    /// The exact transmittance of the particle model at the point itself, on the CPU
    /// ([`crate::shadow::closed_form`]), times a density volume's by its f64 march doubled
    /// until converged: no texels, so `exact - closed_form` is `exact`'s own error.
    pub closed_form: f32,
}

#[derive(Debug, Serialize)]
struct Report<'a> {
    scene: &'a str,
    technique: &'a str,
    channels: u32,
    channels_used: u32,
    shadow_res: u32,
    splat: &'a str,
    light_near_m: f32,
    light_far_m: f32,
    /// `exact`'s self-check at the frame's shaded points: how many were compared and the worst
    /// |ΔT| against the f64 closed form (core/src/render/reference_check.rs).
    reference_check_points: usize,
    reference_check_worst: f64,
    at: Sample,
    along_light: Vec<Sample>,
}

pub fn run(args: &ProbeArgs, adapter: &AdapterPreference) -> anyhow::Result<()> {
    let scene = super::load_scene(args.scene.as_deref(), args.particles)?;
    let technique = args.technique.config(&scene)?;
    let exact = TechniqueConfig {
        name: "exact".to_owned(),
        params: technique.params.clone(),
    };
    let gpu = Gpu::new(adapter).wait()?;
    let particles = crate::particles::scene_particles(&scene)?;
    let (w, h) = (scene.output.width_px, scene.output.height_px);
    let mut renderer = Renderer::new(&gpu, w, h, OUTPUT_FORMAT, &technique).wait()?;
    // The light's depth range encloses a density volume too.
    renderer.load_volume(&gpu, &scene).wait()?;
    let grid = renderer.medium().grid().cloned();
    let light = LightSpace::faces_with(
        &scene.light,
        &particles,
        renderer.medium().bounds(),
        scene.shadow.framing,
    )[0];

    let mut points = vec![args.at];
    if let Some(n) = args.along_light {
        let dir = (args.at - scene.light.position).normalize_or(Vec3::NEG_Y);
        points.extend((0..n).map(|i| {
            let t = light.near_m + (light.far_m - light.near_m) * i as f32 / (n - 1) as f32;
            scene.light.position + dir * t
        }));
    }
    let t_technique = renderer.probe(&gpu, &scene, &particles, &points).wait()?;
    let channels_used = renderer.technique().channels_used();
    renderer.set_technique(&gpu, &exact).wait()?;
    let t_exact = renderer.probe(&gpu, &scene, &particles, &points).wait()?;
    let check =
        smokeshadow_core::render::reference_check::verify(&mut renderer, &gpu, &scene, &particles)
            .wait()?;

    let mut samples = points
        .iter()
        .zip(t_technique.iter().zip(&t_exact))
        .map(|(p, (&t, &e))| {
            let distance_m = p.distance(scene.light.position);
            Sample {
                point: p.to_array(),
                distance_m,
                depth01: (distance_m - light.near_m) / (light.far_m - light.near_m),
                transmittance: t,
                exact: e,
                closed_form: smokeshadow_core::render::reference_check::mirror_transmittance(
                    scene.light.position,
                    *p,
                    &particles,
                    grid.as_deref(),
                ) as f32,
            }
        });
    let at = samples.next().expect("the probed point is always first");
    let report = Report {
        scene: &scene.name,
        technique: &technique.name,
        channels: technique.params.channels,
        channels_used,
        shadow_res: technique.params.resolution_px,
        splat: technique.params.splat.name(),
        light_near_m: light.near_m,
        light_far_m: light.far_m,
        reference_check_points: check.points,
        reference_check_worst: check.worst_difference,
        at,
        along_light: samples.collect(),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "{} / {} at {} channels ({} used), {} splat, shadow map {}²; smoke between {:.3} and {:.3} m from the light",
        report.scene,
        report.technique,
        report.channels,
        report.channels_used,
        report.splat,
        report.shadow_res,
        report.light_near_m,
        report.light_far_m
    );
    let header = format!(
        "{:>9} {:>8} {:>12} {:>12} {:>10} {:>12}",
        "dist m", "depth01", report.technique, "exact", "diff", "closed form"
    );
    let row = |s: &Sample| {
        format!(
            "{:>9.3} {:>8.3} {:>12.6} {:>12.6} {:>+10.6} {:>12.6}",
            s.distance_m,
            s.depth01,
            s.transmittance,
            s.exact,
            s.transmittance - s.exact,
            s.closed_form
        )
    };
    println!("{check}");
    let p = report.at.point;
    println!("T at ({}, {}, {}):", p[0], p[1], p[2]);
    println!("{header}");
    println!("{}", row(&report.at));
    if !report.along_light.is_empty() {
        println!("T along the light ray through it:");
        println!("{header}");
        for s in &report.along_light {
            println!("{}", row(s));
        }
    }
    Ok(())
}
