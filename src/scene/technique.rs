//! The settings types a scene gives the shadow techniques: the splat mode, the parameters every
//! technique receives, and the declaration of a technique-specific parameter. They live with
//! the scene, which owns its settings; the techniques' registry (`crate::shadow`) declares
//! which parameters exist and checks values against them.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// A parameter value outside its declared range.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ParamError {
    #[error("parameter {key} = {value} is out of range: allowed {min}..={max}")]
    OutOfRange {
        key: &'static str,
        value: f32,
        min: f32,
        max: f32,
    },
}

/// How a particle's optical depth is placed along the light ray when building layered maps.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "snake_case")]
pub enum SplatMode {
    /// All of it at the particle centre's depth (the thesis).
    #[default]
    Point,
    /// Spread uniformly over the chord through the sphere (converges to `exact`).
    Segment,
}

impl SplatMode {
    pub fn name(self) -> &'static str {
        match self {
            Self::Point => "point",
            Self::Segment => "segment",
        }
    }
}

/// The parameters every technique receives: the budget, the resolution and the splat mode that
/// all of them share, and the values of technique-specific parameters ([`ParamSpec`]) that were
/// set; each technique reads the ones its registry entry (`shadow::TechniqueEntry`) declares.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TechniqueParams {
    /// Channel budget, 1..=32 (each technique may have a larger minimum); what it buys is the
    /// technique's budget caption (`shadow::TechniqueEntry::budget_caption`).
    pub channels: u32,
    /// Square shadow-map resolution in pixels (light buffer for `has`, list grid for `exact`).
    pub resolution_px: u32,
    /// Where particle optical depth is splatted (layered techniques). Default: point.
    pub splat: SplatMode,
    /// Technique-specific parameters that were set, by [`ParamSpec::key`] (validated against
    /// the registry); an absent key takes its spec's default. Ordered, so equal settings
    /// serialize equally.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub values: BTreeMap<String, f32>,
}

impl TechniqueParams {
    /// `channels` at `resolution_px` with every other parameter at its default.
    pub fn new(channels: u32, resolution_px: u32) -> Self {
        Self {
            channels,
            resolution_px,
            splat: SplatMode::Point,
            values: BTreeMap::new(),
        }
    }

    /// The value of `spec`: the one set, else its default (`None`: derived per frame).
    pub fn get(&self, spec: &ParamSpec) -> Option<f32> {
        self.values.get(spec.key).copied().or(spec.default)
    }
}

/// A technique-specific parameter, declared once in its technique's registry entry: the scene
/// file spells it `[shadow.params] KEY = VALUE`, the CLI `--param KEY=VALUE`, the viewer draws a
/// slider for it, and `info` lists it with this documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    /// Unique across the registry, snake_case, prefixed with the technique's name.
    pub key: &'static str,
    /// Unit of the value ("m", "1/m", "-" for a ratio).
    pub unit: &'static str,
    /// What it changes, in one sentence.
    pub doc: &'static str,
    /// Smallest and largest accepted value, inclusive.
    pub min: f32,
    pub max: f32,
    /// The value when unset; `None` means the technique derives it each frame (the doc says how).
    pub default: Option<f32>,
}

impl ParamSpec {
    /// Checks `value` against the range.
    pub fn check(&self, value: f32) -> Result<(), ParamError> {
        if value.is_finite() && (self.min..=self.max).contains(&value) {
            Ok(())
        } else {
            Err(ParamError::OutOfRange {
                key: self.key,
                value,
                min: self.min,
                max: self.max,
            })
        }
    }
}
