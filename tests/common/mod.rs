//! Shared helpers for GPU tests: a deterministic adapter (lavapipe), and scene shortcuts.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub mod sphere;

use glam::Vec3;
use smokeshadow::gpu::{AdapterPreference, Gpu};
use smokeshadow::render::{OUTPUT_FORMAT, Renderer, TechniqueConfig};
use smokeshadow::scene::Scene;
use smokeshadow::shadow::{SplatMode, TechniqueParams};
use smokeshadow::sim::Particle;

/// The CPU adapter (lavapipe), so results do not depend on which GPU is present. Fails loudly
/// when there is none: GPU tests never skip.
pub fn gpu() -> Gpu {
    let preference = std::env::var("SMOKESHADOW_TEST_ADAPTER")
        .map(|s| s.parse().unwrap())
        .unwrap_or(AdapterPreference::Cpu);
    Gpu::new(&preference).unwrap_or_else(|e| {
        panic!(
            "GPU tests need an adapter ({preference}); install lavapipe (mesa-vulkan-drivers): {e}"
        )
    })
}

/// T at `points` for each configuration, in order (one renderer, switching techniques).
pub fn probe_all(
    gpu: &Gpu,
    scene: &Scene,
    particles: &[Particle],
    configs: &[TechniqueConfig],
    points: &[Vec3],
) -> Vec<Vec<f32>> {
    let mut renderer = Renderer::new(
        gpu,
        scene.output.width_px,
        scene.output.height_px,
        OUTPUT_FORMAT,
        &configs[0],
    )
    .unwrap();
    configs
        .iter()
        .map(|c| {
            renderer.set_technique(gpu, c).unwrap();
            renderer.probe(gpu, scene, particles, points).unwrap()
        })
        .collect()
}

/// The size of the reduced thesis frame the technique tests render and probe.
pub const REDUCED_W: u32 = 256;
pub const REDUCED_H: u32 = 192;

/// The thesis plume at the reduced frame size.
pub fn reduced_plume() -> Scene {
    let mut scene = Scene::thesis_plume();
    scene.output.width_px = REDUCED_W;
    scene.output.height_px = REDUCED_H;
    scene
}

pub fn technique(
    name: &str,
    channels: u32,
    resolution_px: u32,
    splat: SplatMode,
) -> TechniqueConfig {
    TechniqueConfig {
        name: name.to_owned(),
        params: TechniqueParams {
            splat,
            ..TechniqueParams::new(channels, resolution_px)
        },
    }
}

/// Rec. 709 luminance of a linear RGB triple.
pub fn luminance(c: [f32; 4]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// Runs the binary with `args` on the CPU adapter.
pub fn smokeshadow(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_smokeshadow"))
        .args(args)
        .env("SMOKESHADOW_ADAPTER", "cpu")
        .output()
        .expect("the binary runs")
}

/// A fresh, empty folder for one test's files.
pub fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// stderr lines that are ours (the Vulkan loader may print its own XDG_RUNTIME_DIR warning).
pub fn error_lines(out: &Output) -> Vec<String> {
    String::from_utf8_lossy(&out.stderr)
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.contains("XDG_RUNTIME_DIR"))
        .map(str::to_owned)
        .collect()
}
