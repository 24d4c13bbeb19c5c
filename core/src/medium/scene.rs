//! A scene's `[volume]`: the density volume it holds, and how it is made into a
//! [`DensityGrid`] for the frame: an OpenVDB file's float grid, the procedural cloud baked on
//! the GPU, or a homogeneous sphere or box voxelised (the analytic media, whose closed forms
//! test the rest).
//!
//! ```toml
//! [volume]
//! file = "smoke.vdb"          # or: procedural = "cloud", or: shape = "sphere" | "box"
//! grid = "density"            # the file's float grid
//! density_scale_per_m = 10.0  # extinction (1/m) per unit of density
//! translate_m = [0, 0, 0]     # placed after the file's own transform:
//! scale = 1.0                 #   world = translate + rotate(scale · file world)
//! rotate_deg = [-90, 0, 0]    # about x, then y, then z (a z-up file's smoke stood up)
//! albedo = [0.9, 0.9, 0.9]
//! eye_steps = 128             # the eye's ray march
//! ```

use std::path::PathBuf;

use crate::files::Folder;

use glam::{DAffine3, DVec3, UVec3, Vec3};
use serde::{Deserialize, Serialize};

use super::analytic::{HomogeneousMedium, Shape};
use super::cloud::{CloudBaker, CloudNoiseGenerator};
use super::cloud_noise::CloudParams;
use super::grid::DensityGrid;
use super::vdb;
use crate::gpu::{Gpu, MemoryLedger};

/// The most voxels along any side of a shape's or the cloud's grid (and the least).
pub const MAX_VOXELS: u32 = 512;
pub const MIN_VOXELS: u32 = 2;
/// The most eye steps a march may take.
pub const MAX_EYE_STEPS: u32 = 4096;

/// Where the volume's density comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum VolumeKind<'a> {
    File(&'a str),
    Cloud,
    Sphere,
    Box,
}

/// The `[volume]` table of a scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VolumeSpec {
    /// An OpenVDB file, relative to the scene file's folder.
    #[serde(skip_serializing_if = "String::is_empty")]
    pub file: String,
    /// The file's float grid to read.
    pub grid: String,
    /// `cloud`: the slides' and the dissertation's procedural cloud (`[volume.cloud]`).
    #[serde(skip_serializing_if = "String::is_empty")]
    pub procedural: String,
    /// `sphere` (`center_m`, `radius_m`) or `box` (`center_m`, `size_m`): a homogeneous
    /// medium of density 1, voxelised.
    #[serde(skip_serializing_if = "String::is_empty")]
    pub shape: String,
    /// Extinction per unit of density, 1/m, >= 0 (the file's units; 1 inside a shape; the
    /// cloud's densest point).
    pub density_scale_per_m: f32,
    /// The placement after the source's own: world = translate + rotate(scale · p), the
    /// rotation about x, then y, then z, degrees.
    pub translate_m: Vec3,
    pub scale: f32,
    pub rotate_deg: Vec3,
    /// Single-scattering albedo, linear RGB, each in [0, 1].
    pub albedo: Vec3,
    /// Steps of the eye's ray march over the part of each ray the grid covers, 1..=4096.
    pub eye_steps: u32,
    /// Steps along each light-space texel's ray of the techniques' build from the volume
    /// (the same for every technique), 1..=4096.
    pub build_steps: u32,
    /// Where in each step the eye samples: 0.5 its middle; 1 jitters it per pixel (against
    /// banding), in [0, 1].
    pub jitter: f32,
    /// The slides' powder term (dark edges where little light has scattered in), 0 off .. 1.
    pub powder: f32,
    /// A shape's centre and the sphere's radius or the box's sides, metres.
    pub center_m: Vec3,
    pub radius_m: f32,
    pub size_m: Vec3,
    /// Voxels along the longest side of a shape's or the cloud's grid.
    pub voxels: u32,
    /// The procedural cloud's layer.
    pub cloud: CloudSpec,
    /// A file sequence's (`smoke.%04d.vdb`) frames per second, > 0, and its frame at t = 0:
    /// the scene's time picks the frame, as a particle sequence's (default 24 and 0).
    #[serde(skip_serializing_if = "is_default_rate")]
    pub frame_rate_hz: f32,
    #[serde(skip_serializing_if = "is_zero")]
    pub frame_at_zero: i64,
    /// The folder `file` is relative to, and the files it is read from: the scene file's (not
    /// written).
    #[serde(skip)]
    pub folder: Folder,
    /// The scene time the grid is made at, seconds (not written; [`VolumeSpec::at_time`]):
    /// how far the cloud's wind has carried its noise. 0 for a volume that does not move.
    #[serde(skip)]
    pub time_s: f32,
}

impl Default for VolumeSpec {
    fn default() -> Self {
        Self {
            file: String::new(),
            grid: "density".to_owned(),
            procedural: String::new(),
            shape: String::new(),
            density_scale_per_m: 1.0,
            translate_m: Vec3::ZERO,
            scale: 1.0,
            rotate_deg: Vec3::ZERO,
            albedo: Vec3::splat(0.9),
            eye_steps: 128,
            build_steps: 64,
            jitter: 1.0,
            powder: 0.0,
            center_m: Vec3::ZERO,
            radius_m: 1.0,
            size_m: Vec3::ONE,
            voxels: 64,
            cloud: CloudSpec::default(),
            frame_rate_hz: DEFAULT_FRAME_RATE_HZ,
            frame_at_zero: 0,
            folder: Folder::default(),
            time_s: 0.0,
        }
    }
}

/// `[volume.cloud]`: the cloud layer (see [`CloudParams`]; its densest extinction is the
/// volume's `density_scale_per_m`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CloudSpec {
    /// The noise's seed.
    pub seed: u32,
    pub origin_xz_m: [f32; 2],
    pub size_xz_m: [f32; 2],
    pub altitude_m: f32,
    pub thickness_m: f32,
    /// Global coverage, 0 (clear) .. 1 (overcast).
    pub coverage: f32,
    pub top_fraction: f32,
    pub shape_period_m: f32,
    pub detail_period_m: f32,
    /// How much the coverage map shapes the layer, 0..1.
    pub coverage_map: f32,
    /// The wind along x and z, m/s, each finite and at most 1000 in size: at scene time t the
    /// cloud's noise and coverage map have moved by t times it through the layer (the layer's
    /// box stays), so an animation (`sweep --animate`) sees the cloud drift. Default 0: still.
    #[serde(skip_serializing_if = "is_still")]
    pub wind_m_per_s: [f32; 2],
}

fn is_still(wind: &[f32; 2]) -> bool {
    *wind == [0.0; 2]
}

/// A volume sequence's frame rate unless its scene says otherwise.
pub const DEFAULT_FRAME_RATE_HZ: f32 = 24.0;

fn is_default_rate(rate: &f32) -> bool {
    *rate == DEFAULT_FRAME_RATE_HZ
}

fn is_zero(v: &i64) -> bool {
    *v == 0
}

impl Default for CloudSpec {
    fn default() -> Self {
        Self {
            seed: 7,
            origin_xz_m: [-3000.0, -3000.0],
            size_xz_m: [6000.0, 6000.0],
            altitude_m: 1500.0,
            thickness_m: 1500.0,
            coverage: 0.6,
            top_fraction: 1.0,
            shape_period_m: 4000.0,
            detail_period_m: 800.0,
            coverage_map: 1.0,
            wind_m_per_s: [0.0; 2],
        }
    }
}

impl CloudSpec {
    /// How far the wind has carried the noise at `time_s`, world metres (y 0).
    pub fn drift_m(&self, time_s: f32) -> glam::Vec3 {
        glam::Vec3::new(self.wind_m_per_s[0], 0.0, self.wind_m_per_s[1]) * time_s
    }

    /// The layer's parameters, its density 1 at the densest (the grid's scale gives the unit).
    pub fn params(&self) -> CloudParams {
        CloudParams {
            origin_xz_m: self.origin_xz_m,
            size_xz_m: self.size_xz_m,
            altitude_m: self.altitude_m,
            thickness_m: self.thickness_m,
            coverage: self.coverage,
            density_per_m: 1.0,
            top_fraction: self.top_fraction,
            shape_period_m: self.shape_period_m,
            detail_period_m: self.detail_period_m,
            coverage_map: self.coverage_map,
        }
    }
}

/// Why a scene's volume cannot be made. Each renders as one line naming the field or file.
#[derive(Debug, thiserror::Error)]
pub enum VolumeError {
    #[error("cannot read volume file {path}: {cause}")]
    Read {
        path: PathBuf,
        cause: std::io::Error,
    },
    #[error("volume file {path}: {cause}")]
    Vdb { path: PathBuf, cause: vdb::VdbError },
    #[error("volume file {path}: {cause}")]
    Grid {
        path: PathBuf,
        cause: super::grid::GridError,
    },
    #[error("volume: the procedural cloud: {0}")]
    Cloud(String),
    #[error(
        "volume: its {dims} voxels need {steps} reference steps along the diagonal (two a voxel), \
         more than the {max} one shader invocation may take beside the particles' walk: use a \
         coarser grid (volume.voxels, or resample the file)"
    )]
    TooFine { dims: UVec3, steps: u32, max: u32 },
    #[error("volume: cannot upload its grid: {0}")]
    Upload(String),
}

impl VolumeSpec {
    /// Which source the table names (validation has checked that it names exactly one).
    pub fn kind(&self) -> VolumeKind<'_> {
        if !self.file.is_empty() {
            VolumeKind::File(&self.file)
        } else if self.procedural == "cloud" {
            VolumeKind::Cloud
        } else if self.shape == "box" {
            VolumeKind::Box
        } else {
            VolumeKind::Sphere
        }
    }

    /// The file's path, relative to the scene file's folder: for a sequence (`%04d` or `%d`
    /// in its name), the frame at the spec's time ([`VolumeSpec::at_time`]).
    pub fn path(&self) -> PathBuf {
        match self.is_sequence() {
            true => self.folder.join(crate::scene::sequence::frame_name(
                &self.file,
                self.frame_at(self.time_s),
            )),
            false => self.folder.join(&self.file),
        }
    }

    /// Whether its file is a numbered sequence's pattern.
    pub fn is_sequence(&self) -> bool {
        !self.file.is_empty() && crate::scene::sequence::is_sequence(&self.file)
    }

    /// A sequence's frame at scene time `time_s` ([`crate::scene::sequence::sequence_frame`]).
    pub fn frame_at(&self, time_s: f32) -> i64 {
        crate::scene::sequence::sequence_frame(self.frame_at_zero, self.frame_rate_hz, time_s)
    }

    /// The file's grid placed by the file's own transform, `density_scale_per_m` of extinction
    /// per unit of density.
    pub(crate) fn file_grid(&self, density_scale_per_m: f64) -> Result<DensityGrid, VolumeError> {
        let path = self.path();
        let bytes = self.file_bytes()?;
        let file =
            vdb::read_float_grid(&bytes, &self.grid, &vdb::Limits::default()).map_err(|cause| {
                VolumeError::Vdb {
                    path: path.clone(),
                    cause,
                }
            })?;
        DensityGrid::from_vdb(&file, DAffine3::IDENTITY, density_scale_per_m)
            .map_err(|cause| VolumeError::Grid { path, cause })
    }

    /// The file's bytes: read, or built in ([`EMBEDDED_FILES`]).
    pub fn file_bytes(&self) -> Result<std::borrow::Cow<'static, [u8]>, VolumeError> {
        if let Some(name) = self.file.strip_prefix(EMBEDDED_PREFIX) {
            return EMBEDDED_FILES
                .iter()
                .find(|(n, _)| *n == name)
                .map(|(_, bytes)| std::borrow::Cow::Borrowed(*bytes))
                .ok_or_else(|| VolumeError::Read {
                    path: self.file.clone().into(),
                    cause: std::io::Error::new(
                        std::io::ErrorKind::NotFound,
                        format!(
                            "no embedded volume file {name:?}; embedded: {}",
                            EMBEDDED_FILES
                                .iter()
                                .map(|(n, _)| *n)
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    ),
                });
        }
        let path = self.path();
        self.folder
            .files
            .read(&path)
            .map(std::borrow::Cow::Owned)
            .map_err(|cause| VolumeError::Read { path, cause })
    }

    /// The scene's placement of the source: world = translate + rotate(scale · p).
    pub fn placement(&self) -> DAffine3 {
        let r = self.rotate_deg.as_dvec3();
        DAffine3::from_translation(self.translate_m.as_dvec3())
            * DAffine3::from_rotation_z(r.z.to_radians())
            * DAffine3::from_rotation_y(r.y.to_radians())
            * DAffine3::from_rotation_x(r.x.to_radians())
            * DAffine3::from_scale(DVec3::splat(f64::from(self.scale)))
    }

    /// A shape as its closed form, before the placement (`None` for a file or the cloud).
    pub fn analytic(&self) -> Option<HomogeneousMedium> {
        let shape = match self.kind() {
            VolumeKind::Sphere => Shape::Sphere {
                center: self.center_m.as_dvec3(),
                radius_m: f64::from(self.radius_m),
            },
            VolumeKind::Box => Shape::Box {
                min: (self.center_m - 0.5 * self.size_m).as_dvec3(),
                max: (self.center_m + 0.5 * self.size_m).as_dvec3(),
            },
            _ => return None,
        };
        Some(HomogeneousMedium {
            shape,
            extinction_per_m: f64::from(self.density_scale_per_m),
        })
    }

    /// Voxels per axis of a box of `size` with `self.voxels` along its longest side.
    fn dims_for(&self, size: DVec3) -> UVec3 {
        let voxel = size.max_element() / f64::from(self.voxels);
        (size / voxel)
            .ceil()
            .as_uvec3()
            .clamp(UVec3::splat(MIN_VOXELS), UVec3::splat(MAX_VOXELS))
    }

    /// The volume as a density grid in the world: read, baked or voxelised, then placed.
    /// The cloud's bake records its transient buffers in `ledger`.
    pub async fn density_grid(
        &self,
        gpu: &Gpu,
        ledger: &mut MemoryLedger,
    ) -> Result<DensityGrid, VolumeError> {
        let mut grid = match self.kind() {
            VolumeKind::File(_) => self.file_grid(f64::from(self.density_scale_per_m))?,
            VolumeKind::Cloud => {
                let params = self.cloud.params();
                params
                    .validate()
                    .map_err(|e| VolumeError::Cloud(e.to_string()))?;
                let size = DVec3::new(
                    f64::from(params.size_xz_m[0]),
                    f64::from(params.thickness_m),
                    f64::from(params.size_xz_m[1]),
                );
                let noise = CloudNoiseGenerator::new(gpu)
                    .generate(gpu, ledger, self.cloud.seed)
                    .map_err(|e| VolumeError::Cloud(e.to_string()))?;
                let drift = self.cloud.drift_m(self.time_s);
                let mut grid = CloudBaker::new(gpu)
                    .bake(gpu, ledger, &noise, &params, self.dims_for(size), drift)
                    .await
                    .map_err(|e| VolumeError::Cloud(e.to_string()))?;
                grid.density_scale_per_m = f64::from(self.density_scale_per_m);
                grid
            }
            VolumeKind::Sphere | VolumeKind::Box => {
                let medium = self.analytic().expect("a shape has a closed form");
                let (min, max) = medium.shape.bounds();
                // Half a voxel of empty margin on each side, so the edge's ramp is inside.
                let dims = self.dims_for(max - min);
                let margin = (max - min) / dims.as_dvec3();
                let mut grid = DensityGrid::voxelize(&medium, min - margin, max + margin, dims + 2);
                grid.density_scale_per_m = 1.0;
                grid
            }
        };
        grid.world_from_index = self.placement() * grid.world_from_index;
        Ok(grid)
    }

    /// Range checks; each message names the field as `volume.<field>`.
    pub fn problems(&self) -> Vec<String> {
        let mut out = Vec::new();
        let sources = [
            !self.file.is_empty(),
            !self.procedural.is_empty(),
            !self.shape.is_empty(),
        ];
        match sources.iter().filter(|s| **s).count() {
            0 => out.push(
                "[volume] names no source: give file = \"….vdb\", procedural = \"cloud\" or \
                 shape = \"sphere\" | \"box\""
                    .to_owned(),
            ),
            1 => {}
            _ => out.push(
                "[volume] names more than one source: give one of file, procedural and shape"
                    .to_owned(),
            ),
        }
        if !self.procedural.is_empty() && self.procedural != "cloud" {
            out.push(format!(
                "volume.procedural = {:?} is unknown: the one procedural volume is \"cloud\"",
                self.procedural
            ));
        }
        if !self.shape.is_empty() && !matches!(self.shape.as_str(), "sphere" | "box") {
            out.push(format!(
                "volume.shape = {:?} is unknown: \"sphere\" or \"box\"",
                self.shape
            ));
        }
        if self.grid.is_empty() {
            out.push("volume.grid is empty: name the file's float grid (\"density\")".to_owned());
        }
        let mut positive = |field: &str, v: f32| {
            if !(v.is_finite() && v > 0.0) {
                out.push(format!("volume.{field} = {v} is out of range: must be > 0"));
            }
        };
        positive("scale", self.scale);
        positive("radius_m", self.radius_m);
        for (axis, v) in ["x", "y", "z"].iter().zip(self.size_m.to_array()) {
            positive(&format!("size_m.{axis}"), v);
        }
        if !(self.density_scale_per_m.is_finite() && self.density_scale_per_m >= 0.0) {
            out.push(format!(
                "volume.density_scale_per_m = {} is out of range: must be >= 0",
                self.density_scale_per_m
            ));
        }
        let unit = |field: &str, v: f32, out: &mut Vec<String>| {
            if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
                out.push(format!(
                    "volume.{field} = {v} is out of range: allowed [0, 1]"
                ));
            }
        };
        unit("jitter", self.jitter, &mut out);
        unit("powder", self.powder, &mut out);
        for (c, v) in ["r", "g", "b"].iter().zip(self.albedo.to_array()) {
            unit(&format!("albedo.{c}"), v, &mut out);
        }
        for (field, v) in [
            ("translate_m", self.translate_m),
            ("center_m", self.center_m),
            ("rotate_deg", self.rotate_deg),
        ] {
            if !v.is_finite() {
                out.push(format!("volume.{field} = {v} must be finite"));
            }
        }
        if !(1..=MAX_EYE_STEPS).contains(&self.eye_steps) {
            out.push(format!(
                "volume.eye_steps = {} is out of range: allowed 1..={MAX_EYE_STEPS}",
                self.eye_steps
            ));
        }
        if !(1..=MAX_EYE_STEPS).contains(&self.build_steps) {
            out.push(format!(
                "volume.build_steps = {} is out of range: allowed 1..={MAX_EYE_STEPS}",
                self.build_steps
            ));
        }
        if !(MIN_VOXELS..=MAX_VOXELS).contains(&self.voxels) {
            out.push(format!(
                "volume.voxels = {} is out of range: allowed {MIN_VOXELS}..={MAX_VOXELS}",
                self.voxels
            ));
        }
        if !(self.frame_rate_hz.is_finite() && self.frame_rate_hz > 0.0) {
            out.push(format!(
                "volume.frame_rate_hz = {} is out of range: allowed (0, inf)",
                self.frame_rate_hz
            ));
        }
        for (i, w) in self.cloud.wind_m_per_s.iter().enumerate() {
            if !(w.is_finite() && w.abs() <= 1000.0) {
                out.push(format!(
                    "volume.cloud.wind_m_per_s[{i}] = {w} is out of range: allowed -1000..=1000 (m/s)"
                ));
            }
        }
        if self.procedural == "cloud"
            && let Err(e) = self.cloud.params().validate()
        {
            out.push(format!(
                "volume.cloud.{} = {} is out of range: allowed {}",
                e.field.replace(".x", "[0]").replace(".z", "[1]"),
                e.value,
                e.allowed
            ));
        }
        out
    }

    /// The spec of the grid at scene time `time_s`: a file sequence and the procedural cloud
    /// with a wind carry the time (their grid moves); any other volume the same grid at every
    /// time (`time_s` 0).
    pub fn at_time(&self, time_s: f32) -> Self {
        let moves = self.is_sequence()
            || self.kind() == VolumeKind::Cloud && !is_still(&self.cloud.wind_m_per_s);
        Self {
            time_s: if moves { time_s } else { 0.0 },
            ..self.clone()
        }
    }

    /// A short description for `info` and reports.
    pub fn summary(&self) -> String {
        match self.kind() {
            VolumeKind::File(file) => format!(
                "volume: grid {:?} of {file}, {} /m per unit",
                self.grid, self.density_scale_per_m
            ),
            VolumeKind::Cloud => format!(
                "volume: procedural cloud, {:.0}x{:.0} m at {:.0} m, coverage {}, {} /m at its densest",
                self.cloud.size_xz_m[0],
                self.cloud.size_xz_m[1],
                self.cloud.altitude_m,
                self.cloud.coverage,
                self.density_scale_per_m
            ),
            VolumeKind::Sphere => format!(
                "volume: homogeneous sphere r = {} m, {} /m",
                self.radius_m, self.density_scale_per_m
            ),
            VolumeKind::Box => format!(
                "volume: homogeneous box {} m, {} /m",
                self.size_m, self.density_scale_per_m
            ),
        }
    }
}

/// Volume files built into the binary, for the embedded scenes: `file = "embedded:NAME"`.
/// OpenUSD's smoke test file (tests/data/volumes/README.md: OpenUSD's license).
pub const EMBEDDED_FILES: &[(&str, &[u8])] = &[(
    "openusd_smoke_000003.vdb",
    include_bytes!("../../../tests/data/volumes/openusd_smoke_000003.vdb"),
)];

/// The prefix of an embedded volume file's name.
pub const EMBEDDED_PREFIX: &str = "embedded:";
