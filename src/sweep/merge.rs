//! `sweep --merge`: the shards' cells ([`super::shard`]) assembled into each scene's tables,
//! charts and report, and the gallery over the scenes, without a GPU. Every manifest must
//! describe the same plan, and every planned cell be there with that plan's settings; it
//! refuses in one line otherwise.

use std::path::{Path, PathBuf};

use anyhow::Context;

use super::cells::{EXACT_HDR_IMAGE, EXACT_IMAGE, assemble, read_cell};
use super::shard::{PlannedScene, SHARDS_DIR, Shard, ShardManifest, write_manifest};
use super::{CellResult, SweepOutcome, SweepResults};

/// The manifests in `dir/shards/`, by file name.
fn read_manifests(dir: &Path) -> anyhow::Result<Vec<ShardManifest>> {
    let shards = dir.join(SHARDS_DIR);
    if !dir.is_dir() {
        anyhow::bail!("--merge {}: no such folder", dir.display());
    }
    let mut paths: Vec<PathBuf> = match std::fs::read_dir(&shards) {
        Ok(entries) => entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.extension().is_some_and(|e| e == "json")
                    && p.file_name()
                        .is_some_and(|n| !n.to_string_lossy().starts_with('.'))
            })
            .collect(),
        Err(_) => Vec::new(),
    };
    paths.sort();
    if paths.is_empty() {
        anyhow::bail!(
            "--merge {}: no shard manifest ({SHARDS_DIR}/K-of-N.json): not a folder `sweep --shard` wrote",
            dir.display()
        );
    }
    paths
        .iter()
        .map(|p| {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("cannot read {}", p.display()))?;
            serde_json::from_str(&text)
                .with_context(|| format!("{} is not a shard manifest", p.display()))
        })
        .collect()
}

/// The first field two settings keys differ in, as "a against b" (`size=160x120 against
/// size=200x120`).
fn key_difference(a: &str, b: &str) -> String {
    let fields = |k: &str| -> Vec<String> {
        // The technique's parameters are JSON, the last field: keep them whole.
        let (head, params) = k.split_once(" params=").unwrap_or((k, ""));
        let mut f: Vec<String> = head.split(' ').map(str::to_owned).collect();
        f.push(format!("params={params}"));
        f
    };
    let (fa, fb) = (fields(a), fields(b));
    for (x, y) in fa.iter().zip(&fb) {
        if x != y {
            return match (x.split_once('='), y.split_once('=')) {
                (Some(("scene", _)), Some(("scene", _))) => format!(
                    "scene hash {} against {}",
                    &x[6..x.len().min(18)],
                    &y[6..y.len().min(18)]
                ),
                (Some(("tool", va)), Some(("tool", vb))) => {
                    format!("tool version {va} against {vb}")
                }
                _ => format!("{x} against {y}"),
            };
        }
    }
    format!("{a} against {b}")
}

/// How two manifests' plans differ, or `None` when they are the plan of one sweep.
fn plan_difference(a: &ShardManifest, b: &ShardManifest) -> Option<String> {
    if a.shard.n != b.shard.n {
        return Some(format!(
            "split into {} against split into {} shards",
            a.shard.n, b.shard.n
        ));
    }
    if a.tool_version != b.tool_version {
        return Some(format!(
            "tool version {} against {}",
            a.tool_version, b.tool_version
        ));
    }
    let names = |m: &ShardManifest| {
        m.scenes
            .iter()
            .map(|s| s.header.name.clone())
            .collect::<Vec<_>>()
    };
    if names(a) != names(b) {
        return Some(format!(
            "scenes {} against {}",
            names(a).join(","),
            names(b).join(",")
        ));
    }
    for (sa, sb) in a.scenes.iter().zip(&b.scenes) {
        if sa.header.scene_sha256 != sb.header.scene_sha256 {
            return Some(format!(
                "scene {} has hash {} against {}: another scene file, --particles, --size or --param",
                sa.header.name,
                &sa.header.scene_sha256[..12.min(sa.header.scene_sha256.len())],
                &sb.header.scene_sha256[..12.min(sb.header.scene_sha256.len())]
            ));
        }
        let cell_names =
            |s: &PlannedScene| s.cells.iter().map(|c| c.name.clone()).collect::<Vec<_>>();
        if cell_names(sa) != cell_names(sb) {
            return Some(format!(
                "scene {}: {} planned cells against {} (other --techniques, --channels, --shadow-res or --splat)",
                sa.header.name,
                sa.cells.len(),
                sb.cells.len()
            ));
        }
        for (ca, cb) in sa.cells.iter().zip(&sb.cells) {
            if ca.settings_key != cb.settings_key {
                return Some(format!(
                    "scene {}, cell {}: {}",
                    sa.header.name,
                    ca.name,
                    key_difference(&ca.settings_key, &cb.settings_key)
                ));
            }
        }
    }
    None
}

/// `sweep --merge DIR... -o OUT`: assembles the cells of every shard folder into `out`
/// (copying their images and differences when `out` is another folder), and writes the tables,
/// charts and report of each scene, and with several scenes the gallery. Creates no GPU device.
pub fn merge(dirs: &[PathBuf], out: &Path) -> anyhow::Result<SweepOutcome> {
    if dirs.is_empty() {
        anyhow::bail!("--merge needs at least one shard folder");
    }
    let mut manifests: Vec<(PathBuf, ShardManifest)> = Vec::new();
    for dir in dirs {
        for m in read_manifests(dir)? {
            manifests.push((dir.clone(), m));
        }
    }
    let (first_dir, first) = &manifests[0];
    for (dir, m) in &manifests[1..] {
        if let Some(diff) = plan_difference(first, m) {
            anyhow::bail!(
                "--merge refused: shard {} in {} and shard {} in {} are not shards of one sweep ({diff}); merge only shards run with the same options",
                first.shard,
                first_dir.display(),
                m.shard,
                dir.display()
            );
        }
    }
    let n = first.shard.n;
    if out.is_file() {
        anyhow::bail!("output {} is a file; give a folder", out.display());
    }
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;

    // Find every planned cell in some shard's folder, preferring the folder of the shard it
    // belongs to.
    struct Found {
        name: String,
        cell: CellResult,
        from: PathBuf,
    }
    let mut found: Vec<Vec<Found>> = Vec::new();
    let mut missing: Vec<(Shard, String)> = Vec::new();
    for scene in &first.scenes {
        let mut cells = Vec::new();
        for planned in &scene.cells {
            let owner = Shard::of(planned.index, n);
            let mut candidates: Vec<&PathBuf> = manifests
                .iter()
                .filter(|(_, m)| m.shard == owner)
                .map(|(d, _)| d)
                .collect();
            candidates.extend(dirs.iter());
            let mut hit = None;
            for dir in candidates {
                let scene_dir = dir.join(&scene.folder);
                let Some(cell) = read_cell(&scene_dir.join(format!("cells/{}.json", planned.name)))
                else {
                    continue;
                };
                if cell.settings_key != planned.settings_key {
                    anyhow::bail!(
                        "--merge refused: cell {} of scene {} in {} was measured with other settings than the shards' plan ({}); re-run shard {owner} there",
                        planned.name,
                        scene.header.name,
                        dir.display(),
                        key_difference(&cell.settings_key, &planned.settings_key)
                    );
                }
                if !scene_dir.join(&cell.image).is_file() {
                    continue;
                }
                hit = Some(Found {
                    name: planned.name.clone(),
                    cell,
                    from: scene_dir,
                });
                break;
            }
            match hit {
                Some(f) => cells.push(f),
                None => missing.push((owner, format!("{}/{}", scene.header.name, planned.name))),
            }
        }
        found.push(cells);
    }
    if !missing.is_empty() {
        let mut per_shard: Vec<(Shard, Vec<String>)> = Vec::new();
        for (shard, name) in missing.iter().cloned() {
            match per_shard.iter_mut().find(|(s, _)| *s == shard) {
                Some((_, names)) => names.push(name),
                None => per_shard.push((shard, vec![name])),
            }
        }
        per_shard.sort_by_key(|(s, _)| s.k);
        let parts: Vec<String> = per_shard
            .iter()
            .map(|(shard, names)| {
                let state = manifests.iter().find(|(_, m)| m.shard == *shard).map_or(
                    "no manifest: not started",
                    |(_, m)| match m.finished {
                        true => "finished, but its cells are gone",
                        false => "not finished",
                    },
                );
                let shown: Vec<&str> = names.iter().take(3).map(String::as_str).collect();
                format!(
                    "{} of shard {shard} ({state}: {}{})",
                    names.len(),
                    shown.join(", "),
                    if names.len() > 3 { ", ..." } else { "" }
                )
            })
            .collect();
        anyhow::bail!(
            "--merge: {} of {} cells missing: {}; run those shards (again, with --resume) first",
            missing.len(),
            first.scenes.iter().map(|s| s.cells.len()).sum::<usize>(),
            parts.join("; ")
        );
    }

    // Copy what the cells reference, and `exact`, into `out`; write the cells there too, so the
    // merged folder is a complete sweep folder (`--resume` reuses it).
    let mut results: Vec<SweepResults> = Vec::new();
    let shard_labels: Vec<String> = {
        let mut v: Vec<Shard> = manifests.iter().map(|(_, m)| m.shard).collect();
        v.sort_by_key(|s| s.k);
        v.dedup();
        v.iter().map(Shard::to_string).collect()
    };
    let started = manifests
        .iter()
        .map(|(_, m)| m.started.clone())
        .min()
        .unwrap_or_default();
    // Each shard's latest manifest counts once, even when several folders list it.
    let mut walls: Vec<(Shard, f64)> = Vec::new();
    for (_, m) in &manifests {
        if !walls.iter().any(|(s, _)| *s == m.shard) {
            walls.push((m.shard, m.wall_s));
        }
    }
    let wall_s: f64 = walls.iter().map(|(_, w)| w).sum();
    for (scene, cells) in first.scenes.iter().zip(found) {
        let scene_out = out.join(&scene.folder);
        for sub in ["cells", "images", "diffs"] {
            std::fs::create_dir_all(scene_out.join(sub))
                .with_context(|| format!("cannot create {}", scene_out.join(sub).display()))?;
        }
        // The exact image from the folder of the shard that measured the first cell.
        let exact_from = cells
            .iter()
            .map(|f| &f.from)
            .find(|d| d.join(EXACT_IMAGE).is_file())
            .with_context(|| {
                format!("--merge: no {EXACT_IMAGE} for scene {}", scene.header.name)
            })?;
        for rel in [EXACT_IMAGE, EXACT_HDR_IMAGE] {
            copy_into(exact_from, &scene_out, rel)?;
        }
        let mut merged: Vec<CellResult> = Vec::new();
        for f in cells {
            let c = &f.cell;
            for rel in [
                Some(&c.image),
                c.diff_own_24.as_ref(),
                c.flip_own_24.as_ref(),
                c.diff_exact.as_ref(),
                c.flip_exact.as_ref(),
                c.hdr_image.as_ref(),
            ]
            .into_iter()
            .flatten()
            {
                copy_into(&f.from, &scene_out, rel)?;
            }
            if !same_dir(&f.from, &scene_out) {
                crate::output::write_atomic(
                    &scene_out.join(format!("cells/{}.json", f.name)),
                    serde_json::to_string_pretty(c)?.as_bytes(),
                )?;
            }
            merged.push(f.cell);
        }
        let r = assemble(
            scene,
            &first.tool_version,
            first.frames,
            first.warmup,
            &merged,
            None,
            None,
            started.clone(),
            wall_s,
            shard_labels.clone(),
            &scene_out,
        );
        super::report::write_scene(&r, &scene_out)?;
        results.push(r);
    }
    for (dir, m) in &manifests {
        if !same_dir(dir, out) {
            write_manifest(out, m)?;
        }
    }
    let gallery = match first.gallery {
        true => Some(super::gallery::write(out, &results)?),
        false => None,
    };
    Ok(SweepOutcome::Whole {
        scenes: results,
        gallery,
    })
}

/// Whether two paths name the same existing folder.
fn same_dir(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

/// Copies `from/rel` to `to/rel` atomically when the folders differ and the file exists.
fn copy_into(from: &Path, to: &Path, rel: &str) -> anyhow::Result<()> {
    let src = from.join(rel);
    if !src.is_file() || same_dir(from, to) {
        return Ok(());
    }
    let bytes = std::fs::read(&src).with_context(|| format!("cannot read {}", src.display()))?;
    crate::output::write_atomic(&to.join(rel), &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_difference_names_the_field() {
        let a = "tool=0.1.0 scene=abc size=160x120 frames=2 technique=osm params={\"a\":1}";
        let b = "tool=0.1.0 scene=abc size=200x120 frames=2 technique=osm params={\"a\":1}";
        assert_eq!(key_difference(a, b), "size=160x120 against size=200x120");
        let c = "tool=0.1.0 scene=abc size=160x120 frames=2 technique=osm params={\"a\":2}";
        assert_eq!(
            key_difference(a, c),
            "params={\"a\":1} against params={\"a\":2}"
        );
        let d = a.replace("tool=0.1.0", "tool=0.2.0");
        assert_eq!(key_difference(a, &d), "tool version 0.1.0 against 0.2.0");
    }
}
