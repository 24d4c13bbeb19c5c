//! `smokeshadow compare [SCENE] -o DIR`: the thesis' accuracy comparison for one scene, as
//! images, `metrics.csv` and `index.html` ([`crate::compare`]).

use crate::Wait;
use std::path::PathBuf;

use crate::compare::{self, CompareOptions};
use smokeshadow_core::gpu::{AdapterPreference, Gpu};
use smokeshadow_core::shadow::SplatMode;

#[derive(Clone, Debug, clap::Args)]
pub struct CompareArgs {
    /// Scene file (TOML), or the name of an embedded scene (`smokeshadow info` lists them); the
    /// embedded thesis scene when omitted.
    pub scene: Option<PathBuf>,
    #[command(flatten)]
    pub particles: super::ParticlesArg,
    /// Output folder (created if missing).
    #[arg(long, short = 'o')]
    pub output: PathBuf,
    /// Techniques, comma-separated, in display order (`all`: every contender).
    #[arg(
        long,
        value_delimiter = ',',
        default_values_t = smokeshadow_core::shadow::default_compare()
    )]
    pub techniques: Vec<String>,
    /// Budgets, comma-separated; the first is each technique's baseline.
    #[arg(long, value_delimiter = ',', default_value = "24,16,8,6")]
    pub channels: Vec<u32>,
    /// How the layered techniques place optical depth (default: the scene's).
    #[arg(long, value_enum)]
    pub splat: Option<SplatMode>,
    #[command(flatten)]
    pub params: super::ParamArgs,
    /// Output size as WIDTHxHEIGHT (default: the scene's).
    #[arg(long)]
    pub size: Option<super::Size>,
}

pub fn run(args: &CompareArgs, adapter: &AdapterPreference) -> anyhow::Result<()> {
    let mut scene = super::load_scene(args.scene.as_deref(), args.particles)?;
    args.params.apply(&mut scene);
    if let Some(size) = args.size {
        scene.output.width_px = size.width;
        scene.output.height_px = size.height;
    }
    // A technique that cannot shadow the scene's smoke (`has` a density volume, `srm`
    // particles) is noted and left out, as the sweep does.
    let smoke = (
        scene.volume.is_some(),
        crate::particles::count(&scene) as usize,
    );
    let mut techniques = Vec::new();
    for name in smokeshadow_core::shadow::expand_all(&args.techniques) {
        match smokeshadow_core::shadow::find(&name)?.refusal(smoke.0, smoke.1) {
            Some(refusal) => println!("skipped {name}: {refusal}"),
            None => techniques.push(name),
        }
    }
    if techniques.is_empty() {
        anyhow::bail!("no technique given can shadow {}'s smoke", scene.name);
    }
    let options = CompareOptions {
        techniques,
        budgets: args.channels.clone(),
        splat: args.splat.unwrap_or(scene.shadow.splat),
    };
    let gpu = Gpu::new(adapter).wait()?;
    let report = compare::run(&gpu, &scene, &options, &args.output)?;
    println!(
        "wrote {} files to {} (open index.html)",
        report.files.len(),
        args.output.display()
    );
    println!(
        "{:<10} {:>8} {:>12} {:>14} {:>14}",
        "technique", "channels", "bytes", "FLIP vs exact", "FLIP vs own"
    );
    for c in &report.cells {
        println!(
            "{:<10} {:>8} {:>12} {:>14.5} {:>14}",
            c.technique,
            c.channels,
            c.bytes,
            c.vs_exact.metrics.flip_mean,
            c.vs_baseline
                .as_ref()
                .map_or("-".to_owned(), |p| format!("{:.5}", p.metrics.flip_mean))
        );
    }
    Ok(())
}
