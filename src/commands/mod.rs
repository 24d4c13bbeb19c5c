//! The CLI's commands. `main.rs` parses and dispatches; each command lives in its own file.

pub mod baseline;
pub mod bench;
pub mod compare;
pub mod diff;
pub mod info;
pub mod particles;
pub mod probe;
pub mod render;
pub mod sweep;
pub mod tune;
pub mod view;

use std::path::Path;

use smokeshadow_core::scene::Scene;
use smokeshadow_core::shadow::{ParamValue, SplatMode, TechniqueParams};

/// `--particles N`, flattened into every command that loads a scene.
#[derive(Clone, Copy, Debug, Default, clap::Args)]
pub struct ParticlesArg {
    /// Run the scene with N particles (1..=4000000): every radius times (N0/N)^(1/3), τ kept, so
    /// the plume keeps its optical depth and, up to a thinner fringe, its silhouette (see
    /// "Scaling the particle count" in scenes/README.md).
    #[arg(long, value_name = "N", value_parser = parse_particles, allow_negative_numbers = true)]
    pub particles: Option<u32>,
}

/// Parses a `--particles` count: an integer in 1..=[`crate::scene::LIMITS`]`.max_particles`.
pub fn parse_particles(s: &str) -> Result<u32, String> {
    let max = smokeshadow_core::scene::LIMITS.max_particles;
    let n: u64 = s
        .trim()
        .replace('_', "")
        .parse()
        .map_err(|_| format!("\"{s}\" is not a particle count (a whole number, 1..={max})"))?;
    match u32::try_from(n) {
        Ok(n) if (1..=max).contains(&n) => Ok(n),
        _ => Err(format!("{n} particles is out of range: allowed 1..={max}")),
    }
}

/// The scene-loading path every command shares: an embedded scene's name or a file path (the
/// embedded thesis scene when `None`), rescaled to `--particles` when given.
pub fn load_scene(arg: Option<&Path>, particles: ParticlesArg) -> anyhow::Result<Scene> {
    let scene = crate::particles::open_scene(arg)?;
    Ok(match particles.particles {
        Some(n) => scene.with_particles(n)?,
        None => scene,
    })
}

/// `--params FILE|paper` and `--param KEY=VALUE`, flattened into every command that renders
/// with technique parameters.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct ParamArgs {
    /// A set of technique parameters over the scene's `[shadow.params]`: a parameter file
    /// (`[params]` KEY = VALUE, as `smokeshadow tune` writes), or `paper` for the papers'
    /// values (`smokeshadow info` lists them); `--param` overrides it.
    #[arg(long = "params", id = "param_set", value_name = "FILE|paper",
          value_parser = crate::tune::ParamSet::parse)]
    pub set: Option<crate::tune::ParamSet>,
    /// A technique parameter, KEY=VALUE (repeatable; over the scene's `[shadow.params]`), e.g.
    /// `--param dom_layer_growth=2` or `--param osm_interp=cubic`. `smokeshadow info` lists
    /// every key with its range or choices.
    #[arg(long = "param", value_name = "KEY=VALUE", value_parser = smokeshadow_core::shadow::parse_param,
          allow_negative_numbers = true)]
    pub params: Vec<(String, ParamValue)>,
}

impl ParamArgs {
    /// The parameters given: the `--params` set's, then each `--param` (all already checked).
    pub fn all(&self) -> impl Iterator<Item = &(String, ParamValue)> {
        self.set.iter().flat_map(|s| &s.0).chain(&self.params)
    }

    /// Sets the parameters in `scene`'s `[shadow.params]`, for commands that build every
    /// technique they run from the scene's settings.
    pub fn apply(&self, scene: &mut Scene) {
        for (key, value) in self.all() {
            scene.shadow.params.insert(key.clone(), value.clone());
        }
    }
}

/// Options shared by every command that renders a scene with a technique.
#[derive(Clone, Debug, clap::Args)]
pub struct TechniqueArgs {
    /// Shadow technique (see `smokeshadow info` for the list).
    #[arg(long, short = 't', default_value = "osm")]
    pub technique: String,
    /// Channel budget: render-target components, 1..=32 (`osm`, `dom`: up to 128 in several
    /// passes; `has`: batches, up to 240).
    #[arg(long, short = 'c', default_value_t = 24, allow_negative_numbers = true)]
    pub channels: u32,
    /// Shadow-map resolution in pixels (default: the scene's `shadow.resolution_px`).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=8192))]
    pub shadow_res: Option<u32>,
    /// How layered techniques place a particle's optical depth along the light ray (default:
    /// the scene's `shadow.splat`: segment, the reference's model, unless set; point is the
    /// thesis').
    #[arg(long, value_enum)]
    pub splat: Option<SplatMode>,
    /// How the lighting tests the opaque occluders (default: the scene's `shadow.occluders`):
    /// exact, as the reference does, or from a filtered depth map, as an engine would.
    #[arg(long, value_enum)]
    pub occluders: Option<smokeshadow_core::scene::OccluderMode>,
    #[command(flatten)]
    pub params: ParamArgs,
}

impl TechniqueArgs {
    /// The validated technique configuration for `scene`.
    pub fn config(
        &self,
        scene: &smokeshadow_core::scene::Scene,
    ) -> anyhow::Result<smokeshadow_core::render::TechniqueConfig> {
        let entry = smokeshadow_core::shadow::find(&self.technique)?;
        smokeshadow_core::shadow::check_channels(entry, self.channels)?;
        let mut params = TechniqueParams {
            resolution_px: self.shadow_res.unwrap_or(scene.shadow.resolution_px),
            splat: self.splat.unwrap_or(scene.shadow.splat),
            occluders: self.occluders.unwrap_or(scene.shadow.occluders),
            ..scene.shadow.params(self.channels)
        };
        for (key, value) in self.params.all() {
            smokeshadow_core::shadow::set_param(&mut params, key, value)?;
        }
        Ok(smokeshadow_core::render::TechniqueConfig {
            name: entry.name.to_owned(),
            params,
        })
    }
}

/// An image size given as `WxH`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Size {
    pub width: u32,
    pub height: u32,
}

impl std::str::FromStr for Size {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let max = smokeshadow_core::scene::LIMITS.max_size_px;
        let (w, h) = s
            .split_once(['x', 'X'])
            .ok_or_else(|| format!("\"{s}\" is not WIDTHxHEIGHT (e.g. 1024x768)"))?;
        let parse = |v: &str| -> Result<u32, String> {
            let n: u32 = v
                .trim()
                .parse()
                .map_err(|_| format!("\"{s}\" is not WIDTHxHEIGHT (e.g. 1024x768)"))?;
            if (1..=max).contains(&n) {
                Ok(n)
            } else {
                Err(format!(
                    "size {n} in \"{s}\" is out of range: allowed 1..={max}"
                ))
            }
        };
        Ok(Self {
            width: parse(w)?,
            height: parse(h)?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::{Size, parse_particles};

    #[test]
    fn particle_counts_parse_and_reject_out_of_range() {
        assert_eq!(parse_particles("65536"), Ok(65536));
        assert_eq!(parse_particles("1_000_000"), Ok(1_000_000));
        assert!(parse_particles("0").unwrap_err().contains("1..=4000000"));
        assert!(
            parse_particles("4000001")
                .unwrap_err()
                .contains("out of range")
        );
        assert!(
            parse_particles("99999999999")
                .unwrap_err()
                .contains("out of range")
        );
        assert!(
            parse_particles("many")
                .unwrap_err()
                .contains("not a particle count")
        );
        assert!(
            parse_particles("-5")
                .unwrap_err()
                .contains("not a particle count")
        );
    }

    #[test]
    fn sizes_parse_and_reject_out_of_range() {
        assert_eq!(
            "640x480".parse::<Size>(),
            Ok(Size {
                width: 640,
                height: 480
            })
        );
        assert!(
            "0x480"
                .parse::<Size>()
                .unwrap_err()
                .contains("out of range")
        );
        assert!("9000x10".parse::<Size>().unwrap_err().contains("1..=8192"));
        assert!("640".parse::<Size>().unwrap_err().contains("WIDTHxHEIGHT"));
    }
}
