//! `smokeshadow baseline --check | --bless`: the committed 24-channel baselines
//! ([`crate::baseline`]). `--check` exits 1 when any baseline fails; `--bless` is the only way
//! the files change.

use crate::Wait;
use std::path::PathBuf;
use std::process::ExitCode;

use crate::baseline::{self, criterion};
use smokeshadow_core::gpu::{AdapterPreference, Gpu};

#[derive(Clone, Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("mode").required(true).args(["check", "bless"])))]
pub struct BaselineArgs {
    /// Re-render every selected baseline and compare it with the committed image.
    #[arg(long)]
    pub check: bool,
    /// Render the selected baselines and (over)write them and their .json sidecars.
    #[arg(long)]
    pub bless: bool,
    /// Only this scene (repeatable; default: the committed scenes). Besides the committed
    /// scenes, your own: a scene file, an embedded scene's name or a particle file, whose
    /// baselines go to `--dir/<its name>/` (bless them first).
    #[arg(long = "scene")]
    pub scenes: Vec<String>,
    /// Only this technique (repeatable; default: all).
    #[arg(long = "technique")]
    pub techniques: Vec<String>,
    /// Folder holding `<scene>/<technique>.png`.
    #[arg(long, default_value = "baselines")]
    pub dir: PathBuf,
    /// Where `--check` writes the actual image and difference maps of a failing baseline.
    #[arg(long, default_value = "test-output/baselines")]
    pub out: PathBuf,
    // `--particles N` is refused: baselines are the committed scenes at their own counts.
    #[command(flatten)]
    pub particles: super::ParticlesArg,
}

pub fn run(args: &BaselineArgs, adapter: &AdapterPreference) -> anyhow::Result<ExitCode> {
    if let Some(n) = args.particles.particles {
        // A rescaled scene is not the scene a baseline was rendered from: --check would only
        // report it stale, --bless would overwrite the thesis' images with another plume.
        anyhow::bail!(
            "--particles {n} does not apply to baseline: the baselines are the committed scenes ({}) at their own particle counts",
            smokeshadow_core::scene::BASELINE_SCENES.join(", ")
        );
    }
    let baselines = baseline::select(&args.dir, &args.scenes, &args.techniques)?;
    // Baselines are lavapipe's: `auto` means the CPU adapter here, and a hardware adapter named
    // explicitly is refused with the reason (`baseline::require_software_adapter`).
    let adapter = match adapter {
        AdapterPreference::Auto => &AdapterPreference::Cpu,
        other => other,
    };
    let gpu = Gpu::new(adapter).wait()?;
    baseline::require_software_adapter(&gpu)?;
    if args.bless {
        for path in baseline::bless(&gpu, &baselines)? {
            println!("blessed {}", path.display());
        }
        return Ok(ExitCode::SUCCESS);
    }
    println!(
        "checking {} baselines in {} on {}",
        baselines.len(),
        args.dir.display(),
        gpu.describe()
    );
    println!(
        "pass: at most {:.1}% of pixels off by more than 1/255, and every HDR {}x{} block mean \
         within {:.1e} relative (FLIP is reported, not judged)",
        100.0 * criterion::MAX_SHARE_BEYOND_ONE_STEP,
        criterion::BLOCK_PX,
        criterion::BLOCK_PX,
        criterion::MAX_BLOCK_RELATIVE
    );
    println!(
        "{:<14} {:<10} {:>10} {:>10} {:>10}  result",
        "scene", "technique", ">1/255 px", "HDR block", "FLIP mean"
    );
    let rows = baseline::check(&gpu, &baselines, &args.out)?;
    let mut failed = 0;
    for row in &rows {
        let (share, block) = row
            .scores
            .map(|s| {
                (
                    format!("{:.3}%", 100.0 * s.share_beyond_one_step),
                    format!("{:.2e}", s.block_relative),
                )
            })
            .unwrap_or_else(|| ("-".into(), "-".into()));
        let flip = row
            .comparison
            .as_ref()
            .map_or_else(|| "-".into(), |c| format!("{:.5}", c.metrics.flip_mean));
        let result = match &row.failure {
            None => "pass".to_owned(),
            Some(why) => {
                failed += 1;
                format!("FAIL: {why}")
            }
        };
        println!(
            "{:<14} {:<10} {:>10} {:>10} {:>10}  {result}",
            row.baseline.scene, row.baseline.technique, share, block, flip
        );
    }
    if failed > 0 {
        println!("{failed} of {} baselines failed", rows.len());
        Ok(ExitCode::from(1))
    } else {
        println!("all {} baselines pass", rows.len());
        Ok(ExitCode::SUCCESS)
    }
}
