//! Shared helpers for GPU tests: a deterministic adapter (lavapipe), and scene shortcuts.
#![allow(dead_code)]

use smokeshadow::gpu::{AdapterPreference, Gpu};
use smokeshadow::render::TechniqueConfig;
use smokeshadow::shadow::{SplatMode, TechniqueParams};

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
