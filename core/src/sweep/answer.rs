//! Which cells answer: the cells at a byte, memory or time budget ranked by their error
//! against `exact`, the Pareto fronts, the most stable in motion and the cells an animated sweep
//! shows. The report, the charts and the gallery all read the answer from here.

use super::{CellResult, SweepResults};
use crate::render::ParticleRes;

/// The cells answering byte budget `bytes` (full particle resolution: the budgets compare
/// shadow techniques), most accurate first (FLIP vs `exact`, then fewer resident bytes, registry
/// order), as the gallery ranks them.
pub fn at_byte_budget(results: &SweepResults, bytes: u32) -> Vec<&CellResult> {
    let mut at: Vec<&CellResult> = results
        .cells
        .iter()
        .filter(|c| c.byte_budgets.contains(&bytes) && c.particle_res == ParticleRes::Full)
        .filter(|c| flip_exact(c).is_finite())
        .collect();
    at.sort_by(|a, b| by_accuracy_then_bytes(a, b));
    at
}

/// Most accurate first (FLIP vs `exact`), then fewer resident bytes, then registry order: how
/// the answers at a byte or a memory budget rank their cells.
fn by_accuracy_then_bytes(a: &CellResult, b: &CellResult) -> std::cmp::Ordering {
    flip_exact(a)
        .total_cmp(&flip_exact(b))
        .then(a.resident_bytes.cmp(&b.resident_bytes))
        .then(super::registry_index(&a.technique).cmp(&super::registry_index(&b.technique)))
}

/// The memory budgets (total bytes, `--memory`) the cells answer, largest first.
pub fn memory_budgets(results: &SweepResults) -> Vec<u64> {
    budgets_of(results, |c| &c.memory_budgets)
}

/// The budgets of one kind (`of`) the cells answer, largest first.
fn budgets_of<T: Copy + Ord>(
    results: &SweepResults,
    of: impl Fn(&CellResult) -> &Vec<T>,
) -> Vec<T> {
    let mut budgets: Vec<T> = results
        .cells
        .iter()
        .flat_map(|c| of(c).iter().copied())
        .collect();
    budgets.sort_unstable_by(|a, b| b.cmp(a));
    budgets.dedup();
    budgets
}

/// Each technique's most accurate of `cells` (FLIP vs `exact`; the first of equals), in the
/// order their techniques first appear.
fn most_accurate_per_technique<'a>(
    cells: impl Iterator<Item = &'a CellResult>,
) -> Vec<&'a CellResult> {
    let mut best: Vec<&CellResult> = Vec::new();
    for c in cells {
        match best.iter_mut().find(|b| b.technique == c.technique) {
            Some(b) if flip_exact(c) < flip_exact(b) => *b = c,
            Some(_) => {}
            None => best.push(c),
        }
    }
    best
}

/// Each technique's cell that answers the memory budget `total` (one per swept resolution),
/// most accurate first: the answer at equal total memory, every technique at the map resolution
/// `tune` chose for it on the training scenes ([`super::Shapes`], the results' metadata)
/// where that resolution was swept, else at its most accurate of those swept, on this scene
/// ([`shape_tuned`] says which); of several cells there (splats), the most accurate.
pub fn at_memory_budget(results: &SweepResults, total: u64) -> Vec<&CellResult> {
    let answering: Vec<&CellResult> = results
        .cells
        .iter()
        .filter(|c| {
            c.memory_budgets.contains(&total)
                && c.particle_res == ParticleRes::Full
                && flip_exact(c).is_finite()
        })
        .collect();
    let tuned_swept = |technique: &str| {
        answering
            .iter()
            .any(|d| d.technique == technique && shape_tuned(results, total, d))
    };
    let mut best = most_accurate_per_technique(
        answering
            .iter()
            .copied()
            .filter(|c| !tuned_swept(&c.technique) || shape_tuned(results, total, c)),
    );
    best.sort_by(|a, b| by_accuracy_then_bytes(a, b));
    best
}

/// Whether `cell` is at the map resolution `tune` chose for its technique at the memory budget
/// `total` on the training scenes.
pub fn shape_tuned(results: &SweepResults, total: u64, cell: &CellResult) -> bool {
    results
        .metadata
        .shapes
        .get(&cell.technique)
        .and_then(|by_memory| by_memory.get(&total))
        == Some(&cell.shadow_res)
}

/// The frame-time budgets of the time answer: a technique's frame at most this many times the
/// frame without self-shadowing (`none`'s, timed in the same run).
pub const TIME_BUDGETS: &[f64] = &[1.5, 2.0, 4.0];

/// Each technique's most accurate cell (FLIP vs `exact`) whose frame takes at most `ratio`
/// times `none`'s (its `overhead_ratio`, full particle resolution), most accurate first (then
/// faster, registry order): the answer at equal time.
pub fn at_time_budget(results: &SweepResults, ratio: f64) -> Vec<&CellResult> {
    let mut best = most_accurate_per_technique(results.cells.iter().filter(|c| {
        c.particle_res == ParticleRes::Full
            && flip_exact(c).is_finite()
            && c.overhead_ratio.is_some_and(|r| r <= ratio)
            && crate::shadow::find(&c.technique)
                .is_ok_and(|t| t.role == crate::shadow::Role::Contender)
    }));
    best.sort_by(|a, b| {
        flip_exact(a)
            .total_cmp(&flip_exact(b))
            .then(a.frame_ms.median.total_cmp(&b.frame_ms.median))
            .then(super::registry_index(&a.technique).cmp(&super::registry_index(&b.technique)))
    });
    best
}

/// The byte budgets the cells answer, largest first.
pub fn byte_budgets(results: &SweepResults) -> Vec<u32> {
    budgets_of(results, |c| &c.byte_budgets)
}

/// The temporal errors of two renders of one animation by lavapipe on CPUs of different SIMD
/// widths may differ by this much (an estimate, not a measurement: another CPU moves about 1.6%
/// of pixels by 1/255, some 2e-3 of linear luminance at mid-grey, 3e-5 of a frame's mean, and
/// the two frames of a pair each their own way): within it the most stable are tied.
pub const TEMPORAL_SPREAD: f64 = 3e-5;

/// The cells of `at` that were measured over a span, most stable first (temporal error, then
/// registry order).
pub fn most_stable<'a>(at: &[&'a CellResult]) -> Vec<&'a CellResult> {
    let mut moving: Vec<&CellResult> = at.iter().copied().filter(|c| c.motion.is_some()).collect();
    moving.sort_by(|a, b| {
        temporal_error(a)
            .total_cmp(&temporal_error(b))
            .then(super::registry_index(&a.technique).cmp(&super::registry_index(&b.technique)))
    });
    moving
}

/// The cells an animated sweep shows side by side with `exact` ([`super::Animation`]): at each
/// byte budget from the smallest (where they differ most), else each memory budget, else over
/// every cell, the most accurate still and the most stable in motion, and at the first of them
/// the least stable too; three at most.
pub fn animated_cells(results: &SweepResults) -> Vec<&CellResult> {
    let mut budgets: Vec<Vec<&CellResult>> = byte_budgets(results)
        .into_iter()
        .rev()
        .map(|b| at_byte_budget(results, b))
        .collect();
    if budgets.is_empty() {
        budgets = memory_budgets(results)
            .into_iter()
            .rev()
            .map(|m| at_memory_budget(results, m))
            .collect();
    }
    if budgets.is_empty() {
        let mut all: Vec<&CellResult> = results
            .cells
            .iter()
            .filter(|c| flip_exact(c).is_finite())
            .collect();
        all.sort_by(|a, b| by_accuracy_then_bytes(a, b));
        budgets.push(all);
    }
    let mut out: Vec<&CellResult> = Vec::new();
    for at in &budgets {
        let stable = most_stable(at);
        // At the smallest budget also the least stable: what its flicker looks like.
        let least = stable.last().filter(|_| out.is_empty());
        for c in at.first().into_iter().chain(stable.first()).chain(least) {
            if out.len() < 3 && c.motion.is_some() && !out.iter().any(|o| o.image == c.image) {
                out.push(c);
            }
        }
    }
    out
}

/// A cell's temporal error over the span (NaN for a still cell).
pub fn temporal_error(c: &CellResult) -> f64 {
    c.motion.as_ref().map_or(f64::NAN, |m| m.temporal_error)
}

/// The cells no other beats on both frame time (relative to `none`'s) and FLIP vs `exact`, at
/// full particle resolution, fastest first.
pub fn time_pareto(results: &SweepResults) -> Vec<&CellResult> {
    let timed: Vec<&CellResult> = results
        .cells
        .iter()
        .filter(|c| {
            c.particle_res == ParticleRes::Full
                && flip_exact(c).is_finite()
                && c.overhead_ratio.is_some_and(f64::is_finite)
        })
        .collect();
    let ratio = |c: &CellResult| c.overhead_ratio.unwrap_or(f64::INFINITY);
    let mut front: Vec<&CellResult> = timed
        .iter()
        .copied()
        .filter(|c| {
            !timed.iter().any(|d| {
                ratio(d) <= ratio(c)
                    && flip_exact(d) <= flip_exact(c)
                    && (ratio(d) < ratio(c) || flip_exact(d) < flip_exact(c))
            })
        })
        .collect();
    front.sort_by(|a, b| ratio(a).total_cmp(&ratio(b)));
    front
}

/// FLIP mean against `exact`, NaN when absent (never on the front, never the best).
pub fn flip_exact(c: &CellResult) -> f64 {
    c.vs_exact.map_or(f64::NAN, |x| x.flip_mean)
}

/// For each cell, whether it is on the Pareto front of bytes against FLIP vs `exact`: it has a
/// finite error and no other cell has both fewer-or-equal bytes and a lower error. Cells
/// without an error against `exact` (`none`) are never on it.
pub fn pareto_front(cells: &[CellResult]) -> Vec<bool> {
    cells
        .iter()
        .map(|c| {
            let flip = flip_exact(c);
            flip.is_finite()
                && !cells.iter().any(|d| {
                    let other = flip_exact(d);
                    other.is_finite() && d.resident_bytes <= c.resident_bytes && other < flip
                })
        })
        .collect()
}

/// The FLIP mean between two renders of one frame by lavapipe on CPUs of different SIMD widths
/// (±1/255 on a few percent of pixels): 0.0008-0.0010 between this machine's baselines and
/// another's (baselines/, re-blessed December 2026). Two techniques whose FLIP against `exact`
/// differ by less than this may swap places on a user's machine, so the advice calls them tied.
pub const FLIP_SPREAD: f64 = 0.001;
