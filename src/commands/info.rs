//! `smokeshadow info`: which adapters exist, which one is used, and whether it has what the tool
//! needs.

use crate::gpu::{self, AdapterPreference, Gpu};
use crate::shadow;

pub fn run(preference: &AdapterPreference) -> anyhow::Result<()> {
    let adapters = pollster::block_on(gpu::ranked_adapters(&gpu::instance()));
    println!("adapters (in selection order):");
    for a in &adapters {
        println!("  {}", gpu::describe_adapter(&a.get_info()));
    }
    let gpu = Gpu::new(preference)?;
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
        "  colour attachments: {} (32-channel budgets need {})",
        l.max_color_attachments,
        gpu::REQUIRED_COLOR_ATTACHMENTS
    );
    println!(
        "  colour bytes per sample: {} (32 channels of RGBA16F need {})",
        l.max_color_attachment_bytes_per_sample,
        gpu::REQUIRED_BYTES_PER_SAMPLE
    );
    println!("  max 2D texture size: {}", l.max_texture_dimension_2d);
    let ok = l.max_color_attachments >= gpu::REQUIRED_COLOR_ATTACHMENTS
        && l.max_color_attachment_bytes_per_sample >= gpu::REQUIRED_BYTES_PER_SAMPLE;
    println!(
        "  every budget 1..={} usable: {}",
        shadow::MAX_CHANNELS,
        yes_no(ok)
    );
    println!(
        "embedded scenes (any command takes their name for a scene file; * = in the gallery, \
         scene::GALLERY; t = training, only `tune` uses it):"
    );
    for (name, _) in crate::scene::EMBEDDED {
        let gallery = if crate::scene::GALLERY.contains(name) {
            '*'
        } else if crate::scene::TRAINING.contains(name) {
            't'
        } else {
            ' '
        };
        let summary = crate::scene::embedded_summary(name).unwrap_or_default();
        println!("  {gallery} {name:<13} {summary}");
    }
    println!("techniques:");
    for e in shadow::REGISTRY {
        let role = match e.role {
            shadow::Role::FrameBaseline => "frame-time baseline",
            shadow::Role::Reference => "reference",
            shadow::Role::Contender => "contender",
        };
        println!(
            "  {:<10} {role:<19} min {} channels (24: {})  {}",
            e.name,
            e.min_channels,
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
        println!("  {key:<22} {value} ({source})");
    }
    Ok(())
}
