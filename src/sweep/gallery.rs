//! The gallery report of a sweep over several scenes (`sweep --scenes`): each scene's sweep
//! lives in `DIR/<scene>/` with its own report; this module writes, at `DIR`, what answers
//! "which technique should I use" across all of them:
//!
//! - [`ranks`]: within each scene and byte budget per texel (equal memory; or, for sweeps run
//!   without byte budgets, each channel budget), the contenders ranked by FLIP mean against
//!   `exact` (ties: fewer bytes first, then registry order). A technique whose result does not
//!   depend on the budget (measured once) is ranked at every budget it fits, with its one
//!   cell. `none` and `exact` are not ranked;
//! - [`ranking`]: for each technique (and resolution and splat, where the sweep varies them)
//!   and budget, the median and the worst rank across scenes, sorted by median, then worst;
//! - where each technique wins (scenes x budgets), and [`advice`]: sentences generated from
//!   those tables, nothing written by hand per technique;
//! - `results.csv` (every scene's cells, a leading `scene` column), `results.json`
//!   ([`GalleryResults`]), `ranking.csv` and `index.html`.
//!
//! Everything is computed from the scenes' [`SweepResults`], so the gallery can be rewritten
//! from them at any time (`--merge` does).

use std::fmt::Write;
use std::path::Path;

use anyhow::Context;
use serde::{Deserialize, Serialize};

use super::answer::FLIP_SPREAD;
use super::{Budget, CSV_COLUMNS, CellResult, SweepResults, registry_index};
use crate::report::{self, escape as e};
use smokeshadow_core::shadow::{self, SplatMode};

/// The columns of `ranking.csv`.
pub const RANKING_COLUMNS: &[&str] = &[
    "technique",
    "shadow_res",
    "splat",
    "budget",
    "scenes",
    "median_rank",
    "worst_rank",
    "worst_scene",
    "motion_median_rank",
];

/// One technique's rank in one scene at one budget.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Rank {
    pub scene: String,
    pub budget: Budget,
    /// The channel budget of the cell ranked (the one that fits a byte budget).
    pub channels: u32,
    pub technique: String,
    pub shadow_res: u32,
    pub splat: SplatMode,
    /// 1 = the lowest FLIP against `exact` at this budget in this scene.
    pub rank: u32,
    /// How many were ranked there.
    pub of: u32,
    pub flip_vs_exact: f64,
    /// Its resident bytes (scratch included, as byte budgets count them).
    pub bytes: u64,
    /// With `--animate`: its rank among the same cells by temporal error (1 = the steadiest
    /// against `exact`), and that error.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion_rank: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temporal_error: Option<f64>,
}

/// A technique's ranks at one budget across the scenes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RankingRow {
    pub technique: String,
    pub shadow_res: u32,
    pub splat: SplatMode,
    pub budget: Budget,
    /// Scenes it was ranked in.
    pub scenes: u32,
    pub median_rank: f64,
    pub worst_rank: u32,
    /// The (first) scene where it ranked worst.
    pub worst_scene: String,
    /// With `--animate`: its median rank by temporal error across the scenes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion_median_rank: Option<f64>,
}

/// What the gallery computed, as written to `DIR/results.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Gallery {
    pub ranks: Vec<Rank>,
    pub ranking: Vec<RankingRow>,
    pub advice: Vec<String>,
}

/// `DIR/results.json`: every scene's results and the gallery computed from them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GalleryResults {
    pub scenes: Vec<SweepResults>,
    #[serde(flatten)]
    pub gallery: Gallery,
}

fn flip(c: &CellResult) -> f64 {
    c.vs_exact.map_or(f64::NAN, |x| x.flip_mean)
}

/// Every contender's rank within each scene and channel budget (budgets largest first).
pub fn ranks(scenes: &[SweepResults]) -> Vec<Rank> {
    let mut out = Vec::new();
    for r in scenes {
        let ranked: Vec<(&CellResult, &'static shadow::TechniqueEntry)> = r
            .cells
            .iter()
            .filter(|c| flip(c).is_finite())
            // Ranks compare shadow techniques: a lower particle resolution is a cost option of
            // the frame, in each scene's table only.
            .filter(|c| c.particle_res == smokeshadow_core::render::ParticleRes::Full)
            .filter_map(|c| shadow::find(&c.technique).ok().map(|e| (c, e)))
            .filter(|(_, e)| e.role == shadow::Role::Contender)
            .collect();
        // Equal bytes where the sweep asked for byte budgets; else the channel budgets.
        let mut budgets: Vec<Budget> = ranked
            .iter()
            .flat_map(|(c, _)| c.byte_budgets.iter().map(|&b| Budget::BytesPerTexel(b)))
            .collect();
        if budgets.is_empty() {
            budgets = ranked
                .iter()
                .map(|(c, _)| Budget::Channels(c.channels))
                .collect();
        }
        budgets.sort_unstable_by_key(|b| b.order());
        budgets.dedup();
        for b in budgets {
            let mut at: Vec<&CellResult> = ranked
                .iter()
                .filter(|(c, e)| match b {
                    Budget::BytesPerTexel(bytes) => c.byte_budgets.contains(&bytes),
                    Budget::Channels(ch) => {
                        c.channels == ch
                            || (!e.uses_budget && shadow::check_channels(e, ch).is_ok())
                    }
                })
                .map(|(c, _)| *c)
                .collect();
            at.sort_by(|x, y| {
                flip(x)
                    .total_cmp(&flip(y))
                    .then(x.resident_bytes.cmp(&y.resident_bytes))
                    .then(registry_index(&x.technique).cmp(&registry_index(&y.technique)))
                    .then(x.shadow_res.cmp(&y.shadow_res))
                    .then(x.splat.name().cmp(y.splat.name()))
            });
            let of = at.len() as u32;
            let steadiest = super::answer::most_stable(&at);
            for (i, c) in at.iter().enumerate() {
                let motion_rank = steadiest
                    .iter()
                    .position(|s| std::ptr::eq(*s, *c))
                    .map(|k| k as u32 + 1);
                out.push(Rank {
                    scene: r.metadata.scene.clone(),
                    budget: b,
                    channels: c.channels,
                    technique: c.technique.clone(),
                    shadow_res: c.shadow_res,
                    splat: c.splat,
                    rank: i as u32 + 1,
                    of,
                    flip_vs_exact: flip(c),
                    bytes: c.resident_bytes,
                    motion_rank,
                    temporal_error: c.motion.as_ref().map(|m| m.temporal_error),
                });
            }
        }
    }
    out
}

/// The median of `values` (the mean of the middle two for an even count); NaN when empty.
fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// For each technique variant and budget: its median and worst rank across scenes, sorted by
/// median rank, then worst rank (then registry order, larger budgets first).
pub fn ranking(ranks: &[Rank]) -> Vec<RankingRow> {
    let mut rows: Vec<(RankingRow, Vec<f64>, Vec<f64>)> = Vec::new();
    for r in ranks {
        let key = (r.technique.as_str(), r.shadow_res, r.splat, r.budget);
        let found = rows.iter_mut().find(|(row, _, _)| {
            (
                row.technique.as_str(),
                row.shadow_res,
                row.splat,
                row.budget,
            ) == key
        });
        match found {
            Some((row, values, moving)) => {
                values.push(r.rank as f64);
                moving.extend(r.motion_rank.map(f64::from));
                row.scenes += 1;
                if r.rank > row.worst_rank {
                    row.worst_rank = r.rank;
                    row.worst_scene = r.scene.clone();
                }
            }
            None => rows.push((
                RankingRow {
                    technique: r.technique.clone(),
                    shadow_res: r.shadow_res,
                    splat: r.splat,
                    budget: r.budget,
                    scenes: 1,
                    median_rank: f64::NAN,
                    worst_rank: r.rank,
                    worst_scene: r.scene.clone(),
                    motion_median_rank: None,
                },
                vec![r.rank as f64],
                r.motion_rank.map(f64::from).into_iter().collect(),
            )),
        }
    }
    let mut rows: Vec<RankingRow> = rows
        .into_iter()
        .map(|(mut row, values, moving)| {
            row.median_rank = median(&values);
            row.motion_median_rank = (!moving.is_empty()).then(|| median(&moving));
            row
        })
        .collect();
    rows.sort_by(|a, b| {
        a.median_rank
            .total_cmp(&b.median_rank)
            .then(a.worst_rank.cmp(&b.worst_rank))
            .then(registry_index(&a.technique).cmp(&registry_index(&b.technique)))
            .then(a.budget.order().cmp(&b.budget.order()))
            .then(a.shadow_res.cmp(&b.shadow_res))
            .then(a.splat.name().cmp(b.splat.name()))
    });
    rows
}

/// Labels for technique variants: the resolution and splat only where the gallery varies them.
struct Labels {
    several_res: bool,
    several_splats: bool,
}

impl Labels {
    fn of(ranks: &[Rank]) -> Self {
        let first = ranks.first();
        Self {
            several_res: ranks
                .iter()
                .any(|r| first.is_some_and(|f| f.shadow_res != r.shadow_res)),
            several_splats: ranks
                .iter()
                .any(|r| first.is_some_and(|f| f.splat != r.splat)),
        }
    }

    fn label(&self, technique: &str, res: u32, splat: SplatMode) -> String {
        let mut label = technique.to_owned();
        if self.several_res {
            let _ = write!(label, " {res}²");
        }
        if self.several_splats {
            let _ = write!(label, " {}", splat.name());
        }
        label
    }

    fn rank(&self, r: &Rank) -> String {
        self.label(&r.technique, r.shadow_res, r.splat)
    }
}

/// A technique variant: what is ranked.
#[derive(Clone, PartialEq)]
struct Variant {
    technique: String,
    shadow_res: u32,
    splat: SplatMode,
}

impl Variant {
    fn of(r: &Rank) -> Self {
        Self {
            technique: r.technique.clone(),
            shadow_res: r.shadow_res,
            splat: r.splat,
        }
    }
}

/// A variant's ranks over some (scene, budget) pairs, and where it ranked worst.
struct Tally {
    variant: Variant,
    ranks: Vec<f64>,
    worst: u32,
    worst_at: String,
    /// The most techniques ranked beside it.
    of: u32,
}

/// The ranks of `ranks`, tallied per variant in order of first appearance.
fn tally<'r>(ranks: impl Iterator<Item = &'r Rank>) -> Vec<Tally> {
    let mut out: Vec<Tally> = Vec::new();
    for r in ranks {
        let variant = Variant::of(r);
        let at = format!("{} at {}", r.scene, r.budget);
        match out.iter_mut().find(|t| t.variant == variant) {
            Some(t) => {
                t.ranks.push(r.rank as f64);
                t.of = t.of.max(r.of);
                if r.rank > t.worst {
                    t.worst = r.rank;
                    t.worst_at = at;
                }
            }
            None => out.push(Tally {
                variant,
                ranks: vec![r.rank as f64],
                worst: r.rank,
                worst_at: at,
                of: r.of,
            }),
        }
    }
    out
}

/// Plain-words advice, every figure taken from `ranks` and `ranking`: per scene, the most
/// accurate technique at each budget and the runner-up; overall, the best median rank at small
/// ([`Budget::is_small`]) and at large budgets; per scene, the technique that ranks
/// worst there.
pub fn advice(scenes: &[SweepResults], ranks: &[Rank]) -> Vec<String> {
    let labels = Labels::of(ranks);
    let mut out = Vec::new();
    for r in scenes {
        let scene = &r.metadata.scene;
        let here: Vec<&Rank> = ranks.iter().filter(|x| &x.scene == scene).collect();
        if here.is_empty() {
            continue;
        }
        let mut budgets: Vec<Budget> = here.iter().map(|x| x.budget).collect();
        budgets.dedup();
        let mut parts = Vec::new();
        for b in budgets {
            let at = |rank: u32| here.iter().find(|x| x.budget == b && x.rank == rank);
            let Some(best) = at(1) else { continue };
            // Those within the machines' spread of the first are tied with it.
            let tied: Vec<&&Rank> = here
                .iter()
                .filter(|x| {
                    x.budget == b
                        && x.rank > 1
                        && x.flip_vs_exact - best.flip_vs_exact < FLIP_SPREAD
                })
                .collect();
            if !tied.is_empty() {
                let names: Vec<String> = std::iter::once(*best)
                    .chain(tied.iter().map(|x| **x))
                    .map(|x| {
                        format!(
                            "{} (FLIP {:.4}, {} kept)",
                            labels.rank(x),
                            x.flip_vs_exact,
                            report::bytes(x.bytes)
                        )
                    })
                    .collect();
                parts.push(format!(
                    "at {b} {} are tied for the most accurate (within the {FLIP_SPREAD} \
                     FLIP that another machine's rounding moves)",
                    names.join(", ")
                ));
                continue;
            }
            let mut part = format!(
                "at {b} {} is the most accurate (FLIP {:.4}, {} kept)",
                labels.rank(best),
                best.flip_vs_exact,
                report::bytes(best.bytes)
            );
            if let Some(second) = at(2) {
                let _ = write!(
                    part,
                    ", then {} (FLIP {:.4}, {} kept",
                    labels.rank(second),
                    second.flip_vs_exact,
                    report::bytes(second.bytes)
                );
                if best.bytes > 0 && second.bytes != best.bytes {
                    let _ = write!(
                        part,
                        ": {:.2}x the memory",
                        second.bytes as f64 / best.bytes as f64
                    );
                }
                part.push(')');
            }
            parts.push(part);
        }
        let like = match r.metadata.description.trim().trim_end_matches('.') {
            "" => scene.clone(),
            d => format!("{scene} ({d})"),
        };
        out.push(format!("For smoke like {like}: {}.", parts.join("; ")));
    }

    // Overall: the best median rank over every (scene, budget) of a budget class.
    let bytes = ranks
        .iter()
        .any(|r| matches!(r.budget, Budget::BytesPerTexel(_)));
    let (small_class, large_class) = match bytes {
        true => ("≤ 16 bytes a texel", "> 16 bytes a texel"),
        false => ("≤ 8 channels", "> 8 channels"),
    };
    for (class, small) in [
        (format!("small budgets ({small_class})"), true),
        (format!("large budgets ({large_class})"), false),
    ] {
        let in_class: Vec<&Rank> = ranks
            .iter()
            .filter(|r| r.budget.is_small() == small)
            .collect();
        let per = tally(in_class.iter().copied());
        let best = per.iter().min_by(|a, b| {
            median(&a.ranks)
                .total_cmp(&median(&b.ranks))
                .then(a.worst.cmp(&b.worst))
                .then(
                    registry_index(&a.variant.technique).cmp(&registry_index(&b.variant.technique)),
                )
        });
        if let Some(t) = best {
            let scenes: std::collections::BTreeSet<&str> =
                in_class.iter().map(|r| r.scene.as_str()).collect();
            // A best only where no other has the same median rank: else they are tied.
            let tied: Vec<String> = per
                .iter()
                .filter(|o| o.variant != t.variant && median(&o.ranks) == median(&t.ranks))
                .map(|o| labels.label(&o.variant.technique, o.variant.shadow_res, o.variant.splat))
                .collect();
            if !tied.is_empty() {
                out.push(format!(
                    "At {class}, no technique has the best median rank alone: {} and {} tie at {} over {} scene{}.",
                    labels.label(&t.variant.technique, t.variant.shadow_res, t.variant.splat),
                    tied.join(" and "),
                    rank_text(median(&t.ranks)),
                    scenes.len(),
                    if scenes.len() == 1 { "" } else { "s" },
                ));
                continue;
            }
            let v = &t.variant;
            out.push(format!(
                "At {class}, {} has the best median rank: {} over {} ranking{} in {} scene{} (its worst: {}, on {}).",
                labels.label(&v.technique, v.shadow_res, v.splat),
                rank_text(median(&t.ranks)),
                t.ranks.len(),
                if t.ranks.len() == 1 { "" } else { "s" },
                scenes.len(),
                if scenes.len() == 1 { "" } else { "s" },
                t.worst,
                t.worst_at,
            ));
        }
    }

    // Per scene: the technique with the worst mean rank over the scene's budgets.
    for r in scenes {
        let scene = &r.metadata.scene;
        let per = tally(ranks.iter().filter(|x| &x.scene == scene));
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        if per.len() < 2 {
            continue;
        }
        let worst = per
            .iter()
            .map(|t| mean(&t.ranks))
            .fold(f64::NEG_INFINITY, f64::max);
        let at_worst: Vec<&Tally> = per.iter().filter(|t| mean(&t.ranks) == worst).collect();
        let names: Vec<String> = at_worst
            .iter()
            .map(|t| {
                let v = &t.variant;
                labels.label(&v.technique, v.shadow_res, v.splat)
            })
            .collect();
        let (budgets, of) = (at_worst[0].ranks.len(), at_worst[0].of);
        let over = format!(
            "mean rank {worst:.1} of {of} over {budgets} budget{}",
            if budgets == 1 { "" } else { "s" }
        );
        out.push(match names.len() {
            1 => format!("On {scene}, {} ranks worst: {over}.", names[0]),
            _ if names.len() == per.len() => format!(
                "On {scene}, no technique ranks worst overall: {} tie at {over}.",
                names.join(", ")
            ),
            _ => format!("On {scene}, {} tie for worst: {over}.", names.join(", ")),
        });
    }
    out
}

/// A rank for text: `2` or `1.5`.
fn rank_text(rank: f64) -> String {
    if rank.fract() == 0.0 {
        format!("{rank:.0}")
    } else {
        format!("{rank:.1}")
    }
}

/// Computes the gallery of `scenes` (their sweeps already written to `dir/<scene>/`) and writes
/// `results.csv`, `results.json`, `ranking.csv` and `index.html` into `dir`, atomically.
pub fn write(dir: &Path, scenes: &[SweepResults]) -> anyhow::Result<Gallery> {
    let ranks = ranks(scenes);
    let gallery = Gallery {
        ranking: ranking(&ranks),
        advice: advice(scenes, &ranks),
        ranks,
    };

    let mut writer = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["scene"];
    header.extend_from_slice(CSV_COLUMNS);
    writer.write_record(&header)?;
    for r in scenes {
        for c in &r.cells {
            let mut row = vec![r.metadata.scene.clone()];
            let mut cells = smokeshadow_core::sweep::table::csv_row(c);
            // Paths relative to the gallery folder.
            if let Some(image) = cells.last_mut() {
                *image = format!("{}/{image}", r.metadata.scene);
            }
            row.append(&mut cells);
            writer.write_record(&row)?;
        }
    }
    let csv = writer.into_inner().context("cannot encode results.csv")?;
    crate::output::write_atomic(&dir.join("results.csv"), &csv)?;

    let mut writer = csv::Writer::from_writer(Vec::new());
    writer.write_record(RANKING_COLUMNS)?;
    for row in &gallery.ranking {
        writer.write_record([
            row.technique.clone(),
            row.shadow_res.to_string(),
            row.splat.name().to_owned(),
            row.budget.to_string(),
            row.scenes.to_string(),
            format!("{}", row.median_rank),
            row.worst_rank.to_string(),
            row.worst_scene.clone(),
            row.motion_median_rank
                .map_or(String::new(), |m| format!("{m}")),
        ])?;
    }
    let csv = writer.into_inner().context("cannot encode ranking.csv")?;
    crate::output::write_atomic(&dir.join("ranking.csv"), &csv)?;

    let results = GalleryResults {
        scenes: scenes.to_vec(),
        gallery: gallery.clone(),
    };
    crate::output::write_atomic(
        &dir.join("results.json"),
        serde_json::to_string_pretty(&results)?.as_bytes(),
    )?;
    report::write_studies(dir)?;
    crate::output::write_atomic(
        &dir.join(super::report::INDEX_HTML),
        page(scenes, &gallery).as_bytes(),
    )?;
    Ok(gallery)
}

const STYLE: &str = "<style>
td.win { text-align: left; }
td.win b { display: block; }
.swatch { display: inline-block; width: 10px; height: 10px; margin-right: 4px; border-radius: 2px; }
.advice li { margin: 4px 0; }
.wide { overflow-x: auto; }
</style>
";

fn page(scenes: &[SweepResults], gallery: &Gallery) -> String {
    let labels = Labels::of(&gallery.ranks);
    let title = format!("smokeshadow sweep gallery: {} scenes", scenes.len());
    let mut body = String::from(STYLE);
    let _ = writeln!(body, "<h1>{}</h1>", e(&title));
    if let Some(first) = scenes.first() {
        let m = &first.metadata;
        let mut adapters: Vec<&str> = Vec::new();
        for r in scenes {
            for a in r.metadata.adapter.split("; ") {
                if !adapters.contains(&a) {
                    adapters.push(a);
                }
            }
        }
        let _ = writeln!(
            body,
            "<p class=\"muted\">Scenes {}; {} timed frames after {} warm-up per cell; adapter {}; smokeshadow {}.{}</p>",
            scenes
                .iter()
                .map(|r| format!("<code>{}</code>", e(&r.metadata.scene)))
                .collect::<Vec<_>>()
                .join(", "),
            m.frames,
            m.warmup,
            e(&adapters.join("; ")),
            e(&m.tool_version),
            match m.shards.is_empty() {
                true => String::new(),
                false => format!(
                    " Merged from shards {}: each cell's overhead is against the <code>none</code> of the machine that measured it.",
                    e(&m.shards.join(", "))
                ),
            }
        );
    }

    body.push_str("<h2>Advice</h2>\n<ul class=\"advice\">\n");
    if gallery.advice.is_empty() {
        body.push_str("<li>No cell has an error against <code>exact</code> yet.</li>\n");
    }
    for line in &gallery.advice {
        let _ = writeln!(body, "<li>{}</li>", e(line));
    }
    body.push_str("</ul>\n");

    // Colours: by order of first appearance, as in the scenes' charts.
    let mut order: Vec<String> = Vec::new();
    for r in &gallery.ranks {
        let l = labels.rank(r);
        if !order.contains(&l) {
            order.push(l);
        }
    }
    let colour = |label: &str| {
        let i = order.iter().position(|l| l == label).unwrap_or(0);
        super::charts::palette_rgb(i)
    };

    let moving = gallery
        .ranking
        .iter()
        .any(|r| r.motion_median_rank.is_some());
    let _ = writeln!(
        body,
        "<h2>Ranking at equal bytes, all scenes</h2>\n<p>Within each scene and byte budget per \
         shadow-map texel (each technique at the largest configuration whose resident bytes \
         fit it, at its own precision; a sweep without byte budgets: each channel budget) the \
         techniques are ranked by FLIP mean against <code>exact</code> (1 = closest; ties: fewer \
         bytes first). A technique whose result does not depend on the budget is ranked at every \
         budget it fits with its one cell. Below, each technique and budget with its median and worst \
         rank across the scenes, sorted by median, then worst (also \
         <a href=\"ranking.csv\">ranking.csv</a>){}.</p>\n<table><tr><th>technique</th>\
         <th>budget</th><th>median rank</th><th>worst rank</th><th>worst on</th><th>scenes</th>{}</tr>",
        match moving {
            true =>
                "; with <code>--animate</code>, the median rank of the same cells by temporal \
                     error against <code>exact</code> over the span (1 = the steadiest)",
            false => "",
        },
        match moving {
            true => "<th>median rank in motion</th>",
            false => "",
        }
    );
    for row in &gallery.ranking {
        let l = labels.label(&row.technique, row.shadow_res, row.splat);
        let (r, g, b) = colour(&l);
        let _ = writeln!(
            body,
            "<tr><td><span class=\"swatch\" style=\"background: rgb({r},{g},{b})\"></span>{}</td>\
             <td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>{}</tr>",
            e(&l),
            row.budget,
            rank_text(row.median_rank),
            row.worst_rank,
            e(&row.worst_scene),
            row.scenes,
            match (moving, row.motion_median_rank) {
                (true, Some(m)) => format!("<td>{}</td>", rank_text(m)),
                (true, None) => "<td>—</td>".to_owned(),
                (false, _) => String::new(),
            }
        );
    }
    body.push_str("</table>\n");

    // Where each technique wins: scenes x budgets.
    let mut budgets: Vec<Budget> = gallery.ranks.iter().map(|r| r.budget).collect();
    budgets.sort_unstable_by_key(|b| b.order());
    budgets.dedup();
    body.push_str(
        "<h2>Where each technique wins</h2>\n<p>The rank-1 technique of each scene and budget, \
         coloured by technique, with its FLIP against <code>exact</code> and its bytes.</p>\n\
         <div class=\"wide\"><table><tr><th>scene</th>",
    );
    for b in &budgets {
        let _ = write!(body, "<th>{b}</th>");
    }
    body.push_str("</tr>\n");
    for r in scenes {
        let scene = &r.metadata.scene;
        let _ = write!(
            body,
            "<tr><td><a href=\"{s}/index.html\">{s}</a></td>",
            s = e(scene)
        );
        for &b in &budgets {
            match gallery
                .ranks
                .iter()
                .find(|x| &x.scene == scene && x.budget == b && x.rank == 1)
            {
                Some(w) => {
                    let l = labels.rank(w);
                    let (cr, cg, cb) = colour(&l);
                    let _ = write!(
                        body,
                        "<td class=\"win\" style=\"background: rgba({cr},{cg},{cb},0.25)\"><b>{}</b>FLIP {:.4} · {} kept</td>",
                        e(&l),
                        w.flip_vs_exact,
                        report::bytes(w.bytes)
                    );
                }
                None => body.push_str("<td>—</td>"),
            }
        }
        body.push_str("</tr>\n");
    }
    body.push_str("</table></div>\n");
    body.push_str(&report::studies_paragraph());

    body.push_str("<h2>Scenes</h2>\n");
    for r in scenes {
        let m = &r.metadata;
        let _ = writeln!(
            body,
            "<h3><a href=\"{s}/index.html\">{s}</a></h3>\n<p>{desc}{w}x{h}, {p} particles; \
             <a href=\"{s}/index.html\">its report</a> (charts, images, differences).</p>",
            s = e(&m.scene),
            desc = match m.description.is_empty() {
                true => String::new(),
                false => format!("{} ", e(&m.description)),
            },
            w = m.width_px,
            h = m.height_px,
            p = m.particles,
        );
        body.push_str(
            "<div class=\"wide\"><table><tr><th>technique</th><th>channels</th><th>res</th>\
             <th>splat</th><th>bytes</th><th>frame ms</th><th>overhead</th><th>FLIP vs exact</th>\
             <th>RMS T error</th><th>ranks at its budgets</th></tr>\n",
        );
        for c in &r.cells {
            let ranks: Vec<String> = gallery
                .ranks
                .iter()
                .filter(|x| {
                    x.scene == m.scene
                        && x.channels == c.channels
                        && (x.technique.as_str(), x.shadow_res, x.splat)
                            == (c.technique.as_str(), c.shadow_res, c.splat)
                })
                .map(|x| format!("{} of {} at {}", x.rank, x.of, x.budget))
                .collect();
            let _ = writeln!(
                body,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.3}</td>\
                 <td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                e(&c.technique),
                c.channels,
                c.shadow_res,
                c.splat.label(),
                report::bytes(c.resident_bytes),
                c.frame_ms.median,
                c.overhead_ratio
                    .filter(|r| r.is_finite())
                    .map_or("—".into(), |r| format!("{r:.2}x")),
                c.vs_exact
                    .map_or("—".into(), |x| format!("{:.4}", x.flip_mean)),
                c.rms_transmittance_error
                    .map_or("—".into(), |x| format!("{x:.4}")),
                match ranks.is_empty() {
                    true => "—".to_owned(),
                    false => ranks.join("; "),
                },
            );
        }
        body.push_str("</table></div>\n");
    }
    body.push_str(
        "<h2>Data</h2>\n<p>Every scene's cells as <a href=\"results.csv\">results.csv</a> (a \
         leading <code>scene</code> column), with the ranks and the advice as \
         <a href=\"results.json\">results.json</a>; the ranking as \
         <a href=\"ranking.csv\">ranking.csv</a>.</p>\n",
    );
    report::page(&title, &body, "")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rank(scene: &str, technique: &str, channels: u32, rank: u32) -> Rank {
        Rank {
            scene: scene.into(),
            budget: Budget::Channels(channels),
            channels,
            technique: technique.into(),
            shadow_res: 512,
            splat: SplatMode::Point,
            rank,
            of: 2,
            flip_vs_exact: 0.01 * rank as f64,
            bytes: 1000,
            motion_rank: None,
            temporal_error: None,
        }
    }

    #[test]
    fn ranking_takes_median_and_worst_across_scenes_and_sorts_by_them() {
        let ranks = [
            rank("a", "osm", 8, 1),
            rank("a", "fom", 8, 2),
            rank("b", "osm", 8, 2),
            rank("b", "fom", 8, 1),
            rank("c", "osm", 8, 1),
            rank("c", "fom", 8, 2),
        ];
        let rows = ranking(&ranks);
        assert_eq!(rows.len(), 2);
        assert_eq!(
            (
                rows[0].technique.as_str(),
                rows[0].median_rank,
                rows[0].worst_rank
            ),
            ("osm", 1.0, 2)
        );
        assert_eq!(rows[0].worst_scene, "b");
        assert_eq!(
            (rows[1].technique.as_str(), rows[1].median_rank),
            ("fom", 2.0)
        );
        assert_eq!(rows[1].worst_scene, "a");
        assert_eq!(median(&[1.0, 2.0]), 1.5);
    }

    fn scene(name: &str) -> SweepResults {
        let mut r = crate::sweep::report::tests::results();
        r.metadata.scene = name.into();
        r.metadata.description = String::new();
        r
    }

    #[test]
    fn cells_with_byte_budgets_are_ranked_at_equal_bytes_not_channels() {
        // osm at 24 channels and fom at 11 keep 48 bytes a texel; osm at 8 and fom at 3, 16.
        // fom at 24 channels answers no byte budget, and esm (one cell, whatever the budget)
        // answers both.
        let mut r = scene("a");
        let cell = |technique: &str, channels: u32, flip: f64, budgets: &[u32]| {
            let mut c = r.cells[1].clone();
            c.technique = technique.into();
            c.channels = channels;
            c.vs_exact = Some(crate::sweep::ImageError {
                flip_mean: flip,
                rmse: flip,
            });
            c.byte_budgets = budgets.to_vec();
            c
        };
        let cells = vec![
            cell("osm", 24, 0.010, &[48]),
            cell("osm", 8, 0.030, &[16]),
            cell("fom", 24, 0.002, &[]),
            cell("fom", 11, 0.012, &[48]),
            cell("fom", 3, 0.060, &[16]),
            cell("esm", 24, 0.050, &[48, 16]),
        ];
        r.cells = cells;
        let ranks = ranks(&[r]);
        let at = |budget: u32| {
            let mut v: Vec<(&str, u32, u32)> = ranks
                .iter()
                .filter(|x| x.budget == Budget::BytesPerTexel(budget))
                .map(|x| (x.technique.as_str(), x.channels, x.rank))
                .collect();
            v.sort_by_key(|x| x.2);
            v
        };
        assert_eq!(at(48), [("osm", 24, 1), ("fom", 11, 2), ("esm", 24, 3)]);
        assert_eq!(at(16), [("osm", 8, 1), ("esm", 24, 2), ("fom", 3, 3)]);
        // No channel budget is ranked where byte budgets were asked for: fom's 24-channel cell,
        // twice osm's bytes, is in no ranking.
        assert_eq!(ranks.len(), 6);
        assert!(
            ranks
                .iter()
                .all(|x| matches!(x.budget, Budget::BytesPerTexel(_)))
        );
        let advice = advice(&[scene("a")], &ranks);
        assert!(
            advice
                .iter()
                .any(|l| l.contains("at 48 bytes a texel osm is the most accurate")),
            "{advice:?}"
        );
    }

    #[test]
    fn the_advice_names_a_best_only_beyond_the_spread_and_says_which_are_tied() {
        // Scene a: osm beats fom by far more than the spread; scene b: by less.
        let mut ranks = vec![
            rank("a", "osm", 8, 1),
            rank("a", "fom", 8, 2),
            rank("b", "osm", 8, 1),
            rank("b", "fom", 8, 2),
        ];
        ranks[2].flip_vs_exact = 0.0100;
        ranks[3].flip_vs_exact = 0.0100 + 0.5 * FLIP_SPREAD;
        let advice = advice(&[scene("a"), scene("b")], &ranks);
        let on = |s: &str| {
            advice
                .iter()
                .find(|l| l.contains(&format!("like {s}:")))
                .unwrap()
        };
        assert!(on("a").contains("osm is the most accurate"), "{advice:?}");
        assert!(on("b").contains("osm (FLIP 0.0100"), "{advice:?}");
        assert!(
            on("b").contains("are tied for the most accurate"),
            "{advice:?}"
        );
        // Across the scenes osm ranks 1 in both: the best alone.
        assert!(
            advice
                .iter()
                .any(|l| l.contains("osm has the best median rank")),
            "{advice:?}"
        );
        // With the ranks split one each, the median ranks tie and no best is named.
        let split = [
            rank("a", "osm", 8, 1),
            rank("a", "fom", 8, 2),
            rank("b", "osm", 8, 2),
            rank("b", "fom", 8, 1),
        ];
        let advice = super::advice(&[scene("a"), scene("b")], &split);
        assert!(
            advice
                .iter()
                .any(|l| l.contains("no technique has the best median rank alone")),
            "{advice:?}"
        );
        assert!(
            !advice
                .iter()
                .any(|l| l.contains("has the best median rank:")),
            "{advice:?}"
        );
    }
}
