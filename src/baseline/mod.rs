//! Committed reference images and the regression check against them (thesis 4.2.2.2: every
//! technique's 24-channel image is its baseline; wgpu's and vello's golden-image tests).
//!
//! `baselines/<scene>/<technique>.png` is each registered technique at 24 channels (DOM: one
//! depth channel and 23 layers, FOM: 11 harmonics, HAS: 24 slices) on each embedded scene, `exact`
//! at a high shadow resolution; `<technique>.blocks.exr` holds its HDR frame averaged over 16x16
//! blocks, and `<technique>.json` says what it was rendered from. [`check`] re-renders and
//! applies the CPU-independent [`criterion`]; [`bless`] is the only way the files change. A
//! missing, mis-sized or stale baseline is a failure, never silently recreated.
//!
//! Baselines are lavapipe's: a hardware GPU's shader math (its `exp`, its texture filtering, its
//! blending precision) moves pixels far more than another CPU does, so `check` refuses to compare
//! a hardware adapter's renders with them (see [`require_software_adapter`]).

use crate::Wait;
pub mod criterion;

use std::path::{Path, PathBuf};

use anyhow::Context;
use serde::{Deserialize, Serialize};

use crate::diff::{self, Comparison};
use criterion::{HdrBlocks, Scores};
use smokeshadow_core::gpu::Gpu;
use smokeshadow_core::render::{RenderOptions, TechniqueConfig, render_offscreen};
use smokeshadow_core::scene::{self, Scene};
use smokeshadow_core::shadow::{self, TechniqueParams};

/// The budget of every baseline (the thesis' baselines).
pub const BASELINE_CHANNELS: u32 = 24;
/// How a baseline of `technique` is rendered for `scene`.
pub fn config(technique: &str, scene: &Scene) -> TechniqueConfig {
    let params: TechniqueParams = scene.shadow.params(BASELINE_CHANNELS);
    TechniqueConfig {
        name: technique.to_owned(),
        params,
    }
}

/// What a baseline was rendered from, written beside it as `<technique>.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sidecar {
    pub tool_version: String,
    pub scene: String,
    /// [`Scene::content_hash`] of the scene rendered.
    pub scene_sha256: String,
    pub technique: String,
    pub params: TechniqueParams,
    pub width_px: u32,
    pub height_px: u32,
    pub adapter: String,
    pub driver: String,
    /// RFC 3339, UTC.
    pub date: String,
}

/// One baseline: which scene and technique, and where its files are.
#[derive(Clone, Debug)]
pub struct Baseline {
    /// The scene's name: the folder under the baselines' folder.
    pub scene: String,
    /// The scene rendered: an embedded baseline scene, or a user's scene file or particle file
    /// given with `--scene`.
    pub source: Scene,
    /// How `--scene` names it (and `--dir` when not the committed folder), for the hints that
    /// say how to bless it.
    pub select_args: String,
    pub technique: String,
    pub png: PathBuf,
    /// The HDR frame's block means ([`criterion::HdrBlocks`]).
    pub blocks: PathBuf,
    pub sidecar: PathBuf,
}

/// The baselines under `dir` for the given scene and technique names (all when empty).
pub fn select(
    dir: &Path,
    scenes: &[String],
    techniques: &[String],
) -> anyhow::Result<Vec<Baseline>> {
    for t in techniques {
        shadow::find(t)?;
    }
    // The committed scenes by default; a `--scene` that is not one of them is the user's own
    // (a scene file, another embedded scene, or a particle file), with baselines of its own.
    let names: Vec<String> = match scenes.is_empty() {
        true => scene::BASELINE_SCENES
            .iter()
            .map(|n| n.to_string())
            .collect(),
        false => scenes.to_vec(),
    };
    let sources: Vec<(String, Scene)> = names
        .iter()
        .map(|s| {
            let scene = match scene::BASELINE_SCENES.contains(&s.as_str()) {
                true => Ok(Scene::embedded(s).expect("baseline scenes are embedded")),
                false => crate::particles::open_scene(Some(Path::new(s))).with_context(|| {
                    format!(
                        "scene \"{s}\" is not a committed baseline scene ({}) nor a scene or particle file that opens",
                        scene::BASELINE_SCENES.join(", ")
                    )
                }),
            }?;
            let dir_arg = match dir == Path::new("baselines") {
                true => String::new(),
                false => format!(" --dir {}", dir.display()),
            };
            Ok((format!("--scene {s}{dir_arg}"), scene))
        })
        .collect::<anyhow::Result<_>>()?;
    let mut out = Vec::new();
    for (select_args, source) in sources {
        let scene_name = source.name.clone();
        let smoke = (
            source.volume.is_some(),
            crate::particles::count(&source) as usize,
        );
        for entry in shadow::REGISTRY {
            if !techniques.is_empty() && !techniques.iter().any(|t| t == entry.name) {
                continue;
            }
            // A technique that cannot shadow the scene's smoke has no baseline of it (asked
            // for by name, it is refused in one line).
            if let Some(refusal) = entry.refusal(smoke.0, smoke.1) {
                if techniques.is_empty() {
                    continue;
                }
                return Err(refusal.into());
            }
            let folder = dir.join(&scene_name);
            out.push(Baseline {
                scene: scene_name.clone(),
                source: source.clone(),
                select_args: select_args.clone(),
                technique: entry.name.to_owned(),
                png: folder.join(format!("{}.png", entry.name)),
                blocks: folder.join(format!("{}.blocks.exr", entry.name)),
                sidecar: folder.join(format!("{}.json", entry.name)),
            });
        }
    }
    Ok(out)
}

/// A baseline's configuration, rendered.
struct Rendered {
    scene: Scene,
    config: TechniqueConfig,
    /// The tone-mapped frame.
    image: image::RgbImage,
    blocks: HdrBlocks,
}

/// Renders a baseline's configuration: the tone-mapped frame and the HDR frame's block means.
fn render(gpu: &Gpu, baseline: &Baseline) -> anyhow::Result<Rendered> {
    let scene = baseline.source.clone();
    let particles = crate::particles::scene_particles(&scene)?;
    let config = config(&baseline.technique, &scene);
    let frame =
        render_offscreen(gpu, &scene, &particles, &config, &RenderOptions::default()).wait()?;
    Ok(Rendered {
        blocks: HdrBlocks::from_hdr(&frame.hdr),
        image: image::DynamicImage::ImageRgba8(frame.image).into_rgb8(),
        scene,
        config,
    })
}

/// Fails unless `gpu` is a software (CPU) adapter: the baselines are lavapipe renders, and a
/// hardware GPU's shader math differs from it by far more than any tolerance that would still
/// catch a regression (a different `exp`, texture filtering in fixed point, blending at other
/// precisions).
pub fn require_software_adapter(gpu: &Gpu) -> anyhow::Result<()> {
    if gpu.info.device_type == wgpu::DeviceType::Cpu {
        Ok(())
    } else {
        anyhow::bail!(
            "baselines are lavapipe renders and cannot be checked on the hardware adapter {}: \
             run with --adapter cpu (install lavapipe with `apt-get install mesa-vulkan-drivers`)",
            gpu.info.name
        )
    }
}

/// Renders and writes each baseline and its sidecar; returns the PNG paths written.
pub fn bless(gpu: &Gpu, baselines: &[Baseline]) -> anyhow::Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    for b in baselines {
        let Rendered {
            scene,
            config,
            image,
            blocks,
        } = render(gpu, b)?;
        if let Some(folder) = b.png.parent() {
            std::fs::create_dir_all(folder)?;
        }
        crate::output::write_png_rgb_smallest(&b.png, &image)?;
        blocks.save(&b.blocks)?;
        let sidecar = Sidecar {
            tool_version: env!("CARGO_PKG_VERSION").to_owned(),
            scene: b.scene.clone(),
            scene_sha256: scene.content_hash(),
            technique: b.technique.clone(),
            params: config.params,
            width_px: image.width(),
            height_px: image.height(),
            adapter: gpu.info.name.clone(),
            driver: format!("{} {}", gpu.info.driver, gpu.info.driver_info),
            date: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
        };
        crate::output::write_atomic(
            &b.sidecar,
            format!("{}\n", serde_json::to_string_pretty(&sidecar)?).as_bytes(),
        )?;
        written.push(b.png.clone());
    }
    Ok(written)
}

/// The outcome of checking one baseline.
#[derive(Debug)]
pub struct CheckRow {
    pub baseline: Baseline,
    /// The comparison, when both images could be compared (FLIP and the rest, reported only).
    pub comparison: Option<Comparison>,
    /// The criterion's measures, when both images and block files could be compared.
    pub scores: Option<Scores>,
    /// `None`: passed; otherwise why it failed, in one line.
    pub failure: Option<String>,
}

impl CheckRow {
    pub fn passed(&self) -> bool {
        self.failure.is_none()
    }
}

/// Re-renders every baseline and compares it with the committed files by the [`criterion`]. On
/// a failure, the fresh render, the 4x difference and the FLIP map go to `out_dir/<scene>/` as
/// `<technique>-actual.png`, `-diff.png` and `-flip.png`.
pub fn check(gpu: &Gpu, baselines: &[Baseline], out_dir: &Path) -> anyhow::Result<Vec<CheckRow>> {
    require_software_adapter(gpu)?;
    let mut rows = Vec::new();
    for b in baselines {
        let mut row = CheckRow {
            baseline: b.clone(),
            comparison: None,
            scores: None,
            failure: None,
        };
        row.failure = check_one(gpu, b, out_dir, &mut row)?;
        rows.push(row);
    }
    Ok(rows)
}

/// Checks one baseline, filling `row`'s measures; returns why it failed, if it did. Errors are
/// reserved for what stops the whole check (the GPU, the output folder).
fn check_one(
    gpu: &Gpu,
    b: &Baseline,
    out_dir: &Path,
    row: &mut CheckRow,
) -> anyhow::Result<Option<String>> {
    let bless_hint = format!(
        "run `smokeshadow baseline --bless {} --technique {}` if the change is intended",
        b.select_args, b.technique
    );
    if !b.png.is_file() || !b.blocks.is_file() || !b.sidecar.is_file() {
        return Ok(Some(format!(
            "missing baseline {} (or its .blocks.exr or .json); create it with `smokeshadow baseline --bless {} --technique {}`",
            b.png.display(),
            b.select_args,
            b.technique
        )));
    }
    let sidecar: Sidecar = match std::fs::read_to_string(&b.sidecar)
        .map_err(anyhow::Error::from)
        .and_then(|t| serde_json::from_str(&t).map_err(anyhow::Error::from))
    {
        Ok(s) => s,
        Err(err) => {
            return Ok(Some(format!(
                "cannot read {}: {err}; {bless_hint}",
                b.sidecar.display()
            )));
        }
    };
    let actual = render(gpu, b)?;
    if sidecar.scene_sha256 != actual.scene.content_hash() {
        return Ok(Some(format!(
            "the scene {} changed since this baseline was blessed; {bless_hint}",
            b.scene
        )));
    }
    if sidecar.params != actual.config.params {
        return Ok(Some(format!(
            "the baseline was rendered with other technique parameters ({}) than {} uses now; {bless_hint}",
            serde_json::to_string(&sidecar.params)?,
            b.technique
        )));
    }
    let expected = match diff::load_png(&b.png) {
        Ok(image) => image,
        Err(err) => return Ok(Some(format!("{err}; {bless_hint}"))),
    };
    let expected_blocks = match HdrBlocks::load(&b.blocks) {
        Ok(blocks) => blocks,
        Err(err) => return Ok(Some(format!("{err:#}; {bless_hint}"))),
    };
    let comparison = match diff::compare(&expected, &actual.image) {
        Ok(c) => c,
        Err(err) => return Ok(Some(format!("{err}; {bless_hint}"))),
    };
    let Some(scores) = Scores::of(&expected, &actual.image, &expected_blocks, &actual.blocks)
    else {
        return Ok(Some(format!(
            "{} holds {}x{} blocks, the render {}x{}; {bless_hint}",
            b.blocks.display(),
            expected_blocks.width,
            expected_blocks.height,
            actual.blocks.width,
            actual.blocks.height
        )));
    };
    row.scores = Some(scores);
    let failure = scores.failure().map(|why| -> anyhow::Result<String> {
        let folder = out_dir.join(&b.scene);
        std::fs::create_dir_all(&folder)?;
        let stem = folder.join(&b.technique);
        let path = |suffix: &str| PathBuf::from(format!("{}-{suffix}.png", stem.display()));
        crate::output::write_png_rgb(&path("actual"), &actual.image)?;
        crate::output::write_png_rgb(
            &path("diff"),
            &diff::enhanced_difference(&expected, &actual.image, diff::DEFAULT_ENHANCE),
        )?;
        crate::output::write_png_rgb(&path("flip"), &diff::flip_heatmap(&comparison))?;
        Ok(format!(
            "{why}; actual, difference and FLIP map in {}; {bless_hint}",
            folder.display()
        ))
    });
    row.comparison = Some(comparison);
    failure.transpose()
}
