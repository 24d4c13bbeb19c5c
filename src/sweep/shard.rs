//! Sweeps that outgrow one machine: `sweep --shard K/N` runs the cells whose stable index (the
//! cell's position in the full planned list, over every scene) is K mod N, and `sweep --merge`
//! ([`super::merge`]) assembles the shards' cells into the tables, charts and reports, without
//! a GPU.
//!
//! A shard writes its cells in the usual layout (`cells/`, `images/`, `diffs/`, per scene) and,
//! instead of the tables, a manifest `shards/K-of-N.json` ([`ShardManifest`]): the whole plan
//! (every scene, every cell with its stable index and settings key), its machine and wall time,
//! and whether it finished. Shards may share one folder: each clears only its own cells. Merge
//! checks that every manifest describes the same plan, that every planned cell is there with
//! that plan's settings, and refuses in one line otherwise.

use std::path::Path;

use anyhow::Context;
use serde::{Deserialize, Serialize};

pub use super::Shard;
use super::{Machine, SkippedCell};
use smokeshadow_core::sweep::SceneHeader;

/// Folder of the shard manifests inside the sweep folder.
pub const SHARDS_DIR: &str = "shards";

/// One planned cell: its stable index, name and settings key.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlannedCell {
    pub index: usize,
    pub name: String,
    pub settings_key: String,
}

/// One scene of the plan, with what its results' metadata needs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlannedScene {
    /// The scene (nested, not flattened: serde's flatten reads the shapes' integer keys as
    /// strings).
    pub header: SceneHeader,
    /// The scene's folder relative to the sweep folder ("" without `--scenes`).
    pub folder: String,
    pub cells: Vec<PlannedCell>,
    pub skipped: Vec<SkippedCell>,
}

/// `shards/K-of-N.json`: what a shard was asked to do, where it ran and whether it finished.
/// Written when the shard starts (`finished: false`) and again when it ends.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShardManifest {
    pub shard: Shard,
    pub tool_version: String,
    pub frames: u32,
    pub warmup: u32,
    /// The gallery layout (`--scenes`).
    pub gallery: bool,
    /// The whole plan, every shard's cells.
    pub scenes: Vec<PlannedScene>,
    pub machine: Machine,
    /// RFC 3339 (UTC) start, and wall time in seconds so far.
    pub started: String,
    pub wall_s: f64,
    /// Cells this shard measured, and reused from an earlier run (`--resume`).
    pub measured: u32,
    pub reused: u32,
    pub finished: bool,
}

/// Writes `dir/shards/K-of-N.json` atomically.
pub(super) fn write_manifest(dir: &Path, manifest: &ShardManifest) -> anyhow::Result<()> {
    let shards = dir.join(SHARDS_DIR);
    std::fs::create_dir_all(&shards)
        .with_context(|| format!("cannot create {}", shards.display()))?;
    crate::output::write_atomic(
        &shards.join(manifest.shard.manifest_name()),
        serde_json::to_string_pretty(manifest)?.as_bytes(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shard_parses_k_of_n_and_owns_every_nth_index() {
        let s: Shard = "1/3".parse().unwrap();
        assert_eq!(s, Shard { k: 1, n: 3 });
        assert_eq!(s.to_string(), "1/3");
        let owned: Vec<usize> = (0..10).filter(|&i| s.owns(i)).collect();
        assert_eq!(owned, [1, 4, 7]);
        // Every index belongs to exactly one shard of a split.
        for i in 0..20 {
            let owners = (0..4).filter(|&k| Shard { k, n: 4 }.owns(i)).count();
            assert_eq!(owners, 1);
            assert!(Shard::of(i, 4).owns(i));
        }
        for bad in ["3/3", "0/0", "a/2", "1", "-1/2", "1/2/3"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }
}
