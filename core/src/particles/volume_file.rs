//! A bare volume file (`.vdb`) as a scene: its grid placed, framed and lit as a bare particle
//! file is, its densities scaled to a visible optical depth.

use std::path::Path;

use crate::files::{Files, Folder};

/// Whether `path` names a volume file (`.vdb`) rather than a scene or particle file.
pub fn is_volume_file(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("vdb"))
}

/// The optical depth a bare volume file's smoke is given across half its size, at its mean
/// non-zero density (its `density_scale_per_m`: a file's densities have no unit).
pub const BARE_FILE_OPTICAL_DEPTH: f64 = 3.0;

/// A scene for a bare volume file (`smokeshadow render smoke.vdb`, the viewer's Open): its
/// `density` grid placed by the file's transform, framed like a bare particle file
/// ([`super::frame_bounds`]), its density scaled so that half the smoke's size at its
/// mean non-zero density is [`BARE_FILE_OPTICAL_DEPTH`] deep.
pub fn scene_for_volume_file(path: &Path, files: &Files) -> anyhow::Result<crate::scene::Scene> {
    let mut spec = crate::medium::scene::VolumeSpec {
        file: path.to_string_lossy().into_owned(),
        folder: Folder::new("", files.clone()),
        ..Default::default()
    };
    let grid = spec.file_grid(1.0)?;
    let Some((lo, hi)) = grid.world_bounds() else {
        anyhow::bail!(
            "volume file {}: grid {:?} has no active voxels: there is no smoke to frame",
            path.display(),
            spec.grid
        );
    };
    let size = (hi - lo).max_element();
    let non_zero: Vec<f64> = grid
        .values
        .iter()
        .filter(|v| **v > 0.0)
        .map(|v| f64::from(*v))
        .collect();
    let mean = non_zero.iter().sum::<f64>() / non_zero.len().max(1) as f64;
    if !(mean > 0.0 && size > 0.0) {
        anyhow::bail!(
            "volume file {}: grid {:?} holds no density above 0: there is no smoke to render",
            path.display(),
            spec.grid
        );
    }
    spec.density_scale_per_m = (BARE_FILE_OPTICAL_DEPTH / (mean * 0.5 * size)) as f32;
    let mut scene = crate::scene::Scene::thesis_plume();
    super::frame_bounds(&mut scene, lo.as_vec3(), hi.as_vec3())
        .map_err(|m| anyhow::anyhow!("volume file {}: {m}", path.display()))?;
    scene.volume = Some(spec);
    scene.name = path
        .file_stem()
        .map_or("volume".into(), |s| s.to_string_lossy().into_owned());
    scene.description = format!("density volume of {}", path.display());
    scene
        .validate()
        .map_err(|m| anyhow::anyhow!("volume file {}: {m}", path.display()))?;
    Ok(scene)
}
