//! Shared helpers for GPU tests: a deterministic adapter (lavapipe), and scene shortcuts.
#![allow(dead_code)]

use smokeshadow::Wait;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub mod sphere;

use glam::Vec3;
use smokeshadow::gpu::{AdapterPreference, Gpu};
use smokeshadow::render::{OUTPUT_FORMAT, Renderer, TechniqueConfig};
use smokeshadow::scene::{BoxShape, Scene};
use smokeshadow::shadow::{SplatMode, TechniqueParams};
use smokeshadow::sim::Particle;

/// The adapter GPU tests run on: the CPU's (lavapipe), unless `SMOKESHADOW_TEST_ADAPTER` names
/// another (`scripts/gpu-check.sh`).
pub fn adapter_preference() -> AdapterPreference {
    std::env::var("SMOKESHADOW_TEST_ADAPTER")
        .map(|s| s.parse().unwrap())
        .unwrap_or(AdapterPreference::Cpu)
}

/// The CPU adapter (lavapipe), so results do not depend on which GPU is present. Fails loudly
/// when there is none: GPU tests never skip.
pub fn gpu() -> Gpu {
    let preference = adapter_preference();
    Gpu::new(&preference).wait().unwrap_or_else(|e| {
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
    .wait()
    .unwrap();
    configs
        .iter()
        .map(|c| {
            renderer.set_technique(gpu, c).wait().unwrap();
            renderer
                .probe(gpu, scene, particles, points)
                .wait()
                .unwrap()
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

/// The reduced plume simulated, its shaded points (every `stride`-th pixel) and `exact`'s T
/// there: what the convergence tests compare each technique's T with.
pub struct PlumeAgainstExact {
    pub scene: Scene,
    pub particles: Vec<Particle>,
    pub points: Vec<Vec3>,
    pub exact: Vec<f32>,
}

impl PlumeAgainstExact {
    pub fn new(gpu: &Gpu, stride: u32) -> Self {
        let scene = reduced_plume();
        let particles = smokeshadow::sim::simulate(&scene);
        let points = smokeshadow::render::shaded::shaded_points(
            &scene,
            &particles,
            (REDUCED_W, REDUCED_H),
            stride,
            None,
        );
        let res = scene.shadow.resolution_px;
        let exact = probe_all(
            gpu,
            &scene,
            &particles,
            &[technique("exact", 1, res, SplatMode::Segment)],
            &points,
        )
        .remove(0);
        Self {
            scene,
            particles,
            points,
            exact,
        }
    }

    /// The map resolution of the scene.
    pub fn res(&self) -> u32 {
        self.scene.shadow.resolution_px
    }

    /// The RMS T error against `exact` of each configuration.
    pub fn errors(&self, gpu: &Gpu, configs: &[TechniqueConfig]) -> Vec<f64> {
        probe_all(gpu, &self.scene, &self.particles, configs, &self.points)
            .iter()
            .map(|t| smokeshadow::render::shaded::rms_difference(t, &self.exact))
            .collect()
    }
}

/// The reduced plume probed twice, with the camera in front of it and behind it: the renderer
/// sorts the particles back to front for the camera before the build, so the light's passes see
/// them in reversed order while the light space stays the same (order-independence tests).
pub struct ReversedOrder {
    scene: Scene,
    behind: Scene,
    particles: Vec<Particle>,
    /// The shaded points T is probed at (every 8th pixel of the reduced view).
    pub points: Vec<Vec3>,
}

impl ReversedOrder {
    pub fn new() -> Self {
        let scene = reduced_plume();
        let mut behind = scene.clone();
        behind.camera.position = scene.camera.target * 2.0 - scene.camera.position;
        let particles = smokeshadow::sim::simulate(&scene);
        let points = smokeshadow::render::shaded::shaded_points(
            &scene,
            &particles,
            (REDUCED_W, REDUCED_H),
            8,
            None,
        );
        Self {
            scene,
            behind,
            particles,
            points,
        }
    }

    /// The scene's shadow-map resolution.
    pub fn resolution_px(&self) -> u32 {
        self.scene.shadow.resolution_px
    }

    /// T at the points with the particles in one order, then in the reversed one.
    pub fn probe(&self, gpu: &Gpu, config: &TechniqueConfig) -> (Vec<f32>, Vec<f32>) {
        let config = std::slice::from_ref(config);
        let mut front = probe_all(gpu, &self.scene, &self.particles, config, &self.points);
        let mut back = probe_all(gpu, &self.behind, &self.particles, config, &self.points);
        (front.remove(0), back.remove(0))
    }
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

/// Runs the binary with `args` on the tests' adapter (the CPU's, unless
/// `SMOKESHADOW_TEST_ADAPTER` names another). `SMOKESHADOW_TEST_BIN` runs another build of it
/// than cargo's (`scripts/gpu-check.sh --prebuilt` on a machine without cargo).
pub fn smokeshadow(args: &[&str]) -> Output {
    let bin = std::env::var_os("SMOKESHADOW_TEST_BIN")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_BIN_EXE_smokeshadow")));
    let adapter = std::env::var("SMOKESHADOW_TEST_ADAPTER").unwrap_or_else(|_| "cpu".to_owned());
    Command::new(&bin)
        .args(args)
        .env("SMOKESHADOW_ADAPTER", adapter)
        .output()
        .unwrap_or_else(|e| panic!("the binary {} runs: {e}", bin.display()))
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

/// Whether the segment from `a` to `b` passes through the box.
pub fn segment_hits_box(a: Vec3, b: Vec3, bx: &BoxShape) -> bool {
    let lo = bx.center - bx.size * 0.5;
    let hi = bx.center + bx.size * 0.5;
    let d = b - a;
    let (mut t0, mut t1) = (0.0f32, 1.0f32);
    for axis in 0..3 {
        if d[axis].abs() < 1e-9 {
            if a[axis] < lo[axis] || a[axis] > hi[axis] {
                return false;
            }
        } else {
            let (mut ta, mut tb) = (
                (lo[axis] - a[axis]) / d[axis],
                (hi[axis] - a[axis]) / d[axis],
            );
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
        }
    }
    t0 <= t1
}
