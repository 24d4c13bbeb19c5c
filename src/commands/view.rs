//! `smokeshadow view [SCENE]`: the interactive viewer ([`crate::viewer`]).

use std::path::PathBuf;

use crate::gpu::AdapterPreference;

#[derive(Clone, Debug, clap::Args)]
pub struct ViewArgs {
    /// Scene file (TOML), or the name of an embedded scene (`smokeshadow info` lists them); the
    /// embedded thesis scene when omitted.
    pub scene: Option<PathBuf>,
    // `--particles N`: the scene opens at N particles (the file field still names the file,
    // which loads at its own count).
    #[command(flatten)]
    pub particles: super::ParticlesArg,
}

pub fn run(args: &ViewArgs, adapter: &AdapterPreference) -> anyhow::Result<()> {
    crate::viewer::run(
        args.scene.clone(),
        args.particles.particles,
        adapter.clone(),
    )
}
