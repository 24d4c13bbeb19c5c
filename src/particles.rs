//! Particle files and a scene's particles ([`smokeshadow_core::particles`]), with what only the
//! apps do: a progress bar over a long simulation, and files written to the disk.

use std::path::Path;

pub use smokeshadow_core::particles::*;
use smokeshadow_core::sim::Particle;

use smokeshadow_core::files::Files;
use smokeshadow_core::scene::Scene;

/// A scene argument ([`smokeshadow_core::particles::open_scene`]) on the host's file system.
pub fn open_scene(arg: Option<&Path>) -> anyhow::Result<Scene> {
    smokeshadow_core::particles::open_scene(arg, &Files::host())
}

/// The particles of `scene`'s frame ([`frame_particles`]), a long simulation shown on a
/// progress bar.
pub fn scene_particles(scene: &Scene) -> Result<Vec<Particle>, ParticleFileError> {
    frame_particles(scene, crate::progress::simulate)
}

/// Writes particles to `path` in `format` (default: the extension's), atomically: a temporary
/// file renamed into place, so a failed write leaves nothing half-written.
pub fn write(
    path: &Path,
    particles: &[Particle],
    format: Option<Format>,
) -> Result<(), ParticleFileError> {
    let format = format.or_else(|| Format::of_path(path)).ok_or_else(|| {
        ParticleFileError::UnknownFormat {
            path: path.to_owned(),
        }
    })?;
    let bytes = encode(particles, format).map_err(|cause| ParticleFileError::Write {
        path: path.to_owned(),
        cause,
    })?;
    crate::output::write_atomic(path, &bytes).map_err(|e| ParticleFileError::Write {
        path: path.to_owned(),
        cause: format!("{e:#}"),
    })
}
