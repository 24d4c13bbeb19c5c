//! Particle files in and out: the particles of a frame as PLY (binary or ASCII, named vertex
//! properties) or CSV (a header row), so that smoke simulated elsewhere (Houdini, Blender,
//! EmberGen, an engine) can be brought in and ours taken out.
//!
//! - [`encode`] gives the bytes of a particle file in a [`Format`] (`.ply`, binary
//!   little-endian unless [`Format::PlyAscii`] is asked for; `.csv`); the apps write them.
//! - [`parse`] reads either from bytes ([`read`] from a scene's [`Files`]), mapping the property names of common exporters (see
//!   [`PROPERTIES`]) onto [`Particle`]; properties it does not know are ignored, missing
//!   optional ones take the scene's `[particles]` defaults ([`Defaults`]).
//! - [`frame_particles`] is a frame's particles: the scene's particle file (a single file or a
//!   `%04d` sequence, the frame picked by the scene's time) or its emitters' simulation.
//!
//! Every bad file is one [`ParticleFileError`] line naming the file, the element (and particle
//! index) and the property. Values round-trip exactly: binary files hold the f32s, and ASCII
//! PLY and CSV print each f32 in the shortest form that reads back to the same bits.
//!
//! To accept another exporter's name for a property, add it to [`PROPERTIES`] and to the
//! mapping table in `scenes/README.md`.

mod csv_file;
mod ply_file;
mod volume_file;

use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::files::{Files, Folder};
use crate::scene::{ParticleSource, Scene};
use crate::sim::Particle;
pub use volume_file::{BARE_FILE_OPTICAL_DEPTH, is_volume_file, scene_for_volume_file};
use volume_file::{scene_for_volume_sequence, show_volume_frame};

/// A particle file's format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Format {
    /// PLY, binary little-endian.
    Ply,
    /// PLY, ASCII.
    PlyAscii,
    /// Comma-separated values with a header row.
    Csv,
}

impl Format {
    /// The format a file name's extension says (`.ply` is binary PLY), if any.
    pub fn of_path(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "ply" => Some(Self::Ply),
            "csv" => Some(Self::Csv),
            _ => None,
        }
    }
}

/// One property of a particle as files name it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Field {
    X,
    Y,
    Z,
    Radius,
    Density,
    Red,
    Green,
    Blue,
    Age,
    Vx,
    Vy,
    Vz,
}

/// Every property we read: the name we write first, then the other exporters' names for it
/// (matched without regard to case), and whether a file must have it.
pub const PROPERTIES: &[(Field, &[&str], bool)] = &[
    (Field::X, &["x", "px", "P.x", "P[0]"], true),
    (Field::Y, &["y", "py", "P.y", "P[1]"], true),
    (Field::Z, &["z", "pz", "P.z", "P[2]"], true),
    (Field::Radius, &["radius", "pscale", "radius_m"], false),
    (
        Field::Density,
        &["density", "extinction", "density_per_m", "sigma_t"],
        false,
    ),
    (
        Field::Red,
        &["red", "r", "Cd.r", "Cd[0]", "albedo_r"],
        false,
    ),
    (
        Field::Green,
        &["green", "g", "Cd.g", "Cd[1]", "albedo_g"],
        false,
    ),
    (
        Field::Blue,
        &["blue", "b", "Cd.b", "Cd[2]", "albedo_b"],
        false,
    ),
    (Field::Age, &["age", "age_s"], false),
    (Field::Vx, &["vx", "v.x", "v[0]", "velocity_x"], false),
    (Field::Vy, &["vy", "v.y", "v[1]", "velocity_y"], false),
    (Field::Vz, &["vz", "v.z", "v[2]", "velocity_z"], false),
];

/// The columns we write, in order (the first name of each of [`PROPERTIES`]).
pub fn written_names() -> Vec<&'static str> {
    PROPERTIES.iter().map(|(_, names, _)| names[0]).collect()
}

/// The field a file's property name stands for, if any.
pub fn field_of(name: &str) -> Option<Field> {
    PROPERTIES
        .iter()
        .find(|(_, names, _)| names.iter().any(|n| n.eq_ignore_ascii_case(name)))
        .map(|(field, _, _)| *field)
}

/// A particle's values in [`PROPERTIES`] order.
pub fn values_of(p: &Particle) -> [f32; 12] {
    [
        p.position.x,
        p.position.y,
        p.position.z,
        p.radius_m,
        p.density_per_m,
        p.albedo.x,
        p.albedo.y,
        p.albedo.z,
        p.age_s,
        p.velocity.x,
        p.velocity.y,
        p.velocity.z,
    ]
}

/// What a particle takes for the optional properties its file lacks (`[particles]` in a scene).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Defaults {
    pub radius_m: f32,
    pub density_per_m: f32,
    pub albedo: Vec3,
}

impl Default for Defaults {
    fn default() -> Self {
        let p = ParticleSource::default();
        Self {
            radius_m: p.radius_m,
            density_per_m: p.density_per_m,
            albedo: p.albedo,
        }
    }
}

/// A particle being read: the fields found so far.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Partial {
    values: [Option<f64>; 12],
}

impl Partial {
    pub(crate) fn set(&mut self, field: Field, value: f64) {
        self.values[field as usize] = Some(value);
    }
}

/// Errors of particle files: each is one line naming the file and, for bad content, the element
/// (particle) and property.
#[derive(Debug, thiserror::Error)]
pub enum ParticleFileError {
    #[error("cannot read particle file {path}: {cause}")]
    Read {
        path: PathBuf,
        cause: std::io::Error,
    },
    #[error("cannot write particle file {path}: {cause}")]
    Write { path: PathBuf, cause: String },
    #[error("particle file {path}: {message}")]
    Invalid { path: PathBuf, message: String },
    #[error(
        "particle file {path}: unknown format: name it .ply (PLY, binary or ASCII) or .csv (a header row)"
    )]
    UnknownFormat { path: PathBuf },
}

impl ParticleFileError {
    pub(crate) fn invalid(path: &Path, message: impl Into<String>) -> Self {
        Self::Invalid {
            path: path.to_owned(),
            message: message.into(),
        }
    }
}

/// Turns the properties read for each particle into particles, checking each value. `element`
/// names what the file calls a particle (PLY's `vertex`, CSV's row) in errors, `index_of` the
/// particle's position in the file (a CSV line number).
pub(crate) fn finish(
    path: &Path,
    element: &str,
    present: &[Field],
    partials: Vec<Partial>,
    defaults: &Defaults,
    index_of: impl Fn(usize) -> String,
) -> Result<Vec<Particle>, ParticleFileError> {
    let bad = |message: String| ParticleFileError::invalid(path, message);
    for (field, names, required) in PROPERTIES {
        if *required && !present.contains(field) {
            return Err(bad(format!(
                "element {element} has no property {} (also read as: {}); it is required",
                names[0],
                names[1..].join(", ")
            )));
        }
    }
    if partials.is_empty() {
        return Err(bad(format!("element {element} has no particles")));
    }
    let max = crate::scene::LIMITS.max_particles as usize;
    if partials.len() > max {
        return Err(bad(format!(
            "element {element} has {} particles: at most {max}",
            partials.len()
        )));
    }
    let mut particles = Vec::with_capacity(partials.len());
    for (i, partial) in partials.iter().enumerate() {
        let mut v = [0f32; 12];
        for (field, names, _) in PROPERTIES {
            let value = match partial.values[*field as usize] {
                Some(value) => value as f32,
                None => match field {
                    Field::Radius => defaults.radius_m,
                    Field::Density => defaults.density_per_m,
                    Field::Red => defaults.albedo.x,
                    Field::Green => defaults.albedo.y,
                    Field::Blue => defaults.albedo.z,
                    Field::X | Field::Y | Field::Z => {
                        return Err(bad(format!(
                            "element {element} {}: property {} is missing",
                            index_of(i),
                            names[0]
                        )));
                    }
                    Field::Age | Field::Vx | Field::Vy | Field::Vz => 0.0,
                },
            };
            let what = || format!("element {element} {}: property {}", index_of(i), names[0]);
            if !value.is_finite() {
                return Err(bad(format!("{} = {value}: must be finite", what())));
            }
            let range_error = match field {
                Field::Radius if value <= 0.0 => Some("must be > 0"),
                Field::Density if value < 0.0 => Some("must be >= 0"),
                Field::Red | Field::Green | Field::Blue if !(0.0..=1.0).contains(&value) => {
                    Some("must be in [0, 1]")
                }
                Field::Age if value < 0.0 => Some("must be >= 0"),
                _ => None,
            };
            if let Some(range) = range_error {
                return Err(bad(format!("{} = {value}: {range}", what())));
            }
            v[*field as usize] = value;
        }
        particles.push(Particle {
            position: Vec3::new(v[0], v[1], v[2]),
            radius_m: v[3],
            density_per_m: v[4],
            albedo: Vec3::new(v[5], v[6], v[7]),
            age_s: v[8],
            velocity: Vec3::new(v[9], v[10], v[11]),
        });
    }
    Ok(particles)
}

/// Reads the particle file `path` of `files` ([`parse`]).
pub fn read(
    files: &Files,
    path: &Path,
    defaults: &Defaults,
) -> Result<Vec<Particle>, ParticleFileError> {
    // The format first: a file of no known kind is named as such whether or not it exists.
    Format::of_path(path).ok_or_else(|| ParticleFileError::UnknownFormat {
        path: path.to_owned(),
    })?;
    let bytes = files.read(path).map_err(|cause| ParticleFileError::Read {
        path: path.to_owned(),
        cause,
    })?;
    parse(path, &bytes, defaults)
}

/// The particles of a file's `bytes`, its format from `path`'s extension (a `.ply` may be
/// binary or ASCII); `path` names the file in errors.
pub fn parse(
    path: &Path,
    bytes: &[u8],
    defaults: &Defaults,
) -> Result<Vec<Particle>, ParticleFileError> {
    match Format::of_path(path) {
        Some(Format::Ply | Format::PlyAscii) => ply_file::parse(path, bytes, defaults),
        Some(Format::Csv) => csv_file::parse(path, bytes, defaults),
        None => Err(ParticleFileError::UnknownFormat {
            path: path.to_owned(),
        }),
    }
}

/// The bytes of a particle file of `format` holding `particles`, or why they cannot be written.
pub fn encode(particles: &[Particle], format: Format) -> Result<Vec<u8>, String> {
    match format {
        Format::Ply => ply_file::encode(particles, false),
        Format::PlyAscii => ply_file::encode(particles, true),
        Format::Csv => csv_file::encode(particles),
    }
}

pub use crate::scene::sequence::{frame_name, is_sequence, sequence_frame};

impl ParticleSource {
    /// The frame of a sequence at simulated time `time_s` ([`sequence_frame`]).
    pub fn frame_at(&self, time_s: f32) -> i64 {
        sequence_frame(self.frame_at_zero, self.frame_rate_hz, time_s)
    }

    /// The file to read at `time_s`: the file itself, or the sequence's frame, relative to the
    /// scene file's folder.
    pub fn path_at(&self, time_s: f32) -> PathBuf {
        self.folder
            .join(frame_name(&self.file, self.frame_at(time_s)))
    }

    /// The defaults for the properties a file lacks.
    pub fn defaults(&self) -> Defaults {
        Defaults {
            radius_m: self.radius_m,
            density_per_m: self.density_per_m,
            albedo: self.albedo,
        }
    }

    /// The particles at `time_s` (the frame of a sequence at that time).
    pub fn particles_at(&self, time_s: f32) -> Result<Vec<Particle>, ParticleFileError> {
        read(&self.folder.files, &self.path_at(time_s), &self.defaults())
    }
}

/// The particles of `scene`'s frame: read from its particle file when it has one
/// (`[particles]`), else `simulate`d from its emitters to `sim.duration_s`
/// ([`crate::sim::simulate`], or an app's with a progress bar).
pub fn frame_particles(
    scene: &Scene,
    simulate: impl FnOnce(&Scene) -> Vec<Particle>,
) -> Result<Vec<Particle>, ParticleFileError> {
    match &scene.particles {
        Some(source) => source.particles_at(scene.sim.duration_s),
        None => Ok(simulate(scene)),
    }
}

/// How many particles `scene`'s frame has: its emitters' pools, or its particle file's count
/// (0 when the file cannot be read; reading it for the frame reports why).
pub fn count(scene: &Scene) -> u64 {
    match &scene.particles {
        Some(source) => source
            .particles_at(scene.sim.duration_s)
            .map_or(0, |p| p.len() as u64),
        None => scene.particle_count(),
    }
}

/// What was loaded: for the viewer's scene panel and `particles`' summary line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Summary {
    pub count: usize,
    pub min: Vec3,
    pub max: Vec3,
    pub min_density_per_m: f32,
    pub max_density_per_m: f32,
}

impl Summary {
    /// The count, the bounds of the particles' spheres and the extinction range.
    pub fn of(particles: &[Particle]) -> Self {
        let mut s = Self {
            count: particles.len(),
            min: Vec3::splat(f32::INFINITY),
            max: Vec3::splat(f32::NEG_INFINITY),
            min_density_per_m: f32::INFINITY,
            max_density_per_m: f32::NEG_INFINITY,
        };
        for p in particles {
            s.min = s.min.min(p.position - Vec3::splat(p.radius_m));
            s.max = s.max.max(p.position + Vec3::splat(p.radius_m));
            s.min_density_per_m = s.min_density_per_m.min(p.density_per_m);
            s.max_density_per_m = s.max_density_per_m.max(p.density_per_m);
        }
        s
    }

    /// The summary of two sets of particles together (an empty one changes nothing).
    pub fn union(&self, other: &Self) -> Self {
        Self {
            count: self.count + other.count,
            min: self.min.min(other.min),
            max: self.max.max(other.max),
            min_density_per_m: self.min_density_per_m.min(other.min_density_per_m),
            max_density_per_m: self.max_density_per_m.max(other.max_density_per_m),
        }
    }
}

impl std::fmt::Display for Summary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} particles, bounds [{:.2}, {:.2}, {:.2}] .. [{:.2}, {:.2}, {:.2}] m, extinction {:.3} .. {:.3} /m",
            self.count,
            self.min.x,
            self.min.y,
            self.min.z,
            self.max.x,
            self.max.y,
            self.max.z,
            self.min_density_per_m,
            self.max_density_per_m
        )
    }
}

/// A scene argument of any command and of the viewer's Open: a particle file (`.ply`, `.csv`:
/// [`scene_for_file`]), a volume file (`.vdb`: [`scene_for_volume_file`]),
/// an embedded scene's name or a scene file ([`Scene::open`]); the
/// embedded thesis scene when `None`.
pub fn open_scene(arg: Option<&Path>, files: &Files) -> anyhow::Result<Scene> {
    Ok(match arg {
        Some(path) if Format::of_path(path).is_some() => scene_for_file(path, files)?,
        Some(path) if is_volume_file(path) => scene_for_volume_file(path, files)?,
        arg => Scene::load_or_default(arg, files)?,
    })
}

/// The farthest a bare file's particles may lie from the origin, metres: the framing scales the
/// light's intensity with the square of the smoke's size, and f32 coordinates have about a
/// tenth of a metre of precision out there.
pub const MAX_FRAMED_COORDINATE_M: f32 = 1e6;
/// The smallest extent a bare file's smoke may have, as a fraction of its distance from the
/// origin: 2^-13, about a thousand float steps across, so that its particles' positions, chords
/// and shadow-map depths are not dominated by rounding.
pub const MIN_FRAMED_EXTENT_RATIO: f32 = 1.0 / 8192.0;

/// The size (the largest side of the particles' bounds) and the centre of a bare file's smoke,
/// or why it cannot be framed, named in terms of the particles.
fn framing_extent(bounds: &Summary) -> Result<(f32, Vec3), String> {
    if bounds.count == 0 {
        return Err("it holds no particles to frame".to_owned());
    }
    let far = bounds.min.abs().max(bounds.max.abs()).max_element();
    if far.is_nan() || far > MAX_FRAMED_COORDINATE_M {
        return Err(format!(
            "its particles reach {far:e} m from the origin (bounds {:?} .. {:?} m): smokeshadow frames particles within {MAX_FRAMED_COORDINATE_M:e} m of it, so move them nearer or change their units",
            bounds.min.to_array(),
            bounds.max.to_array()
        ));
    }
    let size = (bounds.max - bounds.min).max_element();
    let centre = 0.5 * (bounds.min + bounds.max);
    let from_origin = centre.abs().max_element();
    if !(size > 0.0 && size >= from_origin * MIN_FRAMED_EXTENT_RATIO) {
        return Err(format!(
            "its particles span {size:e} m at {from_origin:e} m from the origin, too small to frame in f32 there (at least 1/{} of the distance): move them nearer the origin",
            1.0 / MIN_FRAMED_EXTENT_RATIO
        ));
    }
    Ok((size, centre))
}

/// Turns the thesis scene's camera and spotlight on the smoke in the box `min`..`max` (world
/// metres): both keep the thesis scene's directions and are moved out to frame the box as the
/// thesis scene frames its plume; the light's intensity is scaled with its distance squared, so
/// the smoke receives the thesis' irradiance. The ground is put under the box, the thesis box
/// and emitters are left out. Errs, naming the problem, for a box that cannot be framed in f32.
pub fn frame_bounds(scene: &mut Scene, min: Vec3, max: Vec3) -> Result<(), String> {
    let bounds = Summary {
        count: 1,
        min,
        max,
        min_density_per_m: 0.0,
        max_density_per_m: 0.0,
    };
    let (size, centre) = framing_extent(&bounds)?;
    // The thesis plume's framing: the camera's and light's offsets from its target, for a
    // plume of this size (between the 5 m the plume looks and the 8.1 m its particles' bounds
    // span at t = 8 s: a bare file's bounds are often a tight box, and get some margin).
    const THESIS_PLUME_SIZE_M: f32 = 6.0;
    let k = size / THESIS_PLUME_SIZE_M;
    let cam = &mut scene.camera;
    let cam_offset = (cam.position - cam.target) * k;
    cam.target = centre;
    cam.position = centre + cam_offset;
    cam.near_m = (cam.near_m * k).max(1e-4);
    cam.far_m *= k.max(1.0);
    let light = &mut scene.light;
    let light_offset = (light.position - light.target) * k;
    light.target = centre;
    light.position = centre + light_offset;
    light.intensity *= k * k;
    scene.ground.height_m = min.y;
    // The ground square is centred on the origin: it reaches under smoke far from it too.
    let reach = 2.0 * (centre.x.abs().max(centre.z.abs()) + size);
    scene.ground.size_m = (scene.ground.size_m * k)
        .max(scene.ground.size_m)
        .max(reach);
    scene.boxes.clear();
    scene.emitters.clear();
    Ok(())
}

/// A scene for a bare particle file (`smokeshadow render smoke.ply`, the viewer's Open): the
/// thesis scene's lighting, shading and shadow settings, its camera and spotlight turned on the
/// particles. Both keep the thesis scene's directions and are moved out to frame the particles'
/// bounds as the thesis scene frames its plume; the light's intensity is scaled with its
/// distance squared, so the smoke receives the thesis' irradiance. The ground is put under the
/// particles, and the thesis box is left out.
pub fn scene_for_file(path: &Path, files: &Files) -> Result<Scene, ParticleFileError> {
    let source = ParticleSource {
        file: path.to_string_lossy().into_owned(),
        folder: Folder::new("", files.clone()),
        ..ParticleSource::default()
    };
    let particles = source.particles_at(Scene::thesis_plume().sim.duration_s)?;
    let description = format!("particles of {}", path.display());
    bare_scene(path, source, &Summary::of(&particles), description)
}

/// The thesis scene framed on `bounds` (its `source`'s particles, [`frame_bounds`]), with them
/// in place of its emitters, named after `path`.
fn bare_scene(
    path: &Path,
    source: ParticleSource,
    bounds: &Summary,
    description: String,
) -> Result<Scene, ParticleFileError> {
    let mut scene = Scene::thesis_plume();
    framing_extent(bounds)
        .and_then(|_| frame_bounds(&mut scene, bounds.min, bounds.max))
        .map_err(|m| ParticleFileError::invalid(path, m))?;
    scene.particles = Some(source);
    scene.name = path
        .file_stem()
        .map_or("particles".into(), |s| s.to_string_lossy().into_owned());
    scene.description = description;
    scene
        .validate()
        .map_err(|message| ParticleFileError::invalid(path, message))?;
    Ok(scene)
}

/// The numbered sequence of particle or volume files `names` make (`smoke.0001.ply`,
/// `smoke.0002.ply`, ...): its pattern (`smoke.%04d.ply`, or `%d` where the numbers are not
/// zero-padded) and its frames, ascending. `None` unless there are two or more names, of one
/// format, that differ only in the last number of the name.
pub fn sequence_of(names: &[String]) -> Option<(String, Vec<i64>)> {
    let known = |n: &String| {
        let path = Path::new(n);
        Format::of_path(path).is_some() || is_volume_file(path)
    };
    if names.len() < 2 || !names.iter().all(known) {
        return None;
    }
    // (before the number, its digits, after it)
    let split = |name: &str| -> Option<(String, String, String)> {
        let bytes = name.as_bytes();
        let end = bytes.iter().rposition(u8::is_ascii_digit)? + 1;
        let start = bytes[..end]
            .iter()
            .rposition(|b| !b.is_ascii_digit())
            .map_or(0, |i| i + 1);
        Some((
            name[..start].to_owned(),
            name[start..end].to_owned(),
            name[end..].to_owned(),
        ))
    };
    let parts: Vec<_> = names.iter().map(|n| split(n)).collect::<Option<_>>()?;
    let (prefix, first_digits, suffix) = &parts[0];
    if suffix.contains(|c: char| c.is_ascii_digit()) || prefix.contains('%') {
        return None;
    }
    let same_width = parts.iter().all(|p| p.1.len() == first_digits.len());
    let padded = parts.iter().any(|p| p.1.len() > 1 && p.1.starts_with('0'));
    let number = match (same_width, padded) {
        (true, _) => format!("%0{}d", first_digits.len()),
        (false, false) => "%d".to_owned(),
        (false, true) => return None,
    };
    let mut frames = Vec::with_capacity(parts.len());
    for (p, digits, s) in &parts {
        if p != prefix || s != suffix {
            return None;
        }
        frames.push(digits.parse::<i64>().ok()?);
    }
    frames.sort_unstable();
    frames.dedup();
    (frames.len() == names.len()).then(|| (format!("{prefix}{number}{suffix}"), frames))
}

/// The scene of a bare sequence of particle or volume files (`pattern`, its `frames` in
/// `files`, [`sequence_of`]) at `frame`: framed (and a volume's density scaled) as one bare
/// file is ([`scene_for_file`], [`scene_for_volume_file`]), over every frame's smoke together,
/// so that the camera and light hold still from frame to frame ([`show_sequence_frame`]).
pub fn scene_for_sequence(
    pattern: &str,
    frames: &[i64],
    frame: i64,
    files: &Files,
) -> anyhow::Result<Scene> {
    match is_volume_file(Path::new(pattern)) {
        true => scene_for_volume_sequence(pattern, frames, frame, files),
        false => Ok(scene_for_particle_sequence(pattern, frames, frame, files)?),
    }
}

/// [`scene_for_sequence`] of particle files.
fn scene_for_particle_sequence(
    pattern: &str,
    frames: &[i64],
    frame: i64,
    files: &Files,
) -> Result<Scene, ParticleFileError> {
    let duration = Scene::thesis_plume().sim.duration_s;
    let mut source = ParticleSource {
        file: pattern.to_owned(),
        folder: Folder::new("", files.clone()),
        ..ParticleSource::default()
    };
    let mut all = Summary::of(&[]);
    for &f in frames {
        source.frame_at_zero = frame_at_zero_for(&source, duration, f);
        all = all.union(&Summary::of(&source.particles_at(duration)?));
    }
    source.frame_at_zero = frame_at_zero_for(&source, duration, frame);
    let description = sequence_description(pattern, frame);
    bare_scene(Path::new(pattern), source, &all, description)
}

/// What a sequence's scene at `frame` says it holds.
fn sequence_description(pattern: &str, frame: i64) -> String {
    format!("particles of {}, frame {frame}", frame_name(pattern, frame))
}

/// Moves a sequence's scene ([`scene_for_sequence`]) to `frame`: the frame its time shows.
pub fn show_sequence_frame(scene: &mut Scene, frame: i64) {
    if scene.volume.as_ref().is_some_and(|v| v.is_sequence()) {
        return show_volume_frame(scene, frame);
    }
    let duration = scene.sim.duration_s;
    if let Some(source) = &mut scene.particles {
        source.frame_at_zero = frame_at_zero_for(source, duration, frame);
        scene.description = sequence_description(&source.file, frame);
    }
}

/// The `frame_at_zero` at which time `time_s` shows `frame` of `source`.
fn frame_at_zero_for(source: &ParticleSource, time_s: f32, frame: i64) -> i64 {
    frame - sequence_frame(0, source.frame_rate_hz, time_s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sequence_patterns_name_their_frames() {
        assert_eq!(frame_name("smoke.%04d.ply", 7), "smoke.0007.ply");
        assert_eq!(frame_name("s_%d.csv", 12), "s_12.csv");
        assert_eq!(frame_name("one.ply", 3), "one.ply");
        assert!(is_sequence("a/%03d.ply") && !is_sequence("100%.ply"));
    }

    #[test]
    fn a_numbered_sequence_is_found_among_dropped_names() {
        let names = |list: &[&str]| list.iter().map(|s| (*s).to_owned()).collect::<Vec<_>>();
        assert_eq!(
            sequence_of(&names(&[
                "smoke.0002.ply",
                "smoke.0000.ply",
                "smoke.0001.ply"
            ])),
            Some(("smoke.%04d.ply".to_owned(), vec![0, 1, 2]))
        );
        assert_eq!(
            sequence_of(&names(&["s_9.csv", "s_10.csv"])),
            Some(("s_%d.csv".to_owned(), vec![9, 10]))
        );
        // One file, two patterns, other formats, a number padded in one and not the other.
        assert_eq!(sequence_of(&names(&["smoke.0001.ply"])), None);
        assert_eq!(sequence_of(&names(&["a.0001.ply", "b.0002.ply"])), None);
        assert_eq!(
            sequence_of(&names(&["a.0001.vdb", "a.0002.vdb"])),
            Some(("a.%04d.vdb".to_owned(), vec![1, 2]))
        );
        assert_eq!(sequence_of(&names(&["a.0001.vdb", "a.0002.ply"])), None);
        assert_eq!(sequence_of(&names(&["a.0001.toml", "a.0002.toml"])), None);
        assert_eq!(sequence_of(&names(&["a.ply", "b.ply"])), None);
        assert_eq!(sequence_of(&names(&["a_01.ply", "a_100.ply"])), None);
    }

    #[test]
    fn every_property_name_maps_back_to_its_field() {
        for (field, names, _) in PROPERTIES {
            for name in *names {
                assert_eq!(field_of(name), Some(*field), "{name}");
                assert_eq!(field_of(&name.to_uppercase()), Some(*field), "{name}");
            }
        }
        assert_eq!(field_of("Cd"), None);
        assert_eq!(field_of("nx"), None);
    }
}
