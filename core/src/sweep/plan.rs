//! The cells a sweep lays out ([`plan`]: the `none` baseline, then per shadow resolution,
//! splat mode and technique its channel and byte budgets, with the cells it cannot run and
//! why), each cell's name and configuration ([`Plan`]), what its settings key records
//! ([`settings_key`]), and when a cell has timed enough frames ([`timed_enough`]). The CLI's
//! sweep and the web page's plan through here, so that one grid gives the same cells in both.

use super::SkippedCell;
use crate::render::{ParticleRes, RenderOptions, TechniqueConfig};
use crate::scene::Scene;
use crate::shadow::{self, SplatMode};

/// The axes of a sweep: what [`plan`] lays out cells over.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    pub techniques: Vec<String>,
    pub channels: Vec<u32>,
    /// Byte budgets per shadow-map texel (`--bytes-per-texel`): each technique at the largest
    /// configuration whose resident bytes fit each ([`shadow::fit_bytes_per_texel`]); may be
    /// empty.
    pub bytes_per_texel: Vec<u32>,
    /// Memory budgets in total bytes (`--memory`): at each map resolution, each technique at
    /// the largest configuration whose resident bytes fit; may be empty.
    pub memory: Vec<u64>,
    pub shadow_res: Vec<u32>,
    pub splats: Vec<SplatMode>,
    /// Resolutions of the particle pass (`--particle-res`; each its own cell).
    pub particle_res: Vec<ParticleRes>,
}

/// How each cell is timed, as its settings key records it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellTiming {
    /// Timed frames per cell (medians over these) and untimed warm-up frames before them.
    pub frames: u32,
    pub warmup: u32,
    /// Seconds of timed frames a cell keeps within ([`timed_enough`]).
    pub cell_seconds: f64,
    /// `--animate`: every cell also rendered over these consecutive frames.
    pub animate: Option<crate::motion::Span>,
}

impl CellTiming {
    /// Refuses, in one line, timing that measures nothing.
    pub fn check(&self) -> anyhow::Result<()> {
        if self.frames == 0 {
            anyhow::bail!("--frames 0: time at least one frame");
        }
        Ok(())
    }
}

/// Parses one memory size (`--memory`, the page's memory budgets): a number and a unit (B, KiB,
/// MiB, GiB, KB, MB, GB), whole bytes.
pub fn parse_memory(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let scale: u64 = match unit.trim() {
        "B" => 1,
        "KiB" => 1 << 10,
        "MiB" => 1 << 20,
        "GiB" => 1 << 30,
        "KB" => 1_000,
        "MB" => 1_000_000,
        "GB" => 1_000_000_000,
        _ => {
            return Err(format!(
                "\"{t}\" is not a memory size: give a number and a unit, B, KiB, MiB, GiB, KB, MB \
                 or GB (e.g. 12MiB)"
            ));
        }
    };
    let bytes = number.parse::<f64>().ok().map(|n| n * scale as f64);
    match bytes {
        Some(b) if b >= 1.0 && b.fract() == 0.0 && b <= 1e12 => Ok(b as u64),
        _ => Err(format!(
            "\"{t}\" is not a memory size: give whole bytes, 1 B to 1 TB (e.g. 12MiB)"
        )),
    }
}

/// The default byte budgets per texel: what `osm`'s half-float slices take at 6, 12 and 24
/// channels, the thesis' range.
pub const DEFAULT_BYTES_PER_TEXEL: [u32; 3] = [48, 24, 12];

/// Timed frames a cell takes at least, whatever `cell_seconds` says (fewer only when
/// `frames` asks for fewer, or [`MIN_SLOW_FRAMES`] when each frame outlasts `cell_seconds`).
pub const MIN_TIMED_FRAMES: u32 = 3;
/// Timed frames a cell takes at least when every frame took longer than `cell_seconds` on its
/// own: a deep capture's frames of seconds on lavapipe vary by a few percent, and a third one
/// would cost `dsm` 2.3 s a cell.
pub const MIN_SLOW_FRAMES: u32 = 2;

/// Whether a cell has timed enough frames (`frame_s`, wall seconds each) after `elapsed_s` of
/// timing: `frames` of them; or at least [`MIN_TIMED_FRAMES`], once one more frame, as long as
/// the frames so far took on average, would take the timing past `cell_seconds`; or
/// [`MIN_SLOW_FRAMES`] when each of them alone took longer than `cell_seconds`.
pub fn timed_enough(frame_s: &[f64], elapsed_s: f64, frames: u32, cell_seconds: f64) -> bool {
    let n = frame_s.len() as u32;
    if n >= frames {
        return true;
    }
    if n >= MIN_TIMED_FRAMES {
        return elapsed_s + elapsed_s / f64::from(n) > cell_seconds;
    }
    n >= MIN_SLOW_FRAMES && frame_s.iter().all(|&s| s > cell_seconds)
}

/// The budget every cell's "own baseline" uses (the thesis' baselines).
pub const BASELINE_CHANNELS: u32 = 24;

/// One planned cell.
#[derive(Clone, Debug)]
pub struct Plan {
    pub name: String,
    pub config: TechniqueConfig,
    pub particle_res: ParticleRes,
    /// The byte budgets per texel this cell is the technique's configuration for.
    pub byte_budgets: Vec<u32>,
    /// The memory budgets (total bytes) it is the configuration for at its resolution.
    pub memory_budgets: Vec<u64>,
    /// Whether a channel budget asked for it (else only byte budgets did).
    pub channel_axis: bool,
}

impl Plan {
    pub fn new(scene: &Scene, technique: &str, channels: u32, res: u32, splat: SplatMode) -> Self {
        let mut params = scene.shadow.params(channels);
        params.resolution_px = res;
        params.splat = splat;
        let name = if technique == shadow::frame_baseline().name {
            technique.to_owned()
        } else {
            format!("{technique}_{channels}_{res}_{}", splat.name())
        };
        Self {
            name,
            config: TechniqueConfig {
                name: technique.to_owned(),
                params,
            },
            particle_res: ParticleRes::Full,
            byte_budgets: Vec::new(),
            memory_budgets: Vec::new(),
            channel_axis: true,
        }
    }

    /// The same cell with the particle pass at `res`: its name gains `_p2` or `_p4` (a
    /// full-resolution cell keeps the name it always had).
    pub fn at(mut self, res: ParticleRes) -> Self {
        if res != ParticleRes::Full {
            self.name = format!("{}_p{}", self.name, res.divisor());
        }
        self.particle_res = res;
        self
    }

    /// The cell its errors are measured against besides `exact`: the technique's own
    /// 24-channel cell ([`BASELINE_CHANNELS`]) at its map resolution, splat and particle
    /// resolution.
    pub fn own_baseline(&self, scene: &Scene) -> Self {
        let p = &self.config.params;
        Self::new(
            scene,
            &self.config.name,
            BASELINE_CHANNELS,
            p.resolution_px,
            p.splat,
        )
        .at(self.particle_res)
    }

    /// Its frame's file, relative to the scene's folder.
    pub fn image(&self) -> String {
        format!("images/{}.png", self.name)
    }

    pub fn options(&self) -> RenderOptions {
        RenderOptions {
            particle_res: self.particle_res,
            ..RenderOptions::default()
        }
    }
}

/// Checks the options and lays out the cells: the `none` baseline, then per resolution, splat
/// mode and technique its budgets. Budgets below a technique's minimum are skipped with a note;
/// techniques that ignore the splat mode run once per resolution.
pub fn plan(scene: &Scene, options: &Grid) -> anyhow::Result<(Vec<Plan>, Vec<SkippedCell>)> {
    let non_empty = |what: &str, empty: bool| {
        if empty {
            anyhow::bail!("--{what} is empty: give at least one value");
        }
        Ok(())
    };
    non_empty("techniques", options.techniques.is_empty())?;
    non_empty("channels", options.channels.is_empty())?;
    // The largest channel budget any technique takes (`has`'s slices, above the maps' 32).
    let most_channels = shadow::REGISTRY
        .iter()
        .map(|e| e.max_channels)
        .max()
        .unwrap_or(shadow::MAX_CHANNELS);
    non_empty("shadow-res", options.shadow_res.is_empty())?;
    non_empty("splat", options.splats.is_empty())?;
    non_empty("particle-res", options.particle_res.is_empty())?;
    for &res in &options.shadow_res {
        if !(1..=8192).contains(&res) {
            anyhow::bail!("--shadow-res {res} is out of range: allowed 1..=8192");
        }
    }
    let mut cells = vec![
        Plan::new(
            scene,
            shadow::frame_baseline().name,
            1,
            options.shadow_res[0],
            options.splats[0],
        )
        .at(options.particle_res[0]),
    ];
    let mut skipped = Vec::new();
    // What the scene's smoke holds, for the techniques that cannot shadow it (`srm` particles,
    // `has` a density volume): noted, not measured.
    let smoke = (
        scene.volume.is_some(),
        crate::particles::count(scene) as usize,
    );
    // Why a technique cannot run on this scene at all: its smoke, or its shadow history.
    let refused = |entry: &shadow::TechniqueEntry| {
        entry
            .refusal(smoke.0, smoke.1)
            .or_else(|| entry.history_refusal(scene.shadow.history))
    };
    for name in &options.techniques {
        let entry = shadow::find(name)?;
        if entry.role != shadow::Role::Contender {
            anyhow::bail!(
                "--techniques {name}: `{}` and `{}` are the sweep's baseline and reference, always measured; list the techniques to compare",
                shadow::frame_baseline().name,
                shadow::reference().name
            );
        }
        if let Some(refusal) = refused(entry) {
            skipped.push(SkippedCell {
                technique: entry.name.to_owned(),
                channels: first_budget(entry, &options.channels).unwrap_or(options.channels[0]),
                bytes_per_texel: None,
                memory: None,
                reason: refusal.to_string(),
            });
            continue;
        }
        for &b in &options.channels {
            if !(1..=most_channels).contains(&b) {
                let beyond: Vec<String> = shadow::REGISTRY
                    .iter()
                    .filter(|e| e.max_channels > shadow::MAX_CHANNELS)
                    .map(|e| format!("{} to {}", e.name, e.max_channels))
                    .collect();
                anyhow::bail!(
                    "--channels {b} is out of range: allowed 1..={most_channels} (above {}: {})",
                    shadow::MAX_CHANNELS,
                    beyond.join(", ")
                );
            }
            if let Err(err) = shadow::check_channels(entry, b) {
                skipped.push(SkippedCell {
                    technique: entry.name.to_owned(),
                    channels: b,
                    bytes_per_texel: None,
                    memory: None,
                    reason: err.to_string(),
                });
            } else if !entry.uses_budget && Some(b) != first_budget(entry, &options.channels) {
                skipped.push(SkippedCell {
                    technique: entry.name.to_owned(),
                    channels: b,
                    bytes_per_texel: None,
                    memory: None,
                    reason: format!(
                        "{} gives the same result at any budget ({}): measured once, at {} channels",
                        entry.name,
                        (entry.budget_caption)(b),
                        first_budget(entry, &options.channels).unwrap_or(b)
                    ),
                });
            }
        }
    }
    for &particle_res in &options.particle_res {
        if particle_res == ParticleRes::Full {
            continue;
        }
        for name in &options.techniques {
            let entry = shadow::find(name)?;
            if entry.owns_particle_pass
                && let Some(b) = first_budget(entry, &options.channels)
            {
                skipped.push(SkippedCell {
                    technique: entry.name.to_owned(),
                    channels: b,
                    bytes_per_texel: None,
                    memory: None,
                    reason: shadow::ShadowError::ParticleResUnsupported {
                        technique: entry.name,
                        res: particle_res.name(),
                    }
                    .to_string(),
                });
            }
        }
    }
    for &res in &options.shadow_res {
        for &particle_res in &options.particle_res {
            for (s, &splat) in options.splats.iter().enumerate() {
                for name in &options.techniques {
                    let entry = shadow::find(name)?;
                    if s > 0 && !entry.uses_splat
                        || particle_res != ParticleRes::Full && entry.owns_particle_pass
                        || refused(entry).is_some()
                    {
                        continue;
                    }
                    for &b in &options.channels {
                        let once =
                            entry.uses_budget || Some(b) == first_budget(entry, &options.channels);
                        if shadow::check_channels(entry, b).is_ok() && once {
                            cells
                                .push(Plan::new(scene, entry.name, b, res, splat).at(particle_res));
                        }
                    }
                    let first_axes = s == 0 && particle_res == options.particle_res[0];
                    for &total in &options.memory {
                        let planned = shadow::memory_per_texel(total, res).and_then(|bytes| {
                            plan_byte_budget(
                                scene,
                                entry,
                                Budget::Memory(bytes, total),
                                (res, splat, particle_res),
                                &mut cells,
                            )
                        });
                        if let Err(reason) = planned
                            && first_axes
                        {
                            skipped.push(SkippedCell {
                                technique: entry.name.to_owned(),
                                channels: 0,
                                bytes_per_texel: None,
                                memory: Some((total, res)),
                                reason,
                            });
                        }
                    }
                    for &bytes in &options.bytes_per_texel {
                        if let Err(reason) = plan_byte_budget(
                            scene,
                            entry,
                            Budget::PerTexel(bytes),
                            (res, splat, particle_res),
                            &mut cells,
                        ) && first_axes
                            && res == options.shadow_res[0]
                        {
                            skipped.push(SkippedCell {
                                technique: entry.name.to_owned(),
                                channels: 0,
                                bytes_per_texel: Some(bytes),
                                memory: None,
                                reason,
                            });
                        }
                    }
                }
            }
        }
    }
    Ok((cells, skipped))
}

/// Adds `bytes` per texel to the cell of `entry`'s configuration that fits it (the
/// [`shadow::fit_bytes_per_texel`] at the scene's particles and frame): a cell already planned
/// with the same channels used (a channel budget's, or another byte budget's) answers it too;
/// else a new cell, off the channel axis. A technique whose result does not depend on the
/// budget answers every byte budget it fits with its one cell. The cell's technique is held to
/// the smallest budget's bytes ([`shadow::TechniqueParams::memory_limit_bytes`]). `Err`: why
/// it fits none.
fn plan_byte_budget(
    scene: &Scene,
    entry: &'static shadow::TechniqueEntry,
    budget: Budget,
    (res, splat, particle_res): (u32, SplatMode, ParticleRes),
    cells: &mut Vec<Plan>,
) -> Result<(), String> {
    let bytes = match budget {
        Budget::PerTexel(b) | Budget::Memory(b, _) => b,
    };
    let record = |p: &mut Plan| match budget {
        Budget::PerTexel(b) => p.byte_budgets.push(b),
        Budget::Memory(_, total) => p.memory_budgets.push(total),
    };
    let base = Plan::new(scene, entry.name, entry.min_channels, res, splat).at(particle_res);
    let particles = crate::particles::count(scene);
    let pixels = u64::from(scene.output.width_px) * u64::from(scene.output.height_px);
    let fit = shadow::fit_bytes_per_texel(entry, &base.config.params, bytes, particles, pixels)?;
    let used = |p: &Plan| shadow::planned_use(entry, &p.config.params, particles, pixels);
    let same = cells.iter_mut().find(|p| {
        p.config.name == entry.name
            && p.config.params.resolution_px == res
            && p.config.params.splat == splat
            && p.particle_res == particle_res
            && (!entry.uses_budget || used(p) == (fit.channels_used, fit.bytes_per_texel))
    });
    // The cell holds itself to the smallest byte budget it answers: its build sheds scratch
    // to fit (more slabs or bands: time for bytes), so its resident bytes are within each.
    let limit = u64::from(bytes) * u64::from(res).pow(2);
    let hold = |p: &mut Plan| {
        let params = &mut p.config.params;
        params.memory_limit_bytes = Some(params.memory_limit_bytes.map_or(limit, |l| l.min(limit)));
    };
    match same {
        Some(p) => {
            record(p);
            hold(p);
        }
        None => {
            let mut p = Plan::new(scene, entry.name, fit.channels, res, splat).at(particle_res);
            record(&mut p);
            p.channel_axis = false;
            hold(&mut p);
            cells.push(p);
        }
    }
    Ok(())
}

/// A byte budget: per texel (`--bytes-per-texel`), or a total (`--memory`) with the bytes a
/// texel it is at the cell's resolution.
#[derive(Clone, Copy, Debug)]
enum Budget {
    PerTexel(u32),
    Memory(u32, u64),
}

/// The first of `budgets` that `entry` accepts: where a technique whose result does not depend
/// on the budget is measured.
pub fn first_budget(entry: &shadow::TechniqueEntry, budgets: &[u32]) -> Option<u32> {
    budgets
        .iter()
        .copied()
        .find(|&b| shadow::check_channels(entry, b).is_ok())
}

/// What a cell's measurement depends on, as a string (`--resume` reuses a cell only when equal).
/// `scene_sha256` is the scene's [`Scene::content_hash`], computed once per scene (for a particle
/// file it reads and hashes the file).
pub fn settings_key(scene: &Scene, scene_sha256: &str, timing: &CellTiming, plan: &Plan) -> String {
    // A full-resolution cell's key is the one it had before the particle resolution was an
    // axis, so earlier sweeps' cells stay reusable.
    let particle_res = match plan.particle_res {
        ParticleRes::Full => String::new(),
        res => format!(" particle_res={res}"),
    };
    // Likewise a still cell's: the span (all of it, as its record writes it) is added only to
    // an animated sweep's.
    let animate = timing.animate.map_or(String::new(), |s| {
        format!(
            " animate={}",
            serde_json::to_string(&s).expect("a span serialises")
        )
    });
    format!(
        "tool={} scene={} size={}x{} frames={} warmup={} cell_seconds={} exact=closed-form technique={} params={}{particle_res}{animate}",
        env!("CARGO_PKG_VERSION"),
        scene_sha256,
        scene.output.width_px,
        scene.output.height_px,
        timing.frames,
        timing.warmup,
        timing.cell_seconds,
        plan.config.name,
        serde_json::to_string(&plan.config.params).expect("params serialise"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_time_three_frames_or_two_slow_ones_within_their_seconds() {
        // Timing goes on while one more frame of the average so far fits in the seconds, up to
        // `frames`.
        assert!(!timed_enough(&[0.1; 4], 0.4, 20, 0.5));
        assert!(timed_enough(&[0.1; 5], 0.5, 20, 0.5));
        assert!(!timed_enough(&[0.02; 19], 0.38, 20, 0.5));
        assert!(timed_enough(&[0.02; 20], 0.4, 20, 0.5));
        // Four frames of 0.12 s: a fifth would end at 0.6 s.
        assert!(timed_enough(&[0.12; 4], 0.48, 20, 0.5));
        // At least three frames, whatever the seconds ...
        assert!(!timed_enough(&[0.3, 0.3], 0.6, 20, 0.5));
        assert!(timed_enough(&[0.3, 0.3, 0.3], 0.9, 20, 0.5));
        // ... or two when each of them took longer than the seconds on its own.
        assert!(!timed_enough(&[2.3], 2.3, 20, 0.5));
        assert!(timed_enough(&[2.3, 2.2], 4.5, 20, 0.5));
        assert!(!timed_enough(&[2.3, 0.4], 2.7, 20, 0.5));
        // `frames` below the minimum wins.
        assert!(timed_enough(&[2.3], 2.3, 1, 0.5));
    }
}
