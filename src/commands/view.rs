//! `smokeshadow view [SCENE]`: the interactive viewer ([`crate::viewer`]).

use std::path::PathBuf;

use smokeshadow_core::gpu::AdapterPreference;

#[derive(Clone, Debug, clap::Args)]
pub struct ViewArgs {
    /// Scene file (TOML), or the name of an embedded scene (`smokeshadow info` lists them); the
    /// embedded thesis scene when omitted.
    pub scene: Option<PathBuf>,
    // `--particles N`: the scene opens at N particles (the file field still names the file,
    // which loads at its own count).
    #[command(flatten)]
    pub particles: super::ParticlesArg,
    /// Play the frames `sweep --animate START..END` renders (scene time, seconds), one a UI
    /// frame, looping; the time bar covers the span.
    #[arg(long, value_name = "START..END")]
    pub animate: Option<String>,
    /// Frames per second of `--animate` (default: a particle or volume sequence's own rate, else 30).
    #[arg(long, requires = "animate")]
    pub fps: Option<f32>,
}

pub fn run(args: &ViewArgs, adapter: &AdapterPreference) -> anyhow::Result<()> {
    crate::viewer::run(
        args.scene.clone(),
        args.particles.particles,
        args.animate.clone().map(|range| (range, args.fps)),
        adapter.clone(),
    )
}
