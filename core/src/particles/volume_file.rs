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
    let spec = crate::medium::scene::VolumeSpec {
        file: path.to_string_lossy().into_owned(),
        folder: Folder::new("", files.clone()),
        ..Default::default()
    };
    let smoke = Smoke::of(&spec, path)?;
    let description = format!("density volume of {}", path.display());
    bare_volume_scene(path, spec, &smoke, description)
}

/// The scene of a bare volume sequence (`pattern`, its `frames` in `files`) at `frame`: framed
/// and scaled as one bare volume file is ([`scene_for_volume_file`]), over every frame's smoke
/// together, so that the camera, the light and the density scale hold still from frame to
/// frame ([`show_volume_frame`]).
pub fn scene_for_volume_sequence(
    pattern: &str,
    frames: &[i64],
    frame: i64,
    files: &Files,
) -> anyhow::Result<crate::scene::Scene> {
    let mut all: Option<Smoke> = None;
    for &f in frames {
        let name = super::frame_name(pattern, f);
        let one = crate::medium::scene::VolumeSpec {
            file: name.clone(),
            folder: Folder::new("", files.clone()),
            ..Default::default()
        };
        let one = Smoke::of(&one, Path::new(&name))?;
        all = Some(match all {
            None => one,
            Some(a) => Smoke {
                lo: a.lo.min(one.lo),
                hi: a.hi.max(one.hi),
                density_sum: a.density_sum + one.density_sum,
                non_zero: a.non_zero + one.non_zero,
            },
        });
    }
    let smoke = all.ok_or_else(|| anyhow::anyhow!("volume sequence {pattern}: no frames"))?;
    let spec = crate::medium::scene::VolumeSpec {
        file: pattern.to_owned(),
        folder: Folder::new("", files.clone()),
        ..Default::default()
    };
    let mut scene = bare_volume_scene(Path::new(pattern), spec, &smoke, String::new())?;
    show_volume_frame(&mut scene, frame);
    Ok(scene)
}

/// Moves a volume sequence's scene ([`scene_for_volume_sequence`]) to `frame`: the frame its
/// time shows.
pub fn show_volume_frame(scene: &mut crate::scene::Scene, frame: i64) {
    let duration = scene.sim.duration_s;
    if let Some(spec) = &mut scene.volume {
        spec.frame_at_zero = frame - super::sequence_frame(0, spec.frame_rate_hz, duration);
        scene.description = format!(
            "density volume of {}, frame {frame}",
            super::frame_name(&spec.file, frame)
        );
    }
}

/// What a bare volume's framing and density scale are made of: its grid's world box and its
/// non-zero densities' sum and count.
struct Smoke {
    lo: glam::DVec3,
    hi: glam::DVec3,
    density_sum: f64,
    non_zero: usize,
}

impl Smoke {
    /// Of `spec`'s file (named `path` in errors); an error where there is no smoke.
    fn of(spec: &crate::medium::scene::VolumeSpec, path: &Path) -> anyhow::Result<Self> {
        let grid = spec.file_grid(1.0)?;
        let Some((lo, hi)) = grid.world_bounds() else {
            anyhow::bail!(
                "volume file {}: grid {:?} has no active voxels: there is no smoke to frame",
                path.display(),
                spec.grid
            );
        };
        let (density_sum, non_zero) = grid
            .values
            .iter()
            .filter(|v| **v > 0.0)
            .fold((0.0, 0), |(sum, n), v| (sum + f64::from(*v), n + 1));
        let smoke = Self {
            lo,
            hi,
            density_sum,
            non_zero,
        };
        if !(smoke.density_sum > 0.0 && smoke.size() > 0.0) {
            anyhow::bail!(
                "volume file {}: grid {:?} holds no density above 0: there is no smoke to render",
                path.display(),
                spec.grid
            );
        }
        Ok(smoke)
    }

    fn size(&self) -> f64 {
        (self.hi - self.lo).max_element()
    }
}

/// The thesis scene framed on `smoke`, with `spec` (its grid) in place of the emitters, its
/// density scaled to [`BARE_FILE_OPTICAL_DEPTH`], named after `path`.
fn bare_volume_scene(
    path: &Path,
    mut spec: crate::medium::scene::VolumeSpec,
    smoke: &Smoke,
    description: String,
) -> anyhow::Result<crate::scene::Scene> {
    let mean = smoke.density_sum / smoke.non_zero.max(1) as f64;
    spec.density_scale_per_m = (BARE_FILE_OPTICAL_DEPTH / (mean * 0.5 * smoke.size())) as f32;
    let mut scene = crate::scene::Scene::thesis_plume();
    super::frame_bounds(&mut scene, smoke.lo.as_vec3(), smoke.hi.as_vec3())
        .map_err(|m| anyhow::anyhow!("volume file {}: {m}", path.display()))?;
    scene.volume = Some(spec);
    scene.name = path
        .file_stem()
        .map_or("volume".into(), |s| s.to_string_lossy().into_owned());
    scene.description = description;
    scene
        .validate()
        .map_err(|m| anyhow::anyhow!("volume file {}: {m}", path.display()))?;
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two frames of one smoke: the sequence's scene reads the frame its time shows, steps to
    /// the other, and is framed and scaled as the one file alone is (the frames' union is it).
    #[test]
    fn a_volume_sequence_shows_each_frame_framed_as_one_file() {
        let smoke = crate::medium::scene::EMBEDDED_FILES[0].1.to_vec();
        let files = Files::memory([
            ("smoke.0001.vdb".into(), smoke.clone()),
            ("smoke.0002.vdb".into(), smoke.clone()),
            ("one.vdb".into(), smoke),
        ]);
        let mut scene =
            super::super::scene_for_sequence("smoke.%04d.vdb", &[1, 2], 1, &files).unwrap();
        let one = scene_for_volume_file(Path::new("one.vdb"), &files).unwrap();
        let at_time = |scene: &crate::scene::Scene| {
            let volume = scene.volume.as_ref().unwrap();
            volume.at_time(scene.sim.duration_s).path()
        };
        assert_eq!(at_time(&scene), Path::new("smoke.0001.vdb"));
        super::super::show_sequence_frame(&mut scene, 2);
        assert_eq!(at_time(&scene), Path::new("smoke.0002.vdb"));
        assert!(scene.description.ends_with("smoke.0002.vdb, frame 2"));
        let (a, b) = (scene.volume.as_ref().unwrap(), one.volume.as_ref().unwrap());
        assert_eq!(a.density_scale_per_m, b.density_scale_per_m);
        assert_eq!(scene.camera.position, one.camera.position);
        assert_eq!(scene.light.position, one.light.position);
        // A frame that is not there is named.
        let missing =
            super::super::scene_for_sequence("smoke.%04d.vdb", &[1, 3], 1, &files).unwrap_err();
        assert!(
            format!("{missing:#}").contains("smoke.0003.vdb"),
            "{missing:#}"
        );
    }
}
