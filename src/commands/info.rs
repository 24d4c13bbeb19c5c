//! `smokeshadow info`: which adapters exist, which one is used, and whether it has what the tool
//! needs.

use crate::Wait;
use std::path::{Path, PathBuf};

use anyhow::Context;

use smokeshadow_core::gpu::{self, AdapterPreference, Gpu};
use smokeshadow_core::medium::vdb;
use smokeshadow_core::shadow;

#[derive(Clone, Debug, clap::Args)]
pub struct InfoArgs {
    /// An OpenVDB file (`.vdb`) to describe instead of the adapters: its grids, their value
    /// types, compression, voxel counts, placement and the float grids' values.
    pub file: Option<PathBuf>,
}

pub fn run(args: &InfoArgs, preference: &AdapterPreference) -> anyhow::Result<()> {
    if let Some(file) = &args.file {
        return describe_vdb(file);
    }
    let adapters = pollster::block_on(gpu::ranked_adapters(&gpu::instance()));
    println!("adapters (in selection order):");
    for a in &adapters {
        println!("  {}", gpu::describe_adapter(&a.get_info()));
    }
    let gpu = Gpu::new(preference).wait()?;
    let yes_no = |b: bool| if b { "yes" } else { "no" };
    let l = &gpu.limits;
    println!("selected ({preference}): {}", gpu.describe());
    println!(
        "  timestamp queries (GPU pass times): {}",
        yes_no(gpu.has_timestamps())
    );
    println!(
        "  FLOAT32_BLENDABLE (fom's 32-bit coefficients): {}",
        yes_no(gpu.features.contains(wgpu::Features::FLOAT32_BLENDABLE))
    );
    println!(
        "  FLOAT32_FILTERABLE (fom's 32-bit coefficients): {}",
        yes_no(gpu.features.contains(wgpu::Features::FLOAT32_FILTERABLE))
    );
    println!(
        "  colour attachments: {}, colour bytes per sample: {}",
        l.max_color_attachments, l.max_color_attachment_bytes_per_sample
    );
    println!("  max 2D texture size: {}", l.max_texture_dimension_2d);
    // A 32-channel half-float layered map: 8 RGBA16F targets, in as many passes as the limits
    // need (budgets past one pass build in several, the same maps).
    let formats = [wgpu::TextureFormat::Rgba16Float; 8];
    match shadow::layered::target_passes(&formats, l) {
        Some(passes) => println!(
            "  a {}-channel half-float layered map builds in {} pass{}",
            shadow::MAX_CHANNELS,
            passes.len(),
            if passes.len() == 1 { "" } else { "es" }
        ),
        None => {
            println!("  layered maps: unusable (an RGBA16F target exceeds the bytes per sample)")
        }
    }
    println!(
        "embedded scenes (any command takes their name for a scene file; * = in the gallery, \
         scene::GALLERY; t = training, only `tune` uses it; h = held out, only the convergence \
         tests use it):"
    );
    for (name, _) in smokeshadow_core::scene::EMBEDDED {
        let gallery = if smokeshadow_core::scene::GALLERY.contains(name) {
            '*'
        } else if smokeshadow_core::scene::TRAINING.contains(name) {
            't'
        } else if smokeshadow_core::scene::HOLDOUT.contains(name) {
            'h'
        } else {
            ' '
        };
        let summary = smokeshadow_core::scene::embedded_summary(name).unwrap_or_default();
        println!("  {gallery} {name:<13} {summary}");
    }
    println!("techniques:");
    for e in shadow::REGISTRY {
        let role = match e.role {
            shadow::Role::FrameBaseline => "frame-time baseline",
            shadow::Role::Reference => "reference",
            shadow::Role::Contender => "contender",
        };
        let media = match (e.shadows_particles, e.volume) {
            (true, shadow::VolumeSupport::Shadows) => "particles+volume",
            (true, shadow::VolumeSupport::Refuses(_)) => "particles",
            (false, _) => "volume",
        };
        println!(
            "  {:<10} {role:<19} {media:<16} channels {}..={} (24: {})  {}",
            e.name,
            e.min_channels,
            e.max_channels,
            (e.budget_caption)(24),
            e.description
        );
    }
    println!("technique parameters ([shadow.params] in a scene file, --param KEY=VALUE):");
    for (e, p) in shadow::all_params() {
        println!(
            "  {:<18} {:<4} {}, default {} ({}): {}",
            p.key,
            p.unit,
            p.accepted(),
            p.default_text(),
            e.name,
            p.doc.split_whitespace().collect::<Vec<_>>().join(" ")
        );
    }
    println!(
        "--params paper (the papers' values; every other parameter keeps its default, which \
         `smokeshadow tune` chose):"
    );
    for (key, value, source) in crate::tune::PAPER {
        // A choice by its name.
        let shown = smokeshadow_core::shadow::find_param(key)
            .ok()
            .and_then(|spec| spec.choices.get(*value as usize))
            .map_or(value.to_string(), |c| (*c).to_owned());
        println!("  {key:<22} {shown} ({source})");
    }
    Ok(())
}

/// `smokeshadow info FILE.vdb`: each grid as the file lists it, and each float grid read whole
/// (what a scene's `[volume]` would get from it).
fn describe_vdb(path: &Path) -> anyhow::Result<()> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    let shown = path.display();
    let grids = vdb::list_grids(&bytes).with_context(|| format!("{shown}"))?;
    println!("{shown}: {} bytes, {} grid(s)", bytes.len(), grids.len());
    for g in &grids {
        let half = if g.saved_as_half {
            ", saved as half"
        } else {
            ""
        };
        let class = g.grid_class.as_deref().unwrap_or("no class");
        println!(
            "  {:?}: {} ({}{half}), {}, {class}",
            g.name, g.value_type, g.type_name, g.compression
        );
        if let Some(parent) = &g.instance_parent {
            println!("    an instance of {parent:?} (shares its tree)");
        }
        if g.value_type != "float" {
            println!("    not readable as a density: only float grids are");
            continue;
        }
        let grid = vdb::read_float_grid(&bytes, &g.name, &vdb::Limits::default())
            .with_context(|| format!("{shown}"))?;
        describe_float_grid(&grid);
    }
    Ok(())
}

fn describe_float_grid(grid: &vdb::FloatGrid) {
    let d = grid.dims;
    if d.min_element() == 0 {
        println!("    no active voxels: an empty medium");
        return;
    }
    let hi = grid.index_min + d.as_ivec3() - glam::IVec3::ONE;
    println!(
        "    {} active voxels in the index box {} to {} (dense {}x{}x{} = {} voxels, {:.1} MiB as \
         R32Float)",
        grid.active_voxels,
        grid.index_min,
        hi,
        d.x,
        d.y,
        d.z,
        grid.values.len(),
        grid.values.len() as f64 * 4.0 / (1024.0 * 1024.0)
    );
    let m = grid.world_from_index.matrix3;
    println!(
        "    voxel {:.4} x {:.4} x {:.4} (file units), index (0,0,0) at {:.4}",
        m.x_axis.length(),
        m.y_axis.length(),
        m.z_axis.length(),
        grid.world_from_index.translation
    );
    let (mut min, mut max, mut sum, mut nonzero) = (f32::INFINITY, f32::NEG_INFINITY, 0.0f64, 0u64);
    for &v in &grid.values {
        min = min.min(v);
        max = max.max(v);
        sum += f64::from(v);
        nonzero += u64::from(v != 0.0);
    }
    println!(
        "    values {min} to {max}, background {}, {nonzero} non-zero, sum {sum:.3}",
        grid.background
    );
}
