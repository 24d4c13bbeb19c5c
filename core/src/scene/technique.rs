//! The settings types a scene gives the shadow techniques: the splat mode, the parameters every
//! technique receives, and the declaration of a technique-specific parameter. They live with
//! the scene, which owns its settings; the techniques' registry (`crate::shadow`) declares
//! which parameters exist and checks values against them.
//!
//! A parameter is a number in a range (`dom_layer_growth = 2`) or one of a few named choices
//! (`osm_interp = "cubic"`): a [`ParamSpec`] with `choices` takes the choice's name or its
//! index, and the technique reads the index.

use std::collections::BTreeMap;
use std::fmt;

use serde::{Deserialize, Serialize};

/// A parameter value its declaration refuses. Each renders as one line naming the parameter,
/// the value and what it accepts.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ParamError {
    #[error("parameter {key} = {value} is out of range: allowed {min}..={max}")]
    OutOfRange {
        key: &'static str,
        value: f32,
        min: f32,
        max: f32,
    },
    #[error("parameter {key} = {value} is not one of its choices: {valid}")]
    NotAChoice {
        key: &'static str,
        /// As written: a quoted name or a number.
        value: String,
        /// The choices, comma-separated.
        valid: String,
    },
    #[error("parameter {key} = \"{value}\" is not a number: allowed {min}..={max}")]
    NotANumber {
        key: &'static str,
        value: String,
        min: f32,
        max: f32,
    },
}

/// A technique parameter's value as a scene file or the CLI spells it: a number, or the name of
/// one of the parameter's choices. [`ParamSpec::resolve`] turns either into the number the
/// technique reads (a choice's index).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum ParamValue {
    Number(f32),
    Choice(String),
}

impl From<f32> for ParamValue {
    fn from(value: f32) -> Self {
        Self::Number(value)
    }
}

// By hand rather than `untagged`, so that a value of another type (a boolean, a table) is
// refused with what is expected instead of "did not match any variant".
impl<'de> Deserialize<'de> for ParamValue {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = ParamValue;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a number, or the name of one of the parameter's choices")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<ParamValue, E> {
                Ok(ParamValue::Number(v as f32))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<ParamValue, E> {
                Ok(ParamValue::Number(v as f32))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<ParamValue, E> {
                Ok(ParamValue::Number(v as f32))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<ParamValue, E> {
                Ok(ParamValue::Choice(v.to_owned()))
            }
        }
        deserializer.deserialize_any(Visitor)
    }
}

/// How a particle's optical depth is placed along the light ray when building layered maps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum SplatMode {
    /// All of it at the particle centre's depth: the thesis' model (2013, 3.2.2), which is not
    /// the reference's, so its error against `exact` measures the mismatch of the models too.
    Point,
    /// Spread over the chord through the sphere with the density τ(1 − d/r) of the ray's
    /// distance d from the centre: the reference's own model (thesis 3.2.2.3), so the error
    /// against `exact` is the technique's alone and converges with the budget. The default.
    #[default]
    Segment,
}

impl SplatMode {
    pub fn name(self) -> &'static str {
        match self {
            Self::Point => "point",
            Self::Segment => "segment",
        }
    }

    /// How reports and the viewer show it: the point splat labelled as the thesis' model.
    pub fn label(self) -> &'static str {
        match self {
            Self::Point => "point (the thesis' model)",
            Self::Segment => "segment (the reference's model)",
        }
    }
}

/// How the lighting tests the light against the opaque occluders (ground and boxes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum OccluderMode {
    /// Every technique tests the segment to the light against the boxes and the ground
    /// exactly, as the reference does (`shaders/common/occluders_exact.wgsl`): the default, so
    /// that the images compared differ only in the smoke's shadow.
    #[default]
    Exact,
    /// The techniques read a filtered depth map of the occluders from the light (3x3 PCF,
    /// `shaders/common/occluders_map.wgsl`), as an engine would; the reference stays exact, so
    /// the comparison then carries the map's own error (docs/rendering.md, "Lights and opaque
    /// occluders", states that floor).
    Map,
}

impl OccluderMode {
    pub fn name(self) -> &'static str {
        match self {
            Self::Exact => "exact",
            Self::Map => "map",
        }
    }
}

/// How a spotlight's light space frames the smoke: the square frustum every map (and `exact`'s
/// tiles, and the occluders' map) is drawn in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum Framing {
    /// Fitted to the smoke's light-space bounds each frame (the particles' spheres and the
    /// density volume's box, within the cone): the default, as engines fit a shadow frustum to
    /// its casters, so that every technique's texels fall on smoke. The volume's grid is fitted
    /// to the same smoke (its world box).
    #[default]
    Fit,
    /// The whole spotlight cone (4% wider for its penumbra): the thesis' framing, in which the
    /// smoke covers a fraction of the texels.
    Cone,
    /// Fitted as `fit`, then held steady as the smoke moves, as engines keep shadow maps from
    /// shimmering: the frustum's size in quarter-octave steps and its aim in steps of 1/256
    /// of its width (a whole texel of any map whose side is a multiple of 256), the radial
    /// depth range in quarter-octave steps and its start in eighths of it; so most frames
    /// keep the last one's texels and slices, and a step moves them at once. It covers up to
    /// a fifth more than `fit` (fewer texels on the smoke).
    Stable,
}

impl Framing {
    pub fn name(self) -> &'static str {
        match self {
            Self::Fit => "fit",
            Self::Cone => "cone",
            Self::Stable => "stable",
        }
    }
}

/// The parameters every technique receives: the budget, the resolution and the splat mode that
/// all of them share, and the values of technique-specific parameters ([`ParamSpec`]) that were
/// set; each technique reads the ones its registry entry (`shadow::TechniqueEntry`) declares.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TechniqueParams {
    /// Channel budget, 1..=32 (`has`: up to 240 batches; each technique may have a larger
    /// minimum); what it buys is the technique's budget caption
    /// (`shadow::TechniqueEntry::budget_caption`).
    pub channels: u32,
    /// Square shadow-map resolution in pixels (light buffer for `has`, list grid for `exact`).
    pub resolution_px: u32,
    /// Where particle optical depth is splatted (layered techniques). Default: segment, the
    /// reference's model; point is the thesis'.
    pub splat: SplatMode,
    /// How the lighting tests the opaque occluders (every technique but the reference, which
    /// is always exact). Default: exact.
    #[serde(default)]
    pub occluders: OccluderMode,
    /// Technique-specific parameters that were set, by [`ParamSpec::key`] (validated against
    /// the registry); an absent key takes its spec's default. Ordered, so equal settings
    /// serialize equally.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub values: BTreeMap<String, ParamValue>,
    /// The most bytes the technique may hold, scratch included (`gpu::MemoryLedger`): a byte
    /// budget's memory (`sweep --bytes-per-texel`, `--memory`). Scratch that can shed (a deep
    /// capture's lists, the volume's voxelisation) sizes itself to what is left, trading time
    /// for bytes; an allocation past it is refused in one line. `None`: the device's budget.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub memory_limit_bytes: Option<u64>,
}

impl TechniqueParams {
    /// `channels` at `resolution_px` with every other parameter at its default.
    pub fn new(channels: u32, resolution_px: u32) -> Self {
        Self {
            channels,
            resolution_px,
            splat: SplatMode::Segment,
            occluders: OccluderMode::Exact,
            values: BTreeMap::new(),
            memory_limit_bytes: None,
        }
    }

    /// The value of `spec`: the one set, else its default (`None`: derived per frame). A
    /// choice reads as its index. A value the spec refuses (`shadow::check_params` refuses it
    /// before any technique is built from these parameters) reads as the default.
    pub fn get(&self, spec: &ParamSpec) -> Option<f32> {
        self.values
            .get(spec.key)
            .and_then(|v| spec.resolve(v).ok())
            .or(spec.default)
    }

    /// The index of the choice set for `spec`, a parameter with choices (its default, else 0,
    /// when unset).
    pub fn choice_index(&self, spec: &ParamSpec) -> usize {
        debug_assert!(!spec.choices.is_empty(), "{} has no choices", spec.key);
        self.get(spec).map_or(0, |v| v as usize)
    }
}

/// A technique-specific parameter, declared once in its technique's registry entry: the scene
/// file spells it `[shadow.params] KEY = VALUE`, the CLI `--param KEY=VALUE`, the viewer draws a
/// slider for it (a choice of buttons for one with `choices`), and `info` lists it with this
/// documentation.
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
    /// Named values, for a parameter that picks one of a few: value i is `choices[i]`, and both
    /// the name and the index are accepted (`min` 0, `max` the last index). Empty for a numeric
    /// parameter.
    pub choices: &'static [&'static str],
    /// Whether the technique reads it as a whole number (it rounds): `tune` proposes whole
    /// numbers for it.
    pub integer: bool,
    /// Whether `tune` searches it. False for a setting that chooses what is measured rather
    /// than a knob of the same algorithm: a storage precision (it sets the bytes), or `avsm`'s
    /// insertion order (its `sorted` is not what a one-pass engine can do).
    pub tuned: bool,
}

impl ParamSpec {
    /// Checks `value` against the range (for a parameter with choices: a choice's index).
    pub fn check(&self, value: f32) -> Result<(), ParamError> {
        if !self.choices.is_empty() {
            return self.choice_at(value).map(|_| ());
        }
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

    /// The choice whose index is `value`.
    pub fn choice_at(&self, value: f32) -> Result<&'static str, ParamError> {
        let index = value as usize;
        if value.fract() == 0.0 && value >= 0.0 && index < self.choices.len() {
            Ok(self.choices[index])
        } else {
            Err(self.not_a_choice(value.to_string()))
        }
    }

    /// The number `value` stands for: a number in the range, or a choice's index.
    pub fn resolve(&self, value: &ParamValue) -> Result<f32, ParamError> {
        match value {
            ParamValue::Number(v) => self.check(*v).map(|()| *v),
            ParamValue::Choice(name) if self.choices.is_empty() => Err(ParamError::NotANumber {
                key: self.key,
                value: name.clone(),
                min: self.min,
                max: self.max,
            }),
            ParamValue::Choice(name) => self
                .choices
                .iter()
                .position(|c| c == name)
                .map(|i| i as f32)
                .ok_or_else(|| self.not_a_choice(format!("\"{name}\""))),
        }
    }

    /// `value`, checked, in the form settings keep: a choice by its name, a number as itself.
    pub fn canonical(&self, value: &ParamValue) -> Result<ParamValue, ParamError> {
        let number = self.resolve(value)?;
        Ok(if self.choices.is_empty() {
            ParamValue::Number(number)
        } else {
            ParamValue::Choice(self.choice_at(number)?.to_owned())
        })
    }

    /// What it accepts, for listings: "linear | cubic" or "1..=4".
    pub fn accepted(&self) -> String {
        if self.choices.is_empty() {
            format!("{}..={}", self.min, self.max)
        } else {
            self.choices.join(" | ")
        }
    }

    /// Its default as a listing shows it: the choice's name, the number, or "derived per frame".
    pub fn default_text(&self) -> String {
        match self.default {
            None => "derived per frame".to_owned(),
            Some(d) if !self.choices.is_empty() => self.choice_at(d).unwrap_or("?").to_owned(),
            Some(d) => d.to_string(),
        }
    }

    fn not_a_choice(&self, value: String) -> ParamError {
        ParamError::NotAChoice {
            key: self.key,
            value,
            valid: self.choices.join(", "),
        }
    }
}
